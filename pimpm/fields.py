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

from .kernels import multifield as kernels

LAWS = {"bonded": kernels.BONDED, "frictionless": kernels.FRICTIONLESS, "friction": kernels.FRICTION}
#: each pair's history columns, as the contact tools' (pimpm.io.history.CONTACT_COLUMNS)
PAIR_COLUMNS = ("normal_force", "tangential_force", "contact_area", "contact_points")


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
        for pair in config["contact"]:
            f, g = sorted(field_of_name[name] for name in pair["bodies"])
            self.law[f, g] = self.law[g, f] = LAWS[pair["law"]]
            self.mu[f, g] = self.mu[g, f] = pair.get("friction_coefficient", 0.0)
            self.pairs.append(("-".join(pair["bodies"]), f, g))
        self.dissipation = 0.0          # frictional dissipation so far (summed over ranks)
        self.last = {name: dict.fromkeys(PAIR_COLUMNS, 0.0) for name, _, _ in self.pairs}
        self.status = None              # owned nodes' contact state at the last step

    def state(self):
        """What a checkpoint keeps (the pairs' law is stateless: only the account)."""
        return {"dissipation": self.dissipation}

    def restore(self, state):
        self.dissipation = float(state.get("dissipation", 0.0))

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
        owned = grid.sum_columns_to_owned(local_values.reshape(grid.n_local_nodes, self.count * k))
        return owned.reshape(-1, k)

    def to_local(self, grid, owned_values, k):
        """Ghosted-local field-node values (n_local_nodes * count, k) of
        owned ones (flat, n_owned_nodes * count * k). Collective."""
        if self.single and k == grid.dim:
            return grid.owned_to_local(owned_values)
        local = grid.owned_columns_to_local(np.reshape(owned_values, (grid.n_owned_nodes, self.count * k)))
        return local.reshape(-1, k)

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
        return np.reshape(field_values, (grid.n_owned_nodes, self.count, grid.dim)).sum(axis=1).reshape(-1)

    def centre_of_mass(self, grid, mass, values):
        """The mass-weighted mean over fields of per-field-dof ``values``
        (velocities), per grid dof; ``mass`` per field dof."""
        if self.single:
            return values
        m = self.total(grid, mass)
        return np.where(m > 0.0, self.total(grid, mass * values) / np.where(m > 0.0, m, 1.0), 0.0)

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
        kernels.surface_extents(axes, footprint, node_index, S, p["x"], sim.particle_half_sizes(),
                                normal_local, extent)
        self._extent = grid.max_columns_to_owned(extent.reshape(grid.n_local_nodes, axes_n * count)).reshape(
            grid.n_owned_nodes, count, axes_n)
        self._floor = sim.mass_floor

    def contact(self, sim, velocity, dt, report=False):
        """The pairs' law applied to field velocities ``velocity`` (owned,
        per field dof; returned anew) at the contacts :meth:`find_contacts`
        found. ``report``: these are the step's new velocities: keep the
        pairs' forces in :attr:`last` and their dissipation (collective)."""
        grid, count = sim.grid, self.count
        v = velocity.reshape(grid.n_owned_nodes, count, sim.dim).copy()
        sums = np.zeros((count * count, kernels.PAIR_SUMS))
        status = np.empty(grid.n_owned_nodes, dtype=np.int64)
        kernels.pair_impulses(self._mass, v, self._normal, self._extent, self._partner, self.law, self.mu, dt,
                              self._floor, sums, status)
        if report:
            self.status = status
            sums = sim.comm.allreduce(sums)
            area = float(np.prod(grid.spacing)) / float(np.min(grid.spacing))   # a node's share of a face
            for name, f, g in self.pairs:
                row = sums[f * count + g]
                self.last[name] = {"normal_force": float(row[0] / dt), "tangential_force": float(row[1] / dt),
                                   "contact_area": float(row[2] * area), "contact_points": int(row[2])}
                self.dissipation += float(row[3])
        return v.reshape(-1)
