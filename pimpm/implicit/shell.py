"""The matrix-free tangent (Sulsky & Kaul 2.4.4): the context of a PETSc
shell matrix whose product is the analytic directional derivative of the
residual, computed particle by particle without storing a matrix."""
import numpy as np

from .. import assembly
from ..materials import tensors
from ..transfer import gradient_at_particles, scatter
from .momentum import projection_diagonal


class TangentShell:
    """Context of a shell matrix: y = K x with K the exact tangent at the
    current Newton iterate (material + geometric + 4/dt^2 M, prescribed dofs
    eliminated), computed particle by particle without storing a matrix:

        (K x)_ia = sum_p v_p g_ic a_acbd H_bd,   H = sum_j x_j (x) g_j

    (the analytic directional derivative of the residual, cf. Sulsky & Kaul
    eq. 2.4.18 which approximates it by a finite difference)."""

    def __init__(self, grid):
        self.grid = grid
        self.state = None
        self.a = None           # (n, dim, dim, dim, dim) spatial tangent c + geometric part
        self.g = None           # (n, nn, dim) current gradients
        self.v = None           # (n,) current volumes
        self.scale = 1.0        # residual scale (dimensionless residual)
        self.project = None     # momentum formulation: x -> R x
        self.hoop = None        # axisymmetric hoop blocks

    def update(self, state, sigma, c, F_inc, scale, project=None):
        """``project`` (momentum formulation): owned u -> (owned, local) R u."""
        n, nn, dim = state.G.shape
        self.project = project
        self.state = state
        self.scale = scale
        self.g = assembly.current_gradients(F_inc, state.G)
        self.v = state.volume_n * tensors.det(F_inc)
        self.a = assembly.spatial_tangent(sigma, c, dim)
        # the geometry's own terms (axisymmetric hoop): per-particle blocks (n, nn*dim, nn*dim)
        self.hoop = state.kinematics.extra_stiffness(sigma, c, F_inc, state.G, state.S,
                                                     state.volume_n, state.radius)

    def mult(self, mat, x, y):
        st, grid = self.state, self.grid
        dim = grid.dim
        xs = x.getArray(readonly=True).copy()
        fixed = st.fixed
        xs_free = np.where(fixed, 0.0, xs)
        # K R x in the momentum formulation (prescribed rows of R x stay 0)
        x_local = grid.owned_to_local(xs_free) if self.project is None else self.project(xs_free)[1]
        if len(self.v):
            H = gradient_at_particles(st.node_index, self.g, x_local)      # (n, dim, dim)
            stress_rate = np.einsum("pacbd,pbd->pac", self.a, H)
            pairs = self.v[:, None, None] * np.matmul(self.g, np.transpose(stress_rate, (0, 2, 1)))
            if self.hoop is not None:
                n, nn = st.node_index.shape
                x_pairs = x_local[st.node_index].reshape(n, nn * dim, 1)
                pairs += np.matmul(self.hoop, x_pairs).reshape(n, nn, dim)
            local = scatter(st.node_index, pairs, grid.n_local_nodes)
        else:
            local = np.zeros((grid.n_local_nodes, dim))
        out = grid.sum_to_owned(local)
        if st.integrator.stiffness_factor != 1.0:       # HHT: (1 + alpha) K
            out *= st.integrator.stiffness_factor
        if st.dynamic:
            out += st.mass_coefficient * st.mass * xs_free
        out[fixed] = st.constraint_scale * xs[fixed]
        y.getArray()[:] = out / self.scale

    def getDiagonal(self, mat, d):
        st, grid = self.state, self.grid
        dim = grid.dim
        if len(self.v):
            # K_(ia)(ia) = sum_p v_p g_ic a_acad g_id
            diag_a = np.einsum("pacad->pacd", self.a)
            pairs = self.v[:, None, None] * np.einsum("pic,pacd,pid->pia", self.g, diag_a, self.g)
            if self.hoop is not None:
                pairs += np.diagonal(self.hoop, axis1=1, axis2=2).reshape(pairs.shape)
            local = scatter(st.node_index, pairs, grid.n_local_nodes)
        else:
            local = np.zeros((grid.n_local_nodes, dim))
        out = grid.sum_to_owned(local)
        if self.project is not None:             # (collective: every rank takes this branch)
            # momentum formulation: diag(K) diag(R), a Jacobi approximation of diag(K R)
            out *= projection_diagonal(st, grid)
        if st.integrator.stiffness_factor != 1.0:
            out *= st.integrator.stiffness_factor
        if st.dynamic:
            out += st.mass_coefficient * st.mass
        out[st.fixed] = st.constraint_scale
        d.getArray()[:] = out / self.scale
