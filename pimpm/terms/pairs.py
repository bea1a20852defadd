"""Contact between the velocity fields of deformable bodies inside Newton
(issue 30; the fields: :mod:`pimpm.fields`): at every owned node that two
fields reach, the pair's law acts between their unknowns, the incremental
displacements u_f and u_g of the same grid node. The law is the rigid
tools' (:func:`pimpm.kernels.contact.contact_point`): field g's surface is a
half-space through the node, at the gap measured at the start of the step
between the two bodies' particle domains along the pair's separating axis
n (:func:`pimpm.kernels.multifield.pair_candidates`); field f presses into
it by (u_f - u_g) . n - gap, with the penalty pressure and Coulomb's
regularized stick and slip on the relative tangential displacement, and
the two fields get equal and opposite forces. The tangent is exact (a
dim x dim block D per pair, in the four blocks of the pair's rows and
columns, which the step's pattern holds: :meth:`pimpm.simulation.Simulation.tangent_pattern`)."""
import numpy as np

from ..config.schema import DEFAULT_CONTACT_STIFFNESS, DEFAULT_SLIP_TOLERANCE, DEFAULT_TANGENTIAL_STIFFNESS
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
        self.symmetric_tangent = not np.any(fields.law == kernels.FRICTION)
        self._u = None

    def set_candidates(self, grid, nodes, fields, normals, gaps):
        """This step's candidate pairs (owned nodes of ``grid``, the grid's
        (not its field nodes'), their fields, axes and gaps at the start;
        pimpm.fields.BodyFields.candidates)."""
        self.nodes, self.pair_fields, self.normals, self.gaps = nodes, fields, normals, gaps
        self.local_nodes = grid.owned_local_nodes[nodes]        # ghosted-local grid nodes
        self.history = self.fields.slip_history(grid, nodes, fields)
        self._u = None

    def _evaluate(self, u_owned):
        if self._u is not None and np.array_equal(self._u, u_owned):
            return self._local
        k, dim = len(self.nodes), self.dim
        local = {"force": np.empty((k, dim)), "D": np.empty((k, dim, dim)), "status": np.empty(k, dtype=np.int64),
                 "pressure": np.empty(k), "slip": np.empty(k), "elastic": np.empty((k, dim))}
        kernels.pair_forces(self.nodes, self.pair_fields, self.normals, self.gaps, self.fields.law, self.fields.mu,
                            np.ascontiguousarray(u_owned), dim, self.fields.count, self.area, self.kn, self.stick,
                            self.kt, self.history, local["force"], local["D"], local["status"], local["pressure"],
                            local["slip"], local["elastic"])
        self._u, self._local = np.array(u_owned, copy=True), local
        return local

    def add_residual(self, u_owned, u_local, residual, grid):
        """The force on field f enters the residual as an external force (-f), on g as +f."""
        local = self._evaluate(u_owned)
        r = residual.reshape(-1, self.fields.count, self.dim)
        np.add.at(r, (self.nodes, self.pair_fields[:, 0]), -local["force"])
        np.add.at(r, (self.nodes, self.pair_fields[:, 1]), local["force"])

    def add_jacobian_values(self, u_local, grid, pattern, values):
        local = self._evaluate(self._owned(u_local, grid))
        kernels.pair_blocks(self.local_nodes, self.pair_fields, local["D"], self.fields.count, grid.ghost_ijk,
                            self.dim, pattern.width, pattern.indptr, pattern.slot_position, values)

    def _owned(self, u_local, grid):
        return np.ascontiguousarray(u_local[grid.owned_local_nodes]).reshape(-1)

    def add_product(self, u_local, grid, x_local, out_local):
        local = self._evaluate(self._owned(u_local, grid))
        kernels.pair_product(self.local_nodes, self.pair_fields, local["D"], self.fields.count, self.dim,
                             np.ascontiguousarray(x_local), out_local)

    def add_diagonal(self, u_local, grid, out_local):
        local = self._evaluate(self._owned(u_local, grid))
        F = self.fields.count
        diagonal = np.diagonal(local["D"], axis1=1, axis2=2)
        np.add.at(out_local, self.local_nodes * F + self.pair_fields[:, 0], -diagonal)
        np.add.at(out_local, self.local_nodes * F + self.pair_fields[:, 1], -diagonal)

    def commit(self, particles):
        """The converged step: each pair's elastic slip stays at its grid node
        for the next step (the grid is the same every step)."""
        self.fields.keep_slip(self.nodes, self.pair_fields, self._local["elastic"])

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
        touching = local["status"] != kernels.OPEN
        mu = self.fields.mu[self.pair_fields[:, 0], self.pair_fields[:, 1]]
        sums = np.zeros((count * count, 4))
        for column, values in enumerate((normal, tangential, touching.astype(float),
                                         self.area * mu * local["pressure"] * local["slip"])):
            np.add.at(sums[:, column], rows, np.where(touching, values, 0.0))
        sums = comm.allreduce(sums)
        for name, f, g in self.fields.pairs:
            row = sums[f * count + g]
            self.fields.last[name] = {"normal_force": float(row[0]), "tangential_force": float(row[1]),
                                      "contact_area": float(row[2] * self.area), "contact_points": int(row[2])}
            self.fields.dissipation += float(row[3])
