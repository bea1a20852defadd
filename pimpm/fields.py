"""Grid velocity fields of the deformable bodies (issue 30): every body named
in a contact pair (the input's top-level ``contact`` list) gets a velocity
field of its own; the bodies in no pair share one, as every body did before.
Where two fields reach the same node, the pair's law acts there
(:mod:`pimpm.kernels.multifield`): frictionless or Coulomb contact that
lets the bodies separate, or bonded (one velocity); fields of bodies in no
declared pair are bonded, so a body without a pair stays welded to the rest.

Field f of grid node i is "field node" ``i * count + f``: particles carry
field-node indices into the transfer kernels, and a nodal array of the
fields is the grid's array with ``count`` times the columns (one exchange
for all fields)."""
import numpy as np
from petsc4py import PETSc

from .kernels import multifield as kernels

LAWS = {"bonded": kernels.BONDED, "frictionless": kernels.FRICTIONLESS, "friction": kernels.FRICTION}
#: each pair's history columns, as the contact tools' (pimpm.io.history.CONTACT_COLUMNS)
PAIR_COLUMNS = ("normal_force", "tangential_force", "contact_area", "contact_points")
#: the grid output of runs with pairs, per node at the end of the step (frictionless and
#: frictional pairs; :meth:`BodyFields.set_node_contact`): the most slipping state of the
#: node's pairs (0 open, 1 stick, 2 slip), their normal pressure, and the traction on
#: the body listed first in each pair (summed over the node's pairs)
NODE_CONTACT_FIELDS = ("contact_status", "contact_pressure", "contact_traction")


def sum_fields_to_owned(grid, count, local_values):
    """Field-node values (n_local_nodes * count, k) of ``grid`` summed over
    ranks: (n_owned_nodes * count, k), one exchange for every field. Collective."""
    k = local_values.shape[1]
    return grid.sum_columns_to_owned(np.reshape(local_values, (grid.n_local_nodes, count * k))).reshape(-1, k)


def fields_to_local(grid, count, owned_values, k):
    """Ghosted-local field-node values (n_local_nodes * count, k) of owned
    ones (flat, n_owned_nodes * count * k). Collective."""
    local = grid.owned_columns_to_local(np.reshape(owned_values, (grid.n_owned_nodes, count * k)))
    return local.reshape(-1, k)


class BodyFields:
    """The fields of a run (``config``: the validated input). ``count`` = 1
    when there are no contact pairs: everything is as with one field."""

    def __init__(self, config):
        bodies = config["bodies"]
        paired = [name for pair in config["contact"] for name in pair["bodies"]]
        paired = list(dict.fromkeys(paired))
        unpaired = [b["name"] for b in bodies if not b["rigid"] and b["name"] not in paired]
        first = 1 if unpaired else 0               # field 0: the bodies in no pair
        field_of_name = {name: first + k for k, name in enumerate(paired)}
        #: field of each body (by its index in the input's list; rigid bodies: -1)
        self.of_body = np.array([-1 if b["rigid"] else field_of_name.get(b["name"], 0) for b in bodies],
                                dtype=np.int64)
        self.count = first + len(paired)
        self.law = np.full((self.count, self.count), kernels.BONDED, dtype=np.int64)
        self.mu = np.zeros((self.count, self.count))
        #: (name, f, g) of every declared pair, f < g
        self.pairs = []
        #: +1 at (f, g) if the pair's first listed body is field f (-1 at (g, f)): the output's traction
        self.orientation = np.zeros((self.count, self.count))
        for pair in config["contact"]:
            f, g = sorted(field_of_name[name] for name in pair["bodies"])
            self.law[f, g] = self.law[g, f] = LAWS[pair["law"]]
            self.mu[f, g] = self.mu[g, f] = pair.get("friction_coefficient", 0.0)
            self.pairs.append(("-".join(pair["bodies"]), f, g))
            first = field_of_name[pair["bodies"][0]]
            self.orientation[f, g], self.orientation[g, f] = (1.0, -1.0) if first == f else (-1.0, 1.0)
        self.dissipation = 0.0          # frictional dissipation so far (summed over ranks)
        self.last = {name: dict.fromkeys(PAIR_COLUMNS, 0.0) for name, _, _ in self.pairs}
        self._density = None
        self._node_contact = None       # the last step's NODE_CONTACT_FIELDS (owned nodes)
        self._step_dissipation = []     # the step's, per pair, until it stands (:meth:`commit`)
        self._pending = None            # a checkpoint's candidates, until the grid is known
        #: implicit: each owned node's pairs' elastic slip, status and penetration (n, F * F, dim + 2)
        self._carried = None

    def carried(self, grid, nodes, fields):
        """What each candidate pair (owned ``nodes`` of ``grid``, ``fields``
        (k, 2)) carries in from the end of the last step at its node: its
        elastic slip (k, dim), its status (kernels.STICK, SLIP or OPEN) and
        its penetration: the implicit law's stick, hold and gap (pimpm.terms.pairs)."""
        dim, pairs = grid.dim, self.count * self.count
        if self._carried is None or len(self._carried) != grid.n_owned_nodes:
            self._carried = np.zeros((grid.n_owned_nodes, pairs, dim + 2))
        if self._pending is not None:           # a checkpoint's (:meth:`restore`)
            node, pair, values = self._pending
            owned = np.full(int(np.prod(grid.nodes)), -1, dtype=np.int64)
            owned[grid.natural_node_index()] = np.arange(grid.n_owned_nodes)
            mine = owned[node] >= 0
            self._carried[owned[node[mine]], pair[mine]] = values[mine]
            self._pending = None
        values = self._carried[nodes, fields[:, 0] * self.count + fields[:, 1]]
        return values[:, :dim].copy(), np.rint(values[:, dim]).astype(np.int64), values[:, dim + 1].copy()

    def pair_masses(self, nodes, fields):
        """The two fields' masses of each candidate pair (k, 2) (:meth:`find_contacts`' step)."""
        return np.stack([self._mass[nodes, fields[:, 0]], self._mass[nodes, fields[:, 1]]], axis=1)

    def keep(self, nodes, fields, elastic, status, penetration):
        """The converged step's candidate pairs: their elastic slips, status
        and penetrations, at their nodes (every other pair's are forgotten)."""
        self._carried[:] = 0.0
        self._carried[nodes, fields[:, 0] * self.count + fields[:, 1]] = np.column_stack(
            [elastic, status, penetration])

    def state(self, grid):
        """What a checkpoint keeps: the frictional dissipation so far and, in
        implicit runs, each candidate pair at the end of the step: its grid
        node (natural numbering, so a restart on other ranks finds it), the
        pair (f * count + g) and what :meth:`carried` returns (the next
        step's stick, hold and gap; pairs with nothing to carry are left
        out). The same on every rank. Collective."""
        out = {"dissipation": self.dissipation}
        if self._carried is not None:
            node, pair = np.nonzero(np.any(self._carried != 0.0, axis=2))
            index = np.column_stack([grid.natural_node_index()[node], pair])
            width = self._carried.shape[2]
            index = np.concatenate([np.asarray(r, dtype=np.int64).reshape(-1, 2)
                                    for r in grid.comm.allgather(index)])
            values = np.concatenate([np.asarray(v, dtype=float).reshape(-1, width)
                                     for v in grid.comm.allgather(self._carried[node, pair])])
            order = np.lexsort((index[:, 1], index[:, 0]))
            out["candidates"] = {"node": index[order, 0].tolist(), "pair": index[order, 1].tolist(),
                                 "carried": values[order].tolist()}
        return out

    def restore(self, state):
        """A checkpoint's :meth:`state`; raises ValueError if it is not one."""
        self.dissipation = float(state.get("dissipation", 0.0))
        candidates = state.get("candidates")
        if candidates is not None:
            node = np.asarray(candidates["node"], dtype=np.int64)
            pair = np.asarray(candidates["pair"], dtype=np.int64)
            values = np.asarray(candidates["carried"], dtype=float)
            k = len(node)
            if len(pair) != k or values.shape[:1] != (k,) or (k and values.ndim != 2) \
                    or np.any(pair < 0) or np.any(pair >= self.count ** 2) or not np.all(np.isfinite(values)):
                raise ValueError("the contact pairs' candidates")
            self._pending = (node, pair, values.reshape(k, -1))

    def transfer(self, old, new):
        """The carried state from grid ``old`` onto ``new``, the same grid
        partitioned differently (:meth:`pimpm.simulation.Simulation.balance_ranks`). Collective."""
        if self._carried is None:
            return
        shape = self._carried.shape[1:]
        self._carried = old.transfer_owned(self._carried.reshape(-1), new).reshape((new.n_owned_nodes,) + shape)

    @property
    def single(self):
        return self.count == 1

    @property
    def names(self):
        return [name for name, _, _ in self.pairs]

    def node_index(self, node_index, body):
        """The particles' field-node indices from their grid-node indices."""
        if self.single:
            return node_index
        return node_index * self.count + self.of_body[body][:, None]

    def local_nodes(self, grid):
        return grid.n_local_nodes * self.count

    def sum_to_owned(self, grid, local_values):
        """Field-node values (n_local_nodes * count, k) summed over ranks:
        (n_owned_nodes * count, k). Collective."""
        k = local_values.shape[1]
        if self.single and k == grid.dim:
            return grid.sum_to_owned(local_values).reshape(-1, k)
        return sum_fields_to_owned(grid, self.count, local_values)

    def to_local(self, grid, owned_values, k):
        """Ghosted-local field-node values (n_local_nodes * count, k) of
        owned ones (flat, n_owned_nodes * count * k). Collective."""
        if self.single and k == grid.dim:
            return grid.owned_to_local(owned_values)
        return fields_to_local(grid, self.count, owned_values, k)

    def spread(self, grid, dof_values):
        """An owned per-dof array of the grid (n_owned_nodes * dim) repeated
        for every field."""
        if self.single:
            return dof_values
        per_node = np.reshape(dof_values, (grid.n_owned_nodes, 1, grid.dim))
        return np.repeat(per_node, self.count, axis=1).reshape(-1)

    def total(self, grid, field_values):
        """The sum over fields of an owned per-field-dof array: per grid dof."""
        if self.single:
            return field_values
        per_field = np.reshape(field_values, (grid.n_owned_nodes, self.count, grid.dim))
        out = per_field[:, 0].copy()
        for f in range(1, self.count):          # a few fields: 3x numpy's sum over the middle axis
            out += per_field[:, f]
        return out.reshape(-1)

    def centre_of_mass(self, grid, mass, values, total_mass=None):
        """The mass-weighted mean over fields of per-field-dof ``values``
        (velocities), per grid dof; ``mass`` per field dof (``total_mass``:
        its :meth:`total`, if known)."""
        if self.single:
            return values
        m = self.total(grid, mass) if total_mass is None else total_mass
        return np.where(m > 0.0, self.total(grid, mass * values) / np.where(m > 0.0, m, 1.0), 0.0)

    def grid_output(self, grid, mass, velocity, acceleration, increment):
        """The step's grid fields for the output, per grid dof (owned): the
        fields' total mass and their centre-of-mass velocity, acceleration and
        displacement increment (``mass`` and the others per field dof)."""
        total = self.total(grid, mass)
        out = {"mass": total, "velocity": self.centre_of_mass(grid, mass, velocity, total),
               "acceleration": self.centre_of_mass(grid, mass, acceleration, total),
               "displacement_increment": self.centre_of_mass(grid, mass, increment, total)}
        return {**out, **self.node_contact(grid)}

    def set_node_contact(self, status, pressure, traction):
        """The step's contact at the owned grid nodes: the most
        slipping status of the node's pairs (n,), their normal pressure (n,)
        and the traction on each pair's first listed body (n, dim)."""
        self._node_contact = (status, pressure, traction)

    def node_contact(self, grid):
        """The NODE_CONTACT_FIELDS per grid dof (the scalars repeated, as the
        mass): the last step's, zero before the first; none without pairs."""
        if not self.pairs:
            return {}
        n, dim = grid.n_owned_nodes, grid.dim
        if self._node_contact is None or len(self._node_contact[0]) != n:
            self._node_contact = (np.zeros(n), np.zeros(n), np.zeros((n, dim)))
        status, pressure, traction = self._node_contact
        return {"contact_status": np.repeat(np.asarray(status, dtype=float), dim),
                "contact_pressure": np.repeat(pressure, dim), "contact_traction": np.reshape(traction, -1)}

    def find_contacts(self, sim, node_index, S, G, nodal_mass):
        """Where the fields meet this step: their outward normals and how far
        their surfaces reach along them at the owned nodes, from the
        particles' field-node footprint and the nodal masses (per field
        dof). Collective."""
        grid, p, dim, count = sim.grid, sim.particles, sim.dim, self.count
        axes, footprint = tuple(range(dim)), tuple(range(S.shape[1]))
        n_local = self.local_nodes(grid)
        gradient = np.empty((n_local, dim))
        kernels.mass_gradients(axes, footprint, node_index, G, p["mass"], gradient)
        gradient = self.sum_to_owned(grid, gradient).reshape(grid.n_owned_nodes, count, dim)
        self._mass = nodal_mass.reshape(grid.n_owned_nodes, count, dim)[:, :, 0].copy()
        self._normal = np.empty((grid.n_owned_nodes, count, kernels.AXES, dim))
        self._partner = np.empty((grid.n_owned_nodes, count), dtype=np.int64)
        kernels.outward_normals(self._mass, gradient, sim.mass_floor, self._normal, self._partner)
        axes_n = kernels.AXES
        normal_local = self.to_local(grid, self._normal.reshape(-1), axes_n * dim).reshape(n_local, axes_n, dim)
        extent = np.empty((n_local, axes_n))
        kernels.surface_extents(axes, footprint, node_index, S, p["x"], p["F"], p["half_size"], normal_local,
                                extent)
        self._extent = grid.max_columns_to_owned(extent.reshape(grid.n_local_nodes, axes_n * count)).reshape(
            grid.n_owned_nodes, count, axes_n)
        self._floor = sim.mass_floor

    def candidates(self, sim, node_index, S, G, nodal_mass):
        """The implicit step's contact candidates at the owned nodes (after
        :meth:`find_contacts`' geometry): (grid nodes, (f, g), separating
        axes, gaps at the start of the step, each pair's share of its node's
        surface). Collective."""
        self.find_contacts(sim, node_index, S, G, nodal_mass)
        n, count, dim = sim.grid.n_owned_nodes, self.count, sim.dim
        if self._density is None:               # each field's reference density (mass over volume), once
            p = sim.particles
            field = self.of_body[p["body"]]
            sums = np.zeros((2, count))
            np.add.at(sums[0], field, p["mass"])
            np.add.at(sums[1], field, p["volume0"])
            sums = sim.comm.allreduce(sums)
            self._density = np.where(sums[1] > 0.0, sums[0] / np.where(sums[1] > 0.0, sums[1], 1.0), 1.0)
        worst = n * count * (count - 1) // 2
        nodes, fields = np.empty(worst, dtype=np.int64), np.empty((worst, 2), dtype=np.int64)
        normals, gaps, shares = np.empty((worst, dim)), np.empty(worst), np.empty(worst)
        k = kernels.pair_candidates(self._mass, self._density, self._normal, self._extent, self._partner,
                                    self._floor, nodes, fields, normals, gaps, shares)
        return nodes[:k].copy(), fields[:k].copy(), normals[:k].copy(), gaps[:k].copy(), shares[:k].copy()

    def contact(self, sim, velocity, dt, report=False):
        """The pairs' law applied to field velocities ``velocity`` (owned,
        per field dof; returned anew) at the contacts :meth:`find_contacts`
        found. ``report``: these are the step's new velocities: keep the
        pairs' forces in :attr:`last` and their dissipation (collective)."""
        grid, count = sim.grid, self.count
        v = velocity.reshape(grid.n_owned_nodes, count, sim.dim).copy()
        sums = np.zeros((count * count, kernels.PAIR_SUMS))
        status = np.empty(grid.n_owned_nodes, dtype=np.int64)
        impulse = np.empty((grid.n_owned_nodes, 1 + sim.dim))
        kernels.pair_impulses(self._mass, v, self._normal, self._extent, self._partner, self.law, self.mu, dt,
                              self._floor, sums, self.orientation, status, impulse)
        if report:
            sums = sim.comm.allreduce(sums)
            area = float(np.prod(grid.spacing)) / float(np.min(grid.spacing))   # a node's share of a face
            self.set_node_contact(status, impulse[:, 0] / (dt * area), impulse[:, 1:] / (dt * area))
            for name, f, g in self.pairs:
                row = sums[f * count + g]
                self.last[name] = {"normal_force": float(row[0] / dt), "tangential_force": float(row[1] / dt),
                                   "contact_area": float(row[2] * area), "contact_points": int(row[2])}
            self.book([sums[f * count + g, 3] for _, f, g in self.pairs])
        return v.reshape(-1)

    def book(self, dissipations):
        """The step's frictional dissipation of each pair (in :attr:`pairs`'
        order), summed over ranks: booked when the step stands (:meth:`commit`)."""
        self._step_dissipation = [float(d) for d in dissipations]

    def commit(self):
        """The step stands: book its frictional dissipation (a step that
        fails after the pairs reported it and is retried must not book it
        twice). The explicit step and pimpm.terms.pairs call it."""
        for dissipation in self._step_dissipation:
            self.dissipation += dissipation
        self._step_dissipation = []


class FieldGrid:
    """The grid as a step sees it with several velocity fields (the implicit
    step's unknowns; :class:`BodyFields` with count F > 1): a grid whose nodes are the field
    nodes, i * F + f, F dim unknowns per grid node on a DMDA of F dim dofs
    (the grid's layout). Field nodes are placed on a virtual grid that is F
    times finer along x (x' = F x + f), so that the tangent's pattern and
    kernels (stencil slots from node multi-indices) run unchanged; the
    stencil's half-width grows to F times the shape functions'. Everything
    else is the grid's."""

    def __init__(self, grid, count):
        self.grid = grid
        self.count = count
        self.dim = grid.dim
        self.comm = grid.comm
        self.da = grid._wide_da(grid.dim * count)[0]
        self.n_local_nodes = grid.n_local_nodes * count
        self.n_owned_nodes = grid.n_owned_nodes * count
        ijk = np.repeat(grid.ghost_ijk, count, axis=0)
        ijk[:, 0] = ijk[:, 0] * count + np.tile(np.arange(count), grid.n_local_nodes)
        self.ghost_ijk = ijk
        self.ghost_shape = grid.ghost_shape.copy()
        self.ghost_shape[0] *= count
        self.owned_local_nodes = (grid.owned_local_nodes[:, None] * count + np.arange(count)).reshape(-1)
        self._lgmap = None

    def lgmap(self):
        """The local-to-global map of the field nodes' dofs in blocks of dim
        (the DMDA's has blocks of F dim, one per grid node)."""
        if self._lgmap is None:
            indices = self.da.getLGMap().getIndices()
            self._lgmap = PETSc.LGMap().create(indices[::self.dim] // self.dim, bsize=self.dim,
                                               comm=self.da.getComm())
        return self._lgmap

    def __getattr__(self, name):          # spacing, lower, cell_volume, contains, ...: the grid's
        return getattr(self.grid, name)

    def sum_to_owned(self, local_values):
        """Field-node values (n_local_nodes, dim) summed over ranks: owned dofs (flat). Collective."""
        return sum_fields_to_owned(self.grid, self.count, np.reshape(local_values, (-1, self.dim))).reshape(-1)

    def sum_scalar_to_owned(self, local_values):
        return self.sum_to_owned(np.repeat(np.asarray(local_values)[:, None], self.dim, axis=1))

    def owned_to_local(self, owned_values):
        """Ghosted-local copy (n_local_nodes, dim) of owned dofs. Collective."""
        return fields_to_local(self.grid, self.count, owned_values, self.dim)

    def vec_to_local(self, vec):
        return self.owned_to_local(vec.getArray(readonly=True))

    def coordinates(self):
        """Every owned dof's node coordinate (a Vec of the field DMDA): the
        rigid-body modes of each field."""
        x = self.grid.node_coordinates_owned()
        values = np.repeat(x[:, None, :], self.count, axis=1).reshape(-1)
        # a Vec of its own: the DMDA's would share its local-to-global map, whose
        # block size (F dim) the near-null space's setBlockSize(dim) would change
        vec = PETSc.Vec().createMPI((len(values), PETSc.DETERMINE), bsize=self.dim, comm=self.da.getComm())
        vec.getArray()[:] = values
        return vec

    def box_preallocation(self, width):
        raise NotImplementedError("several velocity fields need the COO assembly")
