"""The implicit step of Guilkey & Weiss (2003), section 3.3, solved by PETSc SNES.

:class:`StepState` holds everything that is fixed during the Newton
iterations of one step (the particle footprint on the reset grid, the grid
state interpolated from the particles, the constraints). :class:`ImplicitSolver`
owns the PETSc objects (SNES, the DMDA matrix, vectors) and exposes the
residual ``R(u) = -Q`` (G&W step 3) and its exact Jacobian
``K_mat + K_geo + 4/dt^2 M`` (step 2) to SNES. Solver choices come from the
PETSc options database (command line > YAML ``solver.petsc`` > defaults).
"""
import atexit
import weakref
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
from petsc4py import PETSc

from . import assembly, smallmat
from .convergence import GuilkeyWeissTest
from .stages import log_stage
from .linear import FALLBACK_OPTIONS, PRESETS, FallbackKSP, TangentShell, rigid_body_near_null_space
from .transfer import gradient_at_particles, grid_to_particle, particle_to_grid, scatter


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
    group_order: np.ndarray       # particles sorted by the node set they touch
    group_starts: np.ndarray      # first particle of each group in that order
    group_nodes: np.ndarray       # (n_groups, nn) ghosted-local nodes of each group
    mass: np.ndarray              # owned dofs: lumped nodal mass (repeated per component)
    velocity: np.ndarray          # owned dofs: v_g(t) (eq. 3)
    acceleration: np.ndarray      # owned dofs: a_g(t)
    external_force: np.ndarray    # owned dofs: Fext_g(t+dt) (eq. 4)
    fixed: np.ndarray             # owned dofs: bool, prescribed
    fixed_value: np.ndarray       # owned dofs: prescribed incremental displacement
    constraint_scale: float       # diagonal used for prescribed rows
    extra: dict = field(default_factory=dict)

    scheme: str = "newmark"       # newmark | backward_euler | quasi_static
    plane_stress: bool = False    # solve F33 so that sigma33 = 0 at every particle
    radius: np.ndarray = None     # axisymmetric: particle radius at t (None otherwise)
    history: dict = field(default_factory=dict)   # material history at t (per particle)
    particle_mass: np.ndarray = None  # (n,) particle masses (momentum formulation)
    projection_floor: float = 0.0     # nodes with no more mass keep their own u (momentum formulation)

    @property
    def mass_coefficient(self):
        """d(inertia)/du per unit mass: 4/dt^2 (trapezoidal), 1/dt^2 (backward Euler)."""
        return {"newmark": 4.0, "backward_euler": 1.0}.get(self.scheme, 0.0) / self.dt**2

    def grid_kinematics(self, u):
        """v_g(t+dt) and a_g(t+dt) for the incremental displacement u:
        trapezoidal rule (G&W eq. 14-16), backward Euler (Sulsky & Kaul's
        theta = 1: v = u / dt, a = (v - v(t)) / dt), or quasi-static (a = 0)."""
        dt, v, a = self.dt, self.velocity, self.acceleration
        if self.scheme == "newmark":
            return 2.0 / dt * u - v, 4.0 / dt**2 * u - 4.0 / dt * v - a
        if self.scheme == "backward_euler":
            return u / dt, (u / dt - v) / dt
        return u / dt, np.zeros_like(u)

    def free_flight(self):
        """The part of u set by the grid state at t alone (owned dofs): u with
        a(t+dt) = 0 for the trapezoidal rule, dt v(t) for backward Euler,
        nothing in quasi-statics."""
        if self.scheme == "newmark":
            return self.dt * self.velocity + 0.25 * self.dt**2 * self.acceleration
        if self.scheme == "backward_euler":
            return self.dt * self.velocity
        return np.zeros_like(self.velocity)

    def own_value_dofs(self):
        """Owned dofs that the momentum formulation's projection leaves alone:
        prescribed ones and those of nodes with (next to) no mass. A particle
        within round-off of a cell face gives the node across it a mass of
        ~1e-16 m_p made of round-off: projecting onto it would divide noise by
        noise (and leave a numerically zero Jacobian column)."""
        return self.fixed | ~(self.mass > self.projection_floor)

    def inertia(self, u):
        """M a(t+dt) as a function of u (G&W eq. 16 for the trapezoidal rule)."""
        return self.mass * self.grid_kinematics(u)[1]


def particle_kinematics(state, u_local):
    """F_inc, F(t+dt) and the number of inverted particles (det F_inc <= 0)
    for ghosted-local nodal displacements (G&W step 5)."""
    grad_u = gradient_at_particles(state.node_index, state.G, u_local)
    F_inc = assembly.deformation_increment(grad_u)
    if state.radius is not None:        # axisymmetric hoop stretch (r + u_r) / r
        u_r = grid_to_particle(state.node_index, state.S, u_local)[:, 0]
        F_inc[:, 2, 2] = 1.0 + u_r / state.radius
    F = np.matmul(F_inc, state.F_n)
    J_inc = smallmat.det(F_inc)        # full 3x3: an axisymmetric hoop stretch can invert too
    return F_inc, F, int(np.sum(~(J_inc > 0.0)))


def project_displacement(state, grid, u_owned, u_local, base=None):
    """Momentum formulation (Sulsky & Kaul 3.2.1): the particles are deformed
    by the mass-weighted projection of the particle displacements,

        u~_i = u0_i + sum_p m_p N_ip du_p / m_i,   du_p = sum_j N_jp (u_j - u0_j),

    the displacement form of eq. 3.2.7: the grid velocity remapped from the
    updated particle velocities v_p + dt sum_i N_ip a_i (eq. 3.2.6), whose
    old part m_p v_p maps back to the grid velocity of eq. 3.2.3 unchanged.
    ``base`` = (owned, local) u0 is that old part (dt v_g + dt^2/4 a_g for
    the trapezoidal rule, dt v_g for backward Euler, 0 in quasi-statics);
    None projects u itself (the linear map R of the Jacobian). A node that
    a particle has only just entered gets that particle's displacement
    instead of an unbalanced force over a tiny mass. Prescribed dofs, and
    nodes with no mass to speak of (a particle exactly on a cell face: the
    projection is 0/0), keep their own values (rows of R: identity).
    Returns owned and ghosted-local u~. Collective."""
    if base is not None:
        u_owned, u_local = u_owned - base[0], u_local - base[1]
    du = grid_to_particle(state.node_index, state.S, u_local)
    weighted = particle_to_grid(state.node_index, state.S, state.particle_mass[:, None] * du,
                                grid.n_local_nodes)
    keep = state.own_value_dofs()
    projected = grid.sum_to_owned(weighted) / np.where(keep, 1.0, state.mass)
    projected[keep] = u_owned[keep]
    if base is not None:
        projected += base[0]
    return projected, grid.owned_to_local(projected)


def material_update(material, F, history, tangent, plane_stress=False, F_inc=None):
    """``material.update`` for plane strain / 3D, or for plane stress: the
    thickness stretch F33 is found by a vectorized local Newton so that
    sigma33 = 0 (d sigma33 / d ln F33 = c3333 + sigma33), F and F_inc are
    updated in place, and the in-plane tangent is condensed,
    c_abcd - c_ab33 c_33cd / c_3333, so Newton on the grid stays exact."""
    if not plane_stress or len(F) == 0:
        return material.update(F, history, tangent)
    for _ in range(50):
        sigma, c, new = material.update(F, history, True)
        s33 = sigma[:, 2, 2]
        scale = np.abs(c[:, 2, 2, 2, 2]) + np.abs(sigma).max(axis=(1, 2))
        if np.all(np.abs(s33) <= 1e-13 * scale):
            break
        step = np.exp(-s33 / (c[:, 2, 2, 2, 2] + s33))
        F[:, 2, 2] *= step
        if F_inc is not None:
            F_inc[:, 2, 2] *= step
    if tangent:
        c = c.copy()
        c[:, :2, :2, :2, :2] -= (c[:, :2, :2, 2, 2][:, :, :, None, None] * c[:, 2, 2, :2, :2][:, None, None, :, :]
                                 / c[:, 2, 2, 2, 2][:, None, None, None, None])
    else:
        c = None
    return sigma, c, new


def constitutive_update(state, F, tangent, F_inc=None):
    """Cauchy stress (n, 3, 3) and, if ``tangent``, the spatial elasticity
    tensor (n, 3, 3, 3, 3) for every particle, material by material. History
    variables start from the values committed at t (``state.history``); the
    updated ones are left in ``state.extra["history"]`` for the commit."""
    n = len(F)
    sigma = np.zeros((n, 3, 3))
    c = np.zeros((n, 3, 3, 3, 3)) if tangent else None
    new_history = {k: v.copy() for k, v in state.history.items()}
    for material, index in state.material_groups:
        old = {k: state.history[k][index] for k in material.history}
        Fi = F[index]
        Fi_inc = F_inc[index] if F_inc is not None else None
        s, cc, new = material_update(material, Fi, old, tangent, state.plane_stress, Fi_inc)
        if state.plane_stress:                 # write the solved thickness stretch back
            F[index] = Fi
            if F_inc is not None:
                F_inc[index] = Fi_inc
        sigma[index] = s
        if tangent:
            c[index] = cc
        for k, v in new.items():
            new_history[k][index] = v
    state.extra["history"] = new_history
    return sigma, c


class ImplicitSolver:
    """PETSc objects of the implicit solve: SNES on the DMDA, the tangent
    matrix (exactly preallocated by the DMDA, or a shell for the matrix-free
    preset), residual and work vectors.

    The residual is made dimensionless by ``residual_scale`` (Sulsky & Kaul
    3.2.2: Young's modulus times h^(dim-1), a force per unit thickness in
    2D), so tolerances mean the same at any scale. Reactions are computed
    from :meth:`unconstrained_residual`, which is not scaled.
    """

    def __init__(self, grid, solver_config, default_options, residual_scale, stages=None,
                 formulation="velocity"):
        self.grid = grid
        self.momentum = formulation == "momentum"
        self.da = grid.da
        self.state = None
        self.stages = stages or {}
        self.residual_scale = float(residual_scale)
        db = PETSc.Options()
        self.preset = db.getString("pimpm_preset", solver_config["preset"])
        if self.preset not in PRESETS:
            raise ValueError(f"-pimpm_preset {self.preset}: expected one of {', '.join(PRESETS)}")
        preset_options, iterative, spd, self.matrix_free = PRESETS[self.preset]
        if self.momentum and spd:
            raise ValueError(f"solver.preset = {self.preset!r}: expected a preset for non-symmetric "
                             "tangents (gmres-gamg, mumps, jfnk or matrix-free) with "
                             "time.formulation: momentum (its tangent K R is not symmetric)")
        self.fallback = None
        use_fallback = iterative and not self.matrix_free and db.getBool(
            "pimpm_fallback", solver_config["fallback"])
        options = dict(default_options)
        options.update(preset_options)
        if use_fallback:
            options.update(FALLBACK_OPTIONS)
        options.update(solver_config["petsc"])          # the YAML refines the preset
        self.options = options
        conv = solver_config["convergence"]
        test = db.getString("pimpm_convergence_test", conv["test"])
        self.gw_test = None
        if test == "guilkey_weiss":
            self.gw_test = GuilkeyWeissTest(
                db.getReal("pimpm_gw_displacement_tol", conv["displacement_tolerance"]),
                db.getReal("pimpm_gw_energy_tol", conv["energy_tolerance"]))
        elif test != "petsc":
            raise ValueError(f"-pimpm_convergence_test {test}: expected petsc or guilkey_weiss")

        self.X = self.da.createGlobalVec()
        self.R = self.da.createGlobalVec()
        self.diag = self.da.createGlobalVec()
        comm = self.da.getComm()
        if self.matrix_free:
            self.shell = TangentShell(grid)
            n_local, n_global = self.X.getLocalSize(), self.X.getSize()
            self.J = PETSc.Mat().createPython(((n_local, n_global), (n_local, n_global)),
                                              context=self.shell, comm=comm)
            self.J.setUp()
        elif self.momentum:
            # Jacobian M c + K R: K and R on the DMDA pattern, their product
            # on its own (wider) pattern, fixed once here from the full stencil
            self.shell = None
            self.K = self.da.createMat()
            self.K.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
            self.projection = self.da.createMat()
            self.projection.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
            self.projection.setOption(PETSc.Mat.Option.KEEP_NONZERO_PATTERN, True)
            self.J = self.K.matMult(self.projection)
            if iterative:
                self.J.setNearNullSpace(rigid_body_near_null_space(grid))
        else:
            self.shell = None
            self.J = self.da.createMat()
            self.J.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
            if spd:
                self.J.setOption(PETSc.Mat.Option.SPD, True)
            if iterative:
                self.J.setNearNullSpace(rigid_body_near_null_space(grid))
        self.snes = PETSc.SNES().create(comm=comm)
        self.snes.setDM(self.da)
        self.snes.setFunction(self._form_residual, self.R)
        self.snes.setJacobian(self._form_jacobian, self.J, self.J)
        if self.gw_test is not None:
            self.snes.setConvergenceTest(self.gw_test)
        if use_fallback:
            ksp = self.snes.getKSP()
            ksp.setOptionsPrefix("pimpm_outer_")       # the inner solvers read -ksp_*, -pc_*
            ksp.setType(PETSc.KSP.Type.PYTHON)
            self.fallback = FallbackKSP()
            ksp.setPythonContext(self.fallback)
        with scoped_options(options):
            self.snes.setFromOptions()
            if use_fallback:
                self.snes.getKSP().setUp()
        self.row_offset = self.X.getOwnershipRange()[0]
        self.inverted = False
        self.residual_evaluations = 0
        self.destroyed = False
        _LIVE_SOLVERS.add(self)

    def destroy(self):
        """Free the PETSc objects now (collective); Python contexts held by
        PETSc (python KSP, shell matrix) must not outlive PetscFinalize."""
        if self.destroyed:
            return
        self.destroyed = True
        if self.fallback is not None and self.fallback.iterative is not None:
            self.fallback.iterative.destroy()
            self.fallback.direct.destroy()
        for obj in (self.snes, self.J, self.X, self.R, self.diag):
            obj.destroy()
        if self.momentum and not self.matrix_free:
            self.K.destroy()
            self.projection.destroy()

    def describe(self):
        """One line naming the solver (for the run summary)."""
        ksp = self.snes.getKSP()
        if self.fallback is not None:
            inner = self.fallback.iterative
            linear = (f"{inner.getType()}+{inner.getPC().getType()} with direct fallback "
                      f"({self.fallback.direct.getType()}+{self.fallback.direct.getPC().getType()})")
        else:
            linear = f"{ksp.getType()}+{ksp.getPC().getType()}"
        test = "Guilkey-Weiss eq. 13" if self.gw_test else "PETSc (rtol/atol/stol)"
        db = PETSc.Options()
        line_search = db.getString("snes_linesearch_type", self.options.get("snes_linesearch_type", "bt"))
        operator = ", matrix-free operator" if (db.hasName("snes_mf_operator")
                                                or "snes_mf_operator" in self.options) else ""
        return (f"preset {self.preset}: SNES {self.snes.getType()} (line search {line_search}"
                f"{operator}), linear {linear}, convergence {test}")

    # ----------------------------------------------------------------- kernels
    def internal_force(self, sigma, F_inc):
        """Fint on owned dofs (summed over ranks) for stresses and increments."""
        st = self.state
        dim = self.grid.dim
        P = assembly.incremental_first_piola(sigma, F_inc, dim)
        pairs = assembly.internal_force_pairs(P, st.G, st.volume_n)
        if st.radius is not None:
            pairs[:, :, 0] += assembly.hoop_force_pairs(sigma, F_inc, st.S, st.volume_n, st.radius)
        return self.grid.sum_to_owned(scatter(st.node_index, pairs, self.grid.n_local_nodes))

    def kinematic_displacement(self, u_owned, u_local):
        """The ghosted-local displacement that deforms the particles: u itself
        (velocity formulation) or its projection R u (momentum formulation)."""
        if not self.momentum:
            return u_local
        st = self.state
        if "projection_base" not in st.extra:
            base = st.free_flight()
            st.extra["projection_base"] = (base, self.grid.owned_to_local(base))
        return project_displacement(st, self.grid, u_owned, u_local, st.extra["projection_base"])[1]

    def _kinematics(self, u_owned, u_local):
        """Particle kinematics, or None on every rank if any rank has an
        inverted particle (collective, so that no rank is left in a sum)."""
        F_inc, F, n_inverted = particle_kinematics(self.state, self.kinematic_displacement(u_owned, u_local))
        if self.grid.comm.allreduce(n_inverted) > 0:
            self.inverted = True
            return None
        return F_inc, F

    def inverts(self, state, u_owned):
        """True on every rank if the displacement ``u_owned`` inverts a
        particle anywhere. Collective."""
        self.state = state
        u_local = self.kinematic_displacement(u_owned, self.grid.owned_to_local(u_owned))
        _, _, n_inverted = particle_kinematics(state, u_local)
        return self.grid.comm.allreduce(n_inverted) > 0

    def unconstrained_residual(self, u_owned, u_local):
        """-Q of G&W step 3 before constraints: Fint + M a - Fext (owned
        dofs, in force units), or None if a particle inverted."""
        st = self.state
        kin = self._kinematics(u_owned, u_local)
        if kin is None:
            return None
        F_inc, F = kin
        with self._stage("Constitutive update"):
            sigma, _ = constitutive_update(st, F, tangent=False, F_inc=F_inc)
        st.extra["kinematics"] = (F_inc, F, sigma)      # reused by the particle update
        r = self.internal_force(sigma, F_inc) - st.external_force
        if st.dynamic:
            r += st.inertia(u_owned)
        return r

    def _stage(self, name):
        return log_stage(self.stages.get(name))

    # ----------------------------------------------------------------- SNES callbacks
    def _form_residual(self, snes, X, R):
        st = self.state
        self.residual_evaluations += 1
        u_local = self.grid.vec_to_local(X)
        u = X.getArray(readonly=True)
        r = R.getArray()
        unconstrained = self.unconstrained_residual(u, u_local)
        if unconstrained is None:
            # A domain error: an infinite residual makes the line search back
            # off (bt) or SNES stop with DIVERGED_FNORM_NAN.
            r[:] = np.inf
            return
        r[:] = unconstrained / self.residual_scale
        r[st.fixed] = (st.constraint_scale / self.residual_scale) * (u[st.fixed] - st.fixed_value[st.fixed])

    def _form_jacobian(self, snes, X, J, P):
        st = self.state
        grid = self.grid
        u_local = grid.vec_to_local(X)
        kin = self._kinematics(X.getArray(readonly=True), u_local)
        if self.matrix_free:
            if kin is not None:
                with self._stage("Constitutive update"):
                    sigma, c = constitutive_update(st, kin[1], tangent=True, F_inc=kin[0])
                project = (lambda v: project_displacement(st, grid, v, grid.owned_to_local(v))) \
                    if self.momentum else None
                self.shell.update(st, sigma, c, kin[0], self.residual_scale, project)
            P.assemble()
            if J != P:
                J.assemble()
            return
        K = self.K if self.momentum else P
        with self._stage("Assembly"):
            K.zeroEntries()
        if kin is not None and len(kin[1]):
            F_inc, F = kin
            with self._stage("Constitutive update"):
                sigma, c = constitutive_update(st, F, tangent=True, F_inc=F_inc)
            with self._stage("Assembly"):
                Ke = assembly.element_tangents(sigma, c, F_inc, st.G, st.volume_n)
                if st.radius is not None:
                    Ke += assembly.hoop_tangents(sigma, c, F_inc, st.G, st.S, st.volume_n, st.radius)
                Ke = assembly.sum_by_group(Ke[st.group_order], st.group_starts)
                nodes = st.group_nodes.astype(PETSc.IntType)
                K.setValuesBlockedLocalRCV(nodes, nodes, Ke.reshape(len(nodes), -1),
                                           addv=PETSc.InsertMode.ADD_VALUES)
        with self._stage("Assembly"):
            K.assemble()
            if self.momentum:
                self._assemble_projection()
                K.matMult(self.projection, result=P)        # d Fint / du = K R
            if st.dynamic:
                self.diag.getArray()[:] = st.mass_coefficient * st.mass
                P.setDiagonal(self.diag, addv=PETSc.InsertMode.ADD_VALUES)
            rows = (np.nonzero(st.fixed)[0] + self.row_offset).astype(PETSc.IntType)
            P.zeroRowsColumns(rows, diag=st.constraint_scale)
            P.scale(1.0 / self.residual_scale)
            if J != P:
                J.assemble()

    def _assemble_projection(self):
        """R = M^-1 S^T m S with identity rows at prescribed and massless
        dofs (the derivative of :func:`project_displacement`)."""
        st, R = self.state, self.projection
        R.zeroEntries()
        if len(st.particle_mass):
            blocks = assembly.projection_blocks(st.particle_mass, st.S, st.group_order,
                                                st.group_starts, self.grid.dim)
            nodes = st.group_nodes.astype(PETSc.IntType)
            R.setValuesBlockedLocalRCV(nodes, nodes, blocks.reshape(len(nodes), -1),
                                       addv=PETSc.InsertMode.ADD_VALUES)
        R.assemble()
        keep = st.own_value_dofs()
        self.diag.getArray()[:] = np.where(keep, 0.0, 1.0 / np.where(keep, 1.0, st.mass))
        R.diagonalScale(L=self.diag)
        rows = (np.nonzero(keep)[0] + self.row_offset).astype(PETSc.IntType)
        R.zeroRows(rows, diag=1.0)

    # ----------------------------------------------------------------- solve
    def solve(self, state, initial_guess):
        """Newton on the incremental grid displacement. Returns (u_owned, info)."""
        self.state = state
        self.inverted = False
        self.residual_evaluations = 0
        fallbacks_before = self.fallback.fallbacks if self.fallback else 0
        self.X.getArray()[:] = initial_guess
        self.snes.setConvergenceHistory(length=1000, reset=True)
        petsc_error = None
        with self._stage("Solve"):
            try:
                self.snes.solve(None, self.X)
            except PETSc.Error as err:
                # e.g. MUMPS solving with a factorization that failed on a
                # singular tangent: a failed step, cut and retried like the
                # others, after dropping the preconditioner's factors
                petsc_error = err
                self.snes.getKSP().getPC().reset()
        reason = self.snes.getConvergedReason()
        norms, lits = self.snes.getConvergenceHistory()
        its = self.snes.getIterationNumber()
        linear = self.snes.getLinearSolveIterations()
        # Residual evaluations beyond one per Newton iteration are line-search
        # backtracks; with -snes_mf_operator the Krylov products evaluate the
        # residual too, so backtracks cannot be counted this way (-1).
        mf = PETSc.Options().hasName("snes_mf_operator") or "snes_mf_operator" in self.options
        extra = -1 if mf else self.residual_evaluations - 1 - its
        if petsc_error is not None:
            reason = min(int(reason), -1)
        info = {
            "reason": int(reason),
            "reason_name": (_reason_name(reason) if petsc_error is None else
                            f"PETSc error {petsc_error.ierr} in the linear solve (singular tangent?)"),
            "converged": reason > 0 and petsc_error is None,
            "newton_iterations": its,
            "linear_iterations": linear,
            "backtracks": int(extra) if extra < 0 else max(0, int(extra)),
            "linear_fallbacks": (self.fallback.fallbacks - fallbacks_before) if self.fallback else 0,
            "residual_history": np.array(norms, dtype=float),
            "inverted": bool(self.grid.comm.allreduce(self.inverted)),
        }
        return self.X.getArray(readonly=True).copy(), info


_LIVE_SOLVERS = weakref.WeakSet()


@atexit.register
def _destroy_live_solvers():
    """Registered after petsc4py's own exit handler, so it runs before
    PetscFinalize: Python contexts held by PETSc objects must go first."""
    for solver in list(_LIVE_SOLVERS):
        solver.destroy()


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
