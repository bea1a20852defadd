"""The residual and the exact tangent of one implicit step (Guilkey & Weiss
2003, section 3.3, steps 2-5), as the problem object SNES calls back
(``form_residual``/``form_jacobian``, as in petsc4py's bratu3d demo). It
knows nothing of the solver that runs it: :mod:`pimpm.solver` sets SNES,
KSP and PC up from the options.

The unknown is the incremental grid displacement u from t to t+dt. The
residual is ``R(u) = -Q`` of step 3, the integrator's balance of the
internal force, the external force and the inertia, made dimensionless by
``residual_scale`` (Sulsky & Kaul 3.2.2); its exact derivative is
``K_mat + K_geo + 4/dt^2 M`` for the trapezoidal rule (step 2).
Prescribed dofs are eliminated symmetrically: their rows are
``constraint_scale (u - u_prescribed)``.
"""
import numpy as np
from petsc4py import PETSc

from .. import assembly, faults, kinematics
from ..materials.base import youngs_modulus
from ..materials.update import update_stress
from ..stages import log_stage
from ..transfer import gradient_at_particles, grid_to_particle, scatter
from .momentum import assemble_projection, project_displacement
from .shell import TangentShell


def residual_scale(config, materials):
    """Sulsky & Kaul 3.2.2: the largest Young's modulus times h^(dim-1) (a
    force per unit thickness in 2D, a force in 3D) makes the residual
    dimensionless."""
    dim = config["dim"]
    h = float(np.min((np.asarray(config["grid"]["upper"]) - np.asarray(config["grid"]["lower"]))
                     / np.asarray(config["grid"]["cells"])))
    young = max(youngs_modulus(m.shear_modulus, m.bulk_modulus) for m in materials)
    return young * h ** (dim - 1)


def constraint_scale(materials, grid, integrator, dt):
    """Diagonal of prescribed rows: the stiffness (and mass term) of a
    node, so that the eliminated rows are of the size of the others."""
    h = float(np.min(grid.spacing))
    k = max(m.p_wave_modulus for m in materials) * h ** (grid.dim - 2)
    if integrator.dynamic:
        k += integrator.mass_coefficient(dt) * max(m.density for m in materials) * grid.cell_volume
    return k


def particle_kinematics(state, u_local):
    """F_inc, F(t+dt) and the number of inverted particles (det F_inc <= 0)
    for ghosted-local nodal displacements (G&W step 5)."""
    grad_u = gradient_at_particles(state.node_index, state.G, u_local)
    F_inc = state.kinematics.deformation_increment(
        grad_u, state.radius, lambda: grid_to_particle(state.node_index, state.S, u_local))
    F = np.matmul(F_inc, state.F_n)
    return F_inc, F, kinematics.inverted_count(F_inc)


def constitutive_update(state, F, tangent, F_inc=None):
    """Cauchy stress (n, 3, 3) and, if ``tangent``, the spatial elasticity
    tensor for every particle at the trial F (G&W steps 4-5). History starts
    from the values committed at t; the updated one is left in
    ``state.extra["history"]`` for the commit."""
    sigma, c, state.extra["history"] = update_stress(state.material_groups, state.kinematics, F,
                                                     state.history, tangent, F_inc)
    return sigma, c


class StepProblem:
    """Residual and tangent of the implicit step on a grid, for the state of
    the step being solved (:attr:`state`, a StepState). ``momentum``:
    Sulsky & Kaul's momentum formulation (the tangent is K R, not symmetric).
    ``nonsymmetric_materials``: names of the material models whose tangent
    is not symmetric.
    """

    def __init__(self, grid, residual_scale, momentum=False, stages=None, nonsymmetric_materials=()):
        self.grid = grid
        self.momentum = momentum
        #: why the assembled tangent is not symmetric ("" if it is)
        self.asymmetry = ("time.formulation: momentum (its tangent K R is not symmetric)" if momentum else
                          f"material model {', '.join(sorted(set(nonsymmetric_materials)))} (its "
                          "consistent tangent is not symmetric)" if nonsymmetric_materials else "")
        #: is the assembled tangent symmetric? (then a symmetric factorization applies)
        self.symmetric = not self.asymmetry
        self.residual_scale = float(residual_scale)
        self.stages = stages or {}
        self.state = None
        self.step = 0
        self.inverted = False            # did a residual or Jacobian meet an inverted particle?
        self.residual_evaluations = 0
        self.diag = grid.da.createGlobalVec()
        self.row_offset = self.diag.getOwnershipRange()[0]
        self.K = self.projection = None

    def begin(self, state, step=0):
        """Start solving a step (``step``: its 1-based number)."""
        self.state = state
        self.step = step
        self.inverted = False
        self.residual_evaluations = 0

    def create_jacobian(self, matrix_free):
        """The matrix SNES fills through :meth:`form_jacobian`: a shell whose
        product is the analytic directional derivative (``matrix_free``), the
        DMDA matrix, or in the momentum formulation the product K R on its own
        (wider) pattern, fixed once here from the full stencil."""
        da = self.grid.da
        if matrix_free:
            X = da.createGlobalVec()
            sizes = (X.getLocalSize(), X.getSize())
            X.destroy()
            J = PETSc.Mat().createPython((sizes, sizes), context=TangentShell(self.grid),
                                         comm=da.getComm())
            J.setUp()
            return J
        if self.momentum:
            self.K = da.createMat()
            self.K.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
            self.projection = da.createMat()
            self.projection.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
            self.projection.setOption(PETSc.Mat.Option.KEEP_NONZERO_PATTERN, True)
            return self.K.matMult(self.projection)
        J = da.createMat()
        J.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
        return J

    def destroy(self):
        for obj in (self.diag, self.K, self.projection):
            if obj is not None:
                obj.destroy()

    def _stage(self, name):
        return log_stage(self.stages.get(name))

    # ----------------------------------------------------------------- physics
    def internal_force(self, sigma, F_inc):
        """Fint on owned dofs (summed over ranks) for stresses and increments;
        ``F_inc`` None: the stresses at t on the reset grid. Collective."""
        st = self.state
        pairs = st.kinematics.internal_force_pairs(sigma, F_inc, st.G, st.S, st.volume_n, st.radius)
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
        """-Q of G&W step 3 before constraints: the integrator's balance of
        Fint, Fext and M a (owned dofs, in force units), or None if a particle
        inverted. Reactions are read from it."""
        st = self.state
        kin = self._kinematics(u_owned, u_local)
        if kin is None:
            return None
        F_inc, F = kin
        with self._stage("Constitutive update"):
            sigma, _ = constitutive_update(st, F, tangent=False, F_inc=F_inc)
        st.extra["kinematics"] = (F_inc, F, sigma)      # reused by the particle update
        return st.integrator.balance(self.internal_force(sigma, F_inc) - st.external_force, st, u_owned)

    # ----------------------------------------------------------------- SNES callbacks
    def form_residual(self, snes, X, R):
        st = self.state
        self.residual_evaluations += 1
        faults.checkpoint("residual", self.grid.comm.rank, self.step)
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

    def form_jacobian(self, snes, X, J, P):
        st = self.state
        grid = self.grid
        u_local = grid.vec_to_local(X)
        kin = self._kinematics(X.getArray(readonly=True), u_local)
        if P.getType() == PETSc.Mat.Type.PYTHON:
            if kin is not None:
                with self._stage("Constitutive update"):
                    sigma, c = constitutive_update(st, kin[1], tangent=True, F_inc=kin[0])
                project = (lambda v: project_displacement(st, grid, v, grid.owned_to_local(v))) \
                    if self.momentum else None
                P.getPythonContext().update(st, sigma, c, kin[0], self.residual_scale, project)
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
                Ke = st.kinematics.element_tangents(sigma, c, F_inc, st.G, st.S, st.volume_n, st.radius)
                Ke = assembly.sum_by_group(Ke[st.group_order], st.group_starts)
                nodes = st.group_nodes.astype(PETSc.IntType)
                K.setValuesBlockedLocalRCV(nodes, nodes, Ke.reshape(len(nodes), -1),
                                           addv=PETSc.InsertMode.ADD_VALUES)
        with self._stage("Assembly"):
            K.assemble()
            if self.momentum:
                assemble_projection(st, self.projection, self.diag, self.row_offset, grid.dim)
                K.matMult(self.projection, result=P)        # d Fint / du = K R
            if st.integrator.stiffness_factor != 1.0:       # HHT: (1 + alpha) K
                P.scale(st.integrator.stiffness_factor)
            if st.dynamic:
                self.diag.getArray()[:] = st.mass_coefficient * st.mass
                P.setDiagonal(self.diag, addv=PETSc.InsertMode.ADD_VALUES)
            rows = (np.nonzero(st.fixed)[0] + self.row_offset).astype(PETSc.IntType)
            P.zeroRowsColumns(rows, diag=st.constraint_scale)
            P.scale(1.0 / self.residual_scale)
            if J != P:
                J.assemble()
