"""The implicit step of Guilkey & Weiss (2003), section 3.3, solved by PETSc SNES.

:class:`StepState` holds everything that is fixed during the Newton
iterations of one step (the particle footprint on the reset grid, the grid
state interpolated from the particles, the constraints). :class:`ImplicitSolver`
owns the PETSc objects (SNES, the DMDA matrix, vectors) and exposes the
residual ``R(u) = -Q`` (G&W step 3) and its exact Jacobian
``K_mat + K_geo + 4/dt^2 M`` (step 2) to SNES. Solver choices come from the
PETSc options database (command line > YAML ``solver.petsc`` > defaults).
"""
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
from petsc4py import PETSc

from . import assembly, smallmat
from .transfer import gradient_at_particles, scatter


@dataclass
class StepState:
    """Data that stay fixed while Newton iterates on one step."""
    dt: float
    dynamic: bool
    node_index: np.ndarray        # (n, nn) ghosted-local node of each (particle, node) pair
    S: np.ndarray                 # (n, nn) weights at x_p(t)
    G: np.ndarray                 # (n, nn, dim) gradients at x_p(t)
    F_n: np.ndarray               # (n, 3, 3) deformation gradient at t
    volume_n: np.ndarray          # (n,) volume at t
    material_groups: list         # [(material, particle index array)]
    cell_starts: np.ndarray       # first particle of each occupied cell (particles sorted by cell)
    cell_nodes: np.ndarray        # (n_cells_occupied, nn) ghosted-local nodes of each cell
    mass: np.ndarray              # owned dofs: lumped nodal mass (repeated per component)
    velocity: np.ndarray          # owned dofs: v_g(t) (eq. 3)
    acceleration: np.ndarray      # owned dofs: a_g(t)
    external_force: np.ndarray    # owned dofs: Fext_g(t+dt) (eq. 4)
    fixed: np.ndarray             # owned dofs: bool, prescribed
    fixed_value: np.ndarray       # owned dofs: prescribed incremental displacement
    constraint_scale: float       # diagonal used for prescribed rows
    extra: dict = field(default_factory=dict)

    def inertia(self, u):
        """M a(t+dt) with Newmark/trapezoidal a = 4/dt^2 u - 4/dt v - a (G&W eq. 16)."""
        dt = self.dt
        return self.mass * (4.0 / dt**2 * u - 4.0 / dt * self.velocity - self.acceleration)


def particle_kinematics(state, u_local):
    """F_inc, F(t+dt) and the number of inverted particles (det F_inc <= 0)
    for ghosted-local nodal displacements (G&W step 5)."""
    grad_u = gradient_at_particles(state.node_index, state.G, u_local)
    F_inc = assembly.deformation_increment(grad_u)
    F = np.matmul(F_inc, state.F_n)
    dim = state.G.shape[2]
    J_inc = smallmat.det(F_inc[:, :dim, :dim])
    return F_inc, F, int(np.sum(~(J_inc > 0.0)))


def constitutive_update(state, F, tangent):
    """Cauchy stress (n, 3, 3) and, if ``tangent``, the spatial elasticity
    tensor (n, 3, 3, 3, 3) for every particle, material by material."""
    n = len(F)
    sigma = np.zeros((n, 3, 3))
    c = np.zeros((n, 3, 3, 3, 3)) if tangent else None
    for material, index in state.material_groups:
        if tangent:
            sigma[index], c[index] = material.stress_and_tangent(F[index])
        else:
            sigma[index] = material.stress(F[index])
    return sigma, c


class ImplicitSolver:
    """PETSc objects of the implicit solve: SNES on the DMDA, the tangent
    matrix (exactly preallocated by the DMDA), residual and work vectors."""

    def __init__(self, grid, options=None, stages=None):
        self.grid = grid
        self.da = grid.da
        self.state = None
        self.stages = stages or {}
        self.J = self.da.createMat()
        self.J.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
        self.X = self.da.createGlobalVec()
        self.R = self.da.createGlobalVec()
        self.diag = self.da.createGlobalVec()
        self.snes = PETSc.SNES().create(comm=self.da.getComm())
        self.snes.setDM(self.da)
        self.snes.setFunction(self._form_residual, self.R)
        self.snes.setJacobian(self._form_jacobian, self.J, self.J)
        self.snes.setConvergenceHistory(length=1000, reset=True)
        with scoped_options(options or {}):
            self.snes.setFromOptions()
        self.row_offset = self.X.getOwnershipRange()[0]
        self.inverted = False

    # ----------------------------------------------------------------- SNES callbacks
    def _stage(self, name):
        return self.stages.get(name)

    def internal_force(self, sigma, F_inc):
        """Fint on owned dofs (summed over ranks) for stresses and increments."""
        st = self.state
        dim = self.grid.dim
        P = assembly.incremental_first_piola(sigma, F_inc, dim)
        pairs = assembly.internal_force_pairs(P, st.G, st.volume_n)
        return self.grid.sum_to_owned(scatter(st.node_index, pairs, self.grid.n_local_nodes))

    def _kinematics(self, u_local):
        """Particle kinematics, or None on every rank if any rank has an
        inverted particle (collective, so that no rank is left in a sum)."""
        F_inc, F, n_inverted = particle_kinematics(self.state, u_local)
        if self.grid.comm.allreduce(n_inverted) > 0:
            self.inverted = True
            return None
        return F_inc, F

    def inverts(self, state, u_owned):
        """True on every rank if the displacement ``u_owned`` inverts a
        particle anywhere. Collective."""
        self.state = state
        _, _, n_inverted = particle_kinematics(state, self.grid.owned_to_local(u_owned))
        return self.grid.comm.allreduce(n_inverted) > 0

    def unconstrained_residual(self, u_owned, u_local):
        """-Q of G&W step 3 before constraints: Fint + M a - Fext (owned
        dofs), or None if a particle inverted."""
        st = self.state
        kin = self._kinematics(u_local)
        if kin is None:
            return None
        F_inc, F = kin
        sigma, _ = constitutive_update(st, F, tangent=False)
        r = self.internal_force(sigma, F_inc) - st.external_force
        if st.dynamic:
            r += st.inertia(u_owned)
        return r

    def _form_residual(self, snes, X, R):
        st = self.state
        u_local = self.grid.vec_to_local(X)
        u = X.getArray(readonly=True)
        r = R.getArray()
        unconstrained = self.unconstrained_residual(u, u_local)
        if unconstrained is None:
            # A domain error: an infinite residual makes SNES stop with
            # DIVERGED_FNORM_NAN (or the line search back off).
            r[:] = np.inf
            return
        r[:] = unconstrained
        r[st.fixed] = st.constraint_scale * (u[st.fixed] - st.fixed_value[st.fixed])

    def _form_jacobian(self, snes, X, J, P):
        st = self.state
        grid = self.grid
        u_local = grid.vec_to_local(X)
        P.zeroEntries()
        kin = self._kinematics(u_local)
        if kin is not None and len(kin[1]):
            F_inc, F = kin
            sigma, c = constitutive_update(st, F, tangent=True)
            Ke = assembly.element_tangents(sigma, c, F_inc, st.G, st.volume_n)
            Ke = assembly.sum_by_group(Ke, st.cell_starts)
            nodes = st.cell_nodes.astype(PETSc.IntType)
            P.setValuesBlockedLocalRCV(nodes, nodes, Ke.reshape(len(nodes), -1),
                                       addv=PETSc.InsertMode.ADD_VALUES)
        P.assemble()
        if st.dynamic:
            self.diag.getArray()[:] = 4.0 / st.dt**2 * st.mass
            P.setDiagonal(self.diag, addv=PETSc.InsertMode.ADD_VALUES)
        rows = (np.nonzero(st.fixed)[0] + self.row_offset).astype(PETSc.IntType)
        P.zeroRowsColumns(rows, diag=st.constraint_scale)
        if J != P:
            J.assemble()

    # ----------------------------------------------------------------- solve
    def solve(self, state, initial_guess):
        """Newton on the incremental grid displacement. Returns (u_owned, info)."""
        self.state = state
        self.inverted = False
        self.X.getArray()[:] = initial_guess
        self.snes.setConvergenceHistory(length=1000, reset=True)
        self.snes.solve(None, self.X)
        reason = self.snes.getConvergedReason()
        norms, lits = self.snes.getConvergenceHistory()
        info = {
            "reason": int(reason),
            "reason_name": _reason_name(reason),
            "converged": reason > 0,
            "newton_iterations": self.snes.getIterationNumber(),
            "linear_iterations": self.snes.getLinearSolveIterations(),
            "residual_history": np.array(norms, dtype=float),
            "inverted": bool(self.grid.comm.allreduce(self.inverted)),
        }
        return self.X.getArray(readonly=True).copy(), info


@contextmanager
def scoped_options(options):
    """Put program options (defaults, then the YAML ``solver.petsc`` block)
    into PETSc's database only while a solver reads them, so they never leak
    into other solvers; options already in the database (the command line)
    win and are left alone."""
    db = PETSc.Options()
    inserted = [key for key in options if not db.hasName(key)]
    for key in inserted:
        db.setValue(key, options[key])
    try:
        yield
    finally:
        for key in inserted:
            db.delValue(key)


def _reason_name(reason):
    for name in dir(PETSc.SNES.ConvergedReason):
        if not name.startswith("_") and getattr(PETSc.SNES.ConvergedReason, name) == reason:
            return name
    return str(reason)
