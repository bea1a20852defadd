"""Linear-solver pieces of the Newton step: solver presets, Guilkey & Weiss's
iterative-then-direct fallback (section 3.3), and the matrix-free tangent
(Sulsky & Kaul 2.4.4) as a PETSc shell matrix with the analytic product.

All of them are configured through the PETSc options database, so every
choice can be refined or overridden from the command line.
"""
import numpy as np
from petsc4py import PETSc

from . import assembly, smallmat
from .transfer import gradient_at_particles, particle_to_grid, scatter

#: GAMG settings measured by scripts/bench_solvers.py (docs/PERFORMANCE.md): a
#: drop threshold of 0.02 and 3 smoothing steps per level keep the iteration
#: count flat under refinement (defaults: 1.7x growth from 7e3 to 1e5 unknowns).
GAMG = {"pc_type": "gamg", "pc_gamg_threshold": "0.02", "mg_levels_ksp_max_it": "3"}

#: name -> (PETSc options, iterative?, symmetric positive definite?, matrix-free?)
PRESETS = {
    "mumps": ({"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"},
              False, False, False),
    "cg-gamg": ({"ksp_type": "cg", **GAMG, "ksp_rtol": "1e-8", "ksp_max_it": "1000"},
                True, True, False),
    "gmres-gamg": ({"ksp_type": "gmres", **GAMG, "ksp_rtol": "1e-8",
                    "ksp_gmres_restart": "100", "ksp_max_it": "1000"}, True, False, False),
    # Sulsky & Kaul's Jacobian-free Newton-Krylov: the operator is the finite-
    # difference directional derivative (their eq. 2.4.18); the assembled
    # tangent serves only as preconditioner.
    "jfnk": ({"snes_mf_operator": "", "ksp_type": "gmres", **GAMG, "ksp_rtol": "1e-8",
              "ksp_gmres_restart": "100", "ksp_max_it": "1000"}, True, False, False),
    # Fully matrix-free: a shell matrix whose product is the analytic
    # directional derivative of the residual; Jacobi from its diagonal.
    "matrix-free": ({"ksp_type": "gmres", "pc_type": "jacobi", "ksp_rtol": "1e-8",
                     "ksp_gmres_restart": "200", "ksp_max_it": "5000"}, True, False, True),
}

#: the direct solver used when the iterative one fails (prefix "fallback_")
FALLBACK_OPTIONS = {"fallback_ksp_type": "preonly", "fallback_pc_type": "lu",
                    "fallback_pc_factor_mat_solver_type": "mumps"}


class FallbackKSP:
    """Context of a ``python`` KSP: the iterative solver configured by the
    ordinary ``-ksp_*``/``-pc_*`` options solves first; if it fails, the same
    system is solved by the direct solver (``-fallback_ksp_*``/``-fallback_pc_*``,
    MUMPS LU by default), as Guilkey & Weiss (2003, section 3.3) do."""

    def __init__(self):
        self.iterative = None
        self.direct = None
        self.fallbacks = 0          # number of linear solves that needed the direct solver

    def _inner(self, ksp):
        if self.iterative is None:
            comm = ksp.getComm()
            self.iterative = PETSc.KSP().create(comm=comm)
            self.direct = PETSc.KSP().create(comm=comm)
            self.direct.setOptionsPrefix("fallback_")

    def setFromOptions(self, ksp):
        self._inner(ksp)
        self.iterative.setFromOptions()
        self.direct.setFromOptions()

    def setUp(self, ksp):
        self._inner(ksp)
        A, P = ksp.getOperators()
        self.iterative.setOperators(A, P)
        self.direct.setOperators(A, P)

    def solve(self, ksp, b, x):
        # the operators change every Newton iteration (and are a matrix-free
        # MFFD operator with -snes_mf_operator): always hand the current ones on
        A, P = ksp.getOperators()
        self.iterative.setOperators(A, P)
        self.direct.setOperators(A, P)
        self.iterative.solve(b, x)
        reason = self.iterative.getConvergedReason()
        its = self.iterative.getIterationNumber()
        if reason < 0:
            self.fallbacks += 1
            self.direct.solve(b, x)
            reason = self.direct.getConvergedReason()
            its += self.direct.getIterationNumber()
        ksp.setIterationNumber(its)
        ksp.setConvergedReason(reason)

    def view(self, ksp, viewer):
        viewer.printfASCII("  iterative solver with direct fallback (Guilkey & Weiss 3.3):\n")
        if self.iterative is not None:
            self.iterative.view(viewer)
            self.direct.view(viewer)


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
        self.v = state.volume_n * smallmat.det(F_inc)
        self.a = assembly.spatial_tangent(sigma, c, dim)
        # axisymmetric hoop terms: small per-particle blocks (n, nn*dim, nn*dim)
        self.hoop = None if state.radius is None else assembly.hoop_tangents(
            sigma, c, F_inc, state.G, state.S, state.volume_n, state.radius)

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
            r_diag = grid.sum_scalar_to_owned(
                particle_to_grid(st.node_index, st.S**2, st.particle_mass, grid.n_local_nodes))
            keep = st.own_value_dofs()
            out *= np.where(keep, 1.0, r_diag / np.where(keep, 1.0, st.mass))
        if st.dynamic:
            out += st.mass_coefficient * st.mass
        out[st.fixed] = st.constraint_scale
        d.getArray()[:] = out / self.scale


def rigid_body_near_null_space(grid):
    """Rigid-body modes of the grid (translations and rotations) for GAMG."""
    coords = grid.da.getCoordinates()
    coords.setBlockSize(grid.dim)
    return PETSc.NullSpace().createRigidBody(coords)
