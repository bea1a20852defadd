"""Contact between the velocity fields of deformable bodies inside Newton
(issue 30; the fields: :mod:`pimpm.fields`): at every owned node that two
fields reach, the pair's law acts between their unknowns, the incremental
displacements u_f and u_g of the same grid node. The law is the rigid
tools' (:func:`pimpm.kernels.contact.contact_point`): field g's surface is a
half-space through the node, at the gap measured at the start of the step
between the two bodies' particle domains along the pair's separating axis
n (:func:`pimpm.kernels.multifield.pair_candidates`), or at the
penetration the pair ended the last step with (:meth:`FieldContact.set_candidates`);
field f presses into it by (u_f - u_g) . n - gap, with the penalty pressure
(smooth over its first 1e-4 h) and Coulomb's regularized stick and slip on
the relative tangential displacement, per the pair's share of a node's
surface, and the two fields get equal and opposite forces. Newton starts
from the pairs that touched put back in touch (:meth:`FieldContact.predict`)
and its first Jacobian holds them (the rigid tools' hold). The tangent is exact (a
dim x dim block D per pair, in the four blocks of the pair's rows and
columns, which the step's pattern holds: :meth:`pimpm.simulation.Simulation.tangent_pattern`)."""
import numpy as np

from ..config.schema import (DEFAULT_CONTACT_STIFFNESS, DEFAULT_PAIR_ONSET, DEFAULT_SLIP_TOLERANCE,
                             DEFAULT_TANGENTIAL_STIFFNESS)
from ..kernels import multifield as kernels
from .base import NodalTerm


class FieldContact(NodalTerm):
    """The pairs' law in the implicit step. ``fields``: the run's BodyFields;
    ``modulus``: the largest P-wave modulus; ``h``: the smallest cell size."""

    name = "contact pairs"
    couples_particles = True          # its blocks couple two field nodes: added on the step's pattern

    def __init__(self, fields, dim, modulus, h):
        self.fields = fields
        self.dim = dim
        self.h = h
        self.area = h ** (dim - 1)                          # a node's share of the surface
        self.kn = DEFAULT_CONTACT_STIFFNESS * modulus / h   # as a rigid tool's (pimpm.terms.contact)
        self.stick = DEFAULT_SLIP_TOLERANCE * h
        self.kt = DEFAULT_TANGENTIAL_STIFFNESS * modulus / h
        self.onset = DEFAULT_PAIR_ONSET * h
        self.symmetric_tangent = not np.any(fields.law == kernels.FRICTION)
        self.contact_kind = "pair" if self.symmetric_tangent else "frictional pair"   # pimpm.presets.CONTACT_OPTIONS
        self._u = None

    def set_candidates(self, grid, nodes, fields, normals, gaps, shares):
        """This step's candidate pairs (owned nodes of ``grid``, the grid's
        (not its field nodes'), their fields, axes, gaps at the start and
        their share of a node's area: the smaller field's volume at the node
        over the larger's; pimpm.fields.BodyFields.candidates).

        The gap the law starts from: a pair that touched at the end of the
        last step starts from its penetration then (the penalty's own
        measure, carried at its node), not from the gap the particles'
        domains show now. Re-measured every step, the penetration of a
        resting contact jumps by the remap of the particles (a hundredth of
        the penalty's compliance is enough) and the penalty pumps energy
        into the bodies: a stack of blocks at rest under gravity rang up
        from 1e-3 to 0.2 J/m of kinetic energy in 0.15 s (docs/VALIDATION.md).
        Every other pair starts from the measured gap, no less than zero: the
        seeded surfaces of two bodies (a disk's particles on a plate's) can
        overlap by part of a particle spacing, and the penalty acts only on
        the approach beyond, as the explicit law does.
        """
        self.nodes, self.pair_fields, self.normals = nodes, fields, normals
        self.grid_nodes = grid.n_owned_nodes
        self.local_nodes = grid.owned_local_nodes[nodes]        # ghosted-local grid nodes
        self.history, self.held, penetration = self.fields.carried(grid, nodes, fields)
        touched = (self.held == kernels.STICK) | (self.held == kernels.SLIP)
        self.gaps = np.where(touched, -penetration, np.maximum(gaps, 0.0))
        self.areas = self.area * shares
        self.mass = self.fields.pair_masses(nodes, fields)
        self._holding = bool(np.any(self.held))
        self._u = None

    def _evaluate(self, u_owned):
        if self._u is not None and np.array_equal(self._u, u_owned):
            return self._local
        held = self.held if self._holding else np.zeros_like(self.held)
        k, dim = len(self.nodes), self.dim
        local = {"force": np.empty((k, dim)), "D": np.empty((k, dim, dim)), "status": np.empty(k, dtype=np.int64),
                 "pressure": np.empty(k), "slip": np.empty(k), "elastic": np.empty((k, dim))}
        kernels.pair_forces(self.nodes, self.pair_fields, self.normals, self.gaps, self.fields.law, self.fields.mu,
                            np.ascontiguousarray(u_owned), dim, self.fields.count, self.areas, self.kn, self.stick,
                            self.kt, self.history, held, self.onset, local["force"], local["D"], local["status"],
                            local["pressure"], local["slip"], local["elastic"])
        self._u, self._local = np.array(u_owned, copy=True), local
        return local

    def add_residual(self, u_owned, u_local, residual, grid):
        """The force on field f enters the residual as an external force (-f), on g as +f."""
        local = self._evaluate(u_owned)
        r = residual.reshape(-1, self.fields.count, self.dim)
        np.add.at(r, (self.nodes, self.pair_fields[:, 0]), -local["force"])
        np.add.at(r, (self.nodes, self.pair_fields[:, 1]), local["force"])

    def _first_jacobian_done(self):
        """Holding (the pairs that touched at the end of the last step keep
        the penalty's stiffness while open within the stick length) is for
        the step's first Jacobian only, as the rigid tools'
        (pimpm.terms.contact): held longer, a pair the predictor left open
        closes by one penalty compliance an iteration."""
        if self._holding:
            self._holding = False
            self._u = None

    def add_jacobian_values(self, u_local, grid, pattern, values):
        local = self._evaluate(self._owned(u_local, grid))
        kernels.pair_blocks(self.local_nodes, self.pair_fields, local["D"], self.fields.count, grid.ghost_ijk,
                            self.dim, pattern.width, pattern.indptr, pattern.slot_position, values)
        self._first_jacobian_done()

    def predict(self, u_owned, grid, fixed):
        """The Newton guess with the pairs that touched at the end of the last
        step put back in touch: their fields' relative displacement along
        the pair's axis removed (and across it too where they stuck with
        friction), shared by the two field nodes in inverse proportion to
        their masses (all of it on a free one if the other is prescribed).
        The predictor moves each field with its own velocity; a resting
        block's field then lifts off the floor's by round-off and Newton
        starts with the pairs open."""
        F, dim = self.fields.count, self.dim
        u = np.array(u_owned, copy=True).reshape(-1, F, dim)   # a new array on every rank (the caller's test)
        touched = self.held != kernels.OPEN
        free = ~np.asarray(fixed).reshape(-1, F, dim)
        nodes, f, g = self.nodes[touched], self.pair_fields[touched, 0], self.pair_fields[touched, 1]
        n = self.normals[touched]
        d = u[nodes, f] - u[nodes, g]
        stuck = (self.held[touched] == kernels.STICK) & (self.fields.law[f, g] == kernels.FRICTION)
        remove = np.where(stuck[:, None], d, np.einsum("ka,ka->k", d, n)[:, None] * n)
        mf, mg = self.mass[touched, :1], self.mass[touched, 1:]
        free_f, free_g = free[nodes, f], free[nodes, g]          # (k, dim)
        share_f = np.where(free_f, np.where(free_g, mg / (mf + mg), 1.0), 0.0)
        share_g = np.where(free_g, np.where(free_f, mf / (mf + mg), 1.0), 0.0)
        np.add.at(u, (nodes, f), -share_f * remove)
        np.add.at(u, (nodes, g), share_g * remove)
        return u.reshape(-1)

    def _owned(self, u_local, grid):
        return np.ascontiguousarray(u_local[grid.owned_local_nodes]).reshape(-1)

    def add_product(self, u_local, grid, x_local, out_local):
        self._first_jacobian_done()          # the matrix-free product is always the exact one
        local = self._evaluate(self._owned(u_local, grid))
        kernels.pair_product(self.local_nodes, self.pair_fields, local["D"], self.fields.count, self.dim,
                             np.ascontiguousarray(x_local), out_local)

    def add_diagonal(self, u_local, grid, out_local):
        self._first_jacobian_done()
        local = self._evaluate(self._owned(u_local, grid))
        F = self.fields.count
        diagonal = np.diagonal(local["D"], axis1=1, axis2=2)
        np.add.at(out_local, self.local_nodes * F + self.pair_fields[:, 0], -diagonal)
        np.add.at(out_local, self.local_nodes * F + self.pair_fields[:, 1], -diagonal)

    def commit(self, particles):
        """The converged step: each pair's elastic slip stays at its grid node
        for the next step (the grid is the same every step), and the
        dissipation :meth:`report` found is booked."""
        status = np.where(self._local["status"] == kernels.HELD, kernels.OPEN, self._local["status"])
        if len(self.nodes):
            u = self._u.reshape(-1, self.fields.count, self.dim)
            d = u[self.nodes, self.pair_fields[:, 0]] - u[self.nodes, self.pair_fields[:, 1]]
            penetration = np.maximum(np.einsum("ka,ka->k", d, self.normals) - self.gaps, 0.0)
        else:
            penetration = np.zeros(0)
        self.fields.keep(self.nodes, self.pair_fields, self._local["elastic"], status, penetration)
        self.fields.commit()

    def _node_output(self, force, along, touching):
        """The step's contact per owned node for the output
        (pimpm.fields.NODE_CONTACT_FIELDS): the frictionless and frictional
        pairs' most slipping status, normal pressure and traction on each
        pair's first listed body, per a node's share of the surface (h^(dim-1)),
        so that they sum to the pairs' forces over the nodes' areas."""
        grid_nodes = self.grid_nodes
        f, g = self.pair_fields[:, 0], self.pair_fields[:, 1]
        shown = touching & (self.fields.law[f, g] != kernels.BONDED)
        nodes = self.nodes[shown]
        status = np.zeros(grid_nodes, dtype=np.int64)
        np.maximum.at(status, nodes, self._local["status"][shown])
        pressure = np.zeros(grid_nodes)     # per a node's whole share of the surface, as the explicit law's
        np.add.at(pressure, nodes, np.abs(along[shown]) / self.area)
        traction = np.zeros((grid_nodes, self.dim))
        np.add.at(traction, nodes, self.fields.orientation[f[shown], g[shown], None] * force[shown] / self.area)
        self.fields.set_node_contact(status, pressure, traction)

    def report(self, forces, comm, explicit=False):
        """The converged step's pair forces (pimpm.fields.BodyFields.last) and
        the frictional dissipation (area mu p times the slip beyond the elastic one)."""
        local = self._local
        count = self.fields.count
        rows = self.pair_fields[:, 0] * count + self.pair_fields[:, 1]
        force = local["force"]
        along = np.einsum("ka,ka->k", force, self.normals)
        normal = np.abs(along)
        tangential = np.linalg.norm(force - along[:, None] * self.normals, axis=1) if len(force) else np.zeros(0)
        touching = (local["status"] == kernels.STICK) | (local["status"] == kernels.SLIP)
        mu = self.fields.mu[self.pair_fields[:, 0], self.pair_fields[:, 1]]
        sums = np.zeros((count * count, 5))
        for column, values in enumerate((normal, tangential, touching.astype(float), self.areas,
                                         self.areas * mu * local["pressure"] * local["slip"])):
            np.add.at(sums[:, column], rows, np.where(touching, values, 0.0))
        sums = comm.allreduce(sums)
        self._node_output(force, along, touching)
        for name, f, g in self.fields.pairs:
            row = sums[f * count + g]
            self.fields.last[name] = {"normal_force": float(row[0]), "tangential_force": float(row[1]),
                                      "contact_area": float(row[3]), "contact_points": int(row[2])}
        self.fields.book([sums[f * count + g, 4] for _, f, g in self.fields.pairs])
