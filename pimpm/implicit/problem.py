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
from mpi4py import MPI
from petsc4py import PETSc

from .. import coo, faults, fbar, interrupt
from ..linear import FreeDofsOperator, free_dofs_operator
from ..kernels import fbar as fbar_kernels
from ..kernels import particle_step
from ..materials.model import youngs_modulus
from ..stages import log_stage
from .formulation import VelocityFormulation
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


class ParticleEvaluation:
    """What the compiled kernel computed at one iterate (ghosted-local
    kinematic displacement ``u``): F_inc, F, Cauchy stress, packed history,
    the internal force on the ghosted-local nodes, what the tangent needs
    (the in-plane stiffness density times the current volume, and the
    axisymmetric hoop couplings), and how many particles the increment
    inverts on this rank. The tangent (assembled, or the matrix-free
    product) reuses it when SNES asks for the Jacobian at the iterate whose
    residual it has just evaluated (G&W steps 4-5 are done once per iterate)."""

    def __init__(self, state, n_nodes, dim):
        n = len(state.F_n)
        self.u = None
        self.F_inc = np.empty((n, 3, 3))
        self.F = np.empty((n, 3, 3))
        self.sigma = np.empty((n, 3, 3))
        self.history = np.empty_like(state.history_packed)
        self.force = np.empty((n_nodes, dim))
        self.tangent = np.empty((n,) + (dim,) * 4)
        axisymmetric = state.kinematics.kernel_code == particle_step.AXISYMMETRIC
        self.hoop = np.empty((n if axisymmetric else 0, 2 * dim * dim + 1))
        averaged = state.cells is not None and state.cells.count > 0     # on this rank
        self.fbar_q = np.empty((n if averaged else 0, 3, 3))          # F-bar: v Q per particle
        self.fbar_weight = np.empty(n if averaged else 0)             # F-bar: v / V_cell
        self.inverted = 0
        self.unconverged = 0          # plane stress: particles whose thickness solve failed
        self.jbar = _NO_JBAR          # F-bar on the nodes: each particle's J_bar
        self._coupling = None         # ... and its (u, R, D) (node_coupling)

    def evaluate(self, state, u_local, dim):
        """Fill everything for ``u_local`` (G&W step 5 and the internal force).
        Collective with F-bar on the nodes (its average sums over the ranks)."""
        st, mt = state, state.materials
        cells = st.cells if st.cells is not None else fbar.NONE
        radius = st.radius if st.radius is not None else _NO_RADIUS
        axes, footprint = tuple(range(dim)), tuple(range(st.S.shape[1]))
        self.jbar = _NO_JBAR
        if cells.kind == "nodes":            # the increments first, then their average on the nodes
            self.jbar = cells.increments_and_jbar(st.kinematics.kernel_code, u_local, st.node_index, st.active,
                                                  st.S, st.G, radius, st.volume_n, self.F_inc)
        self.inverted, self.unconverged = particle_step.evaluate_particles(
            st.kinematics.kernel_code, axes, footprint, u_local,
            st.node_index, st.active, st.S, st.G, radius,
            st.F_n, st.volume_n, mt.only_model, mt.models, mt.params, mt.material_of, st.history_packed, True, True,
            cells.cell, 0 if cells.kind == "nodes" else cells.count, self.F_inc, self.F, self.sigma, self.history,
            self.force, self.tangent, self.hoop, self.fbar_q, self.fbar_weight, self.jbar, mt.f_bar_alpha)
        self.u = u_local.copy()

    def node_coupling(self, state):
        """F-bar on the nodes: (R, D) of :meth:`pimpm.fbar.AveragedNodes.coupling`
        at this iterate, made once (collective: every rank asks at the same
        iterate)."""
        if self._coupling is None or self._coupling[0] is not self.u:
            st = state
            R, D = st.cells.coupling(st.kinematics.kernel_code, st.node_index, st.active, st.S, st.G,
                                     st.radius if st.radius is not None else _NO_RADIUS, self.F_inc, self.fbar_q,
                                     st.volume_n, self.jbar)
            self._coupling = (self.u, R, D)
        return self._coupling[1], self._coupling[2]

    def matches(self, u_local):
        return self.u is not None and np.array_equal(self.u, u_local)


_NO_RADIUS = np.zeros(0)
_NO_JBAR = np.zeros(0)


class StepProblem:
    """Residual and tangent of the implicit step on a grid, for the state of
    the step being solved (:attr:`state`, a StepState). ``formulation``:
    what deforms the particles (:mod:`pimpm.implicit.formulation`; Guilkey &
    Weiss's velocity formulation if None). ``nonsymmetric_materials``: names
    of the material models whose tangent is not symmetric; ``f_bar``: some
    material averages its volume change per cell (F-bar: a non-symmetric
    tangent that couples the particles of a cell, pimpm.kernels.fbar).
    """

    def __init__(self, grid, residual_scale, formulation=None, stages=None, nonsymmetric_materials=(),
                 terms=(), f_bar=False):
        self.grid = grid
        #: the run's nodal terms (pimpm.terms): their forces and derivatives join the particles'
        self.terms = list(terms)
        self.formulation = formulation or VelocityFormulation()
        materials = (f"material model {', '.join(sorted(set(nonsymmetric_materials)))} (its "
                     "consistent tangent is not symmetric)" if nonsymmetric_materials else "")
        averaged = ("F-bar (its consistent tangent is not symmetric)" if f_bar else "")
        frictional = [t.name for t in self.terms if not t.symmetric_tangent]
        friction = (f"frictional contact with {', '.join(frictional)} (Coulomb's return map has "
                    "no symmetric tangent)" if frictional else "")
        #: why the assembled tangent is not symmetric ("" if it is)
        self.asymmetry = self.formulation.asymmetry or materials or averaged or friction
        #: is the assembled tangent symmetric? (then a symmetric factorization applies)
        self.symmetric = not self.asymmetry
        #: has every material's stiffness density major symmetry? (each particle's
        #: element matrix is then symmetric: the kernel computes half of it)
        self.symmetric_density = not nonsymmetric_materials and not f_bar
        self.residual_scale = float(residual_scale)
        self.stages = stages or {}
        self.state = None
        self.step = 0
        self.inverted = False            # did a residual or Jacobian meet an inverted particle?
        self.thickness_failed = False    # ... or a plane-stress thickness solve that failed?
        self.residual_evaluations = 0
        self.diag = grid.da.createGlobalVec()
        self.row_offset = self.diag.getOwnershipRange()[0]
        #: the tangent on the step's pattern is assembled through COO (pimpm.coo)
        self.coo = coo.available() and self.formulation.assembles_on_pattern
        #: the step's tangent on the free dofs only (:meth:`create_free_jacobian`), or None
        self.free_matrix = None
        #: the positions in the COO values of the free matrix's entries (row
        #: and column free), and a buffer for those values
        self.free_entries = self.free_values = None

    def begin(self, state, step=0):
        """Start solving a step (``step``: its 1-based number)."""
        self.state = state
        self.step = step
        self.inverted = False
        self.thickness_failed = False
        self.residual_evaluations = 0
        if state.evaluation is None:
            state.evaluation = ParticleEvaluation(state, self.grid.n_local_nodes, self.grid.dim)
        self.formulation.begin_step(state, self.grid)
        for term in self.terms:
            term.begin_newton(state)

    def end_step(self):
        """The step is over (its particles updated, or it failed): drop its
        state (the particles' footprint, weights, stiffness densities and
        iterates, about 2 kB a particle in 3D with GIMP) and the terms'
        share of it, so that the next step's (and the migration's copies)
        are not made beside them: the peak resident memory of a step grew by
        about 1.4 KiB a particle more without this (docs/PERFORMANCE.md)."""
        self.state = None
        for term in self.terms:
            term.end_newton()

    @property
    def assembles_on_pattern(self):
        """Is the tangent a matrix on the step's own nonzero pattern (the
        velocity formulation, assembled), to be made anew when the pattern
        changes? (The momentum formulation's K R keeps the DMDA pattern.)"""
        return self.formulation.assembles_on_pattern

    def create_jacobian(self, matrix_free, pattern=None):
        """The matrix SNES fills through :meth:`form_jacobian`: a shell whose
        product is the analytic directional derivative (``matrix_free``), an
        AIJ matrix holding exactly the couplings of ``pattern`` (a
        TangentPattern: nodes no particle reaches keep only their diagonal),
        or in the momentum formulation the product K R on its own (wider)
        pattern, fixed once here from the DMDA's full stencil."""
        da = self.grid.da
        if matrix_free:
            X = da.createGlobalVec()
            sizes = (X.getLocalSize(), X.getSize())
            X.destroy()
            J = PETSc.Mat().createPython((sizes, sizes), context=TangentShell(self.grid, self.terms),
                                         comm=da.getComm())
            J.setUp()
            return J
        if not self.formulation.assembles_on_pattern:
            return self.formulation.create_matrix(da)
        return pattern_matrix(self.grid, pattern, self.coo)

    def create_free_jacobian(self, pattern, free):
        """The step's tangent on its free dofs only (``free``: owned dofs,
        not prescribed), filled by :meth:`form_jacobian` with the values it
        gives the whole matrix: the same COO pattern, with a local-to-global
        map that sends every prescribed dof to -1, whose entries PETSc then
        ignores. Rows are owned where the DMDA owns the dof; block size 1 (a
        node may have one dof prescribed and the other free). Replaces the
        previous step's. Collective."""
        grid = self.grid
        comm = grid.comm
        n_free = int(np.count_nonzero(free))
        first = comm.exscan(n_free) or 0
        total = comm.allreduce(n_free)
        owned_index = np.full(len(free), -1.0)
        owned_index[free] = first + np.arange(n_free)
        local_index = np.rint(grid.owned_to_local(owned_index).reshape(-1)).astype(PETSc.IntType)
        if self.free_matrix is not None:
            self.free_matrix.destroy()
        A = PETSc.Mat().create(comm=grid.da.getComm())
        A.setSizes(((n_free, total), (n_free, total)))
        A.setType(PETSc.Mat.Type.AIJ)
        lgmap = PETSc.LGMap().create(local_index, comm=grid.da.getComm())
        A.setLGMap(lgmap, lgmap)
        lgmap.destroy()
        # only the entries of free rows and columns: PETSc would drop the others
        # (their index maps to -1), but its preallocation takes about twice as
        # long with them in the list (0.5 mm 3D upsetting: 0.52 s against 0.25 s
        # on one rank, 16% of the entries dropped; docs/PERFORMANCE.md)
        rows, cols = pattern.scalar_rows, pattern.scalar_indices
        self.free_entries = np.flatnonzero((local_index[rows] >= 0) & (local_index[cols] >= 0))
        self.free_values = np.empty(len(self.free_entries))
        coo.preallocate_local(A, rows[self.free_entries], cols[self.free_entries])
        A.setOption(PETSc.Mat.Option.NEW_NONZERO_LOCATION_ERR, True)
        self.free_matrix = A
        return A

    def destroy(self):
        if self.free_matrix is not None:
            self.free_matrix.destroy()
        self.formulation.destroy()
        self.diag.destroy()

    def _stage(self, name):
        return log_stage(self.stages.get(name))

    # ----------------------------------------------------------------- physics
    def kinematic_displacement(self, u_owned, u_local):
        """The ghosted-local displacement that deforms the particles: u itself
        (velocity formulation) or its projection R u (momentum formulation)."""
        return self.formulation.kinematic_displacement(self.state, self.grid, u_owned, u_local)

    def evaluate(self, u_owned, u_local):
        """The particles at the iterate u (compiled, G&W steps 4-5 and the
        internal force), or None on every rank if any rank has an inverted
        particle. Collective (so that no rank is left in a sum)."""
        st = self.state
        kinematic = self.kinematic_displacement(u_owned, u_local)
        evaluation = st.evaluation
        stale = not evaluation.matches(kinematic)
        if st.cells is not None and st.cells.kind == "nodes":      # its sums need every rank
            stale = self.grid.comm.allreduce(stale, op=MPI.LOR)
        if stale:
            with self._stage("Constitutive update"):
                evaluation.evaluate(st, kinematic, self.grid.dim)
        # one reduction tells every rank about inverted particles and signals:
        # a run being stopped abandons its step here, on all ranks at once
        bad, signum = interrupt.agreed(self.grid.comm, evaluation.inverted + evaluation.unconverged)
        if signum:
            raise interrupt.Interrupted(signum)
        if bad > 0:
            self.inverted = True
            self.thickness_failed = self.grid.comm.allreduce(evaluation.unconverged) > 0
            return None
        return evaluation

    def inverts(self, state, u_owned):
        """True on every rank if the displacement ``u_owned`` inverts a
        particle anywhere. Collective. The step of ``state`` is begun once
        (:meth:`begin`): the Newton guesses tried on it only reset the flags
        an inverted one sets (the terms' set-up, a contact tool's candidates
        and corner weights, took 0.1 s a try at 0.5 mm in 3D)."""
        if state is not self.state:
            self.begin(state, self.step)
        self.inverted = False
        self.thickness_failed = False
        return self.evaluate(u_owned, self.grid.owned_to_local(u_owned)) is None

    def unconstrained_residual(self, u_owned, u_local):
        """-Q of G&W step 3 before constraints: the integrator's balance of
        Fint, Fext and M a (owned dofs, in force units), or None if a particle
        inverted. Reactions are read from it."""
        st = self.state
        evaluation = self.evaluate(u_owned, u_local)
        if evaluation is None:
            return None
        st.residual_evaluation = evaluation          # for the particle update
        fint = self.grid.sum_to_owned(evaluation.force)
        force = st.integrator.balance(fint - st.external_force, st, u_owned)
        for term in self.terms:
            term.add_residual(u_owned, u_local, force, self.grid)
        return force

    # ----------------------------------------------------------------- SNES callbacks
    def form_residual(self, snes, X, R):
        st = self.state
        self.residual_evaluations += 1
        faults.checkpoint("residual", self.grid.comm.rank, self.step)
        u_local = self.grid.vec_to_local(X)
        u = X.getArray(readonly=True)
        unconstrained = self.unconstrained_residual(u, u_local)
        if unconstrained is None:
            # A domain error: an infinite residual makes the line search back
            # off (bt) or SNES stop with DIVERGED_FNORM_NAN.
            R.set(np.inf)
            return
        r = unconstrained / self.residual_scale
        r[st.fixed] = (st.constraint_scale / self.residual_scale) * (u[st.fixed] - st.fixed_value[st.fixed])
        # setArray: the Vec's state (and so its cached norm) changes now, not
        # whenever a numpy view of getArray() happens to be released
        R.setArray(r)

    def create_free_dofs_operator(self, free_matrix, free):
        """The step's Newton matrix as its free dofs' matrix ``free_matrix``
        and the prescribed rows' diagonal (:class:`pimpm.linear.FreeDofsOperator`),
        for a direct solver on the free dofs: the whole grid's matrix is not
        assembled. Collective."""
        grid, pattern = self.grid, self.state.pattern

        def whole(values):
            J = pattern_matrix(grid, pattern, use_coo=True)
            coo.set_values(J, values)
            return J

        X = grid.da.createGlobalVec()
        sizes = (X.getLocalSize(), X.getSize())
        X.destroy()
        context = FreeDofsOperator(free_matrix, free, whole)
        J = PETSc.Mat().createPython((sizes, sizes), context=context, comm=grid.da.getComm())
        J.setUp()
        return J

    def form_jacobian(self, snes, X, J, P):
        st = self.state
        grid = self.grid
        faults.checkpoint("jacobian", grid.comm.rank, self.step)
        u_local = grid.vec_to_local(X)
        evaluation = self.evaluate(X.getArray(readonly=True), u_local)
        free_operator = free_dofs_operator(P)
        if P.getType() == PETSc.Mat.Type.PYTHON and free_operator is None:      # the matrix-free shell
            if evaluation is not None:
                project = self.formulation.projector(st, grid)
                P.getPythonContext().update(st, evaluation, self.residual_scale, project,
                                            X.getArray(readonly=True).copy(), u_local)
            P.assemble()
            if J != P:
                J.assemble()
            return
        K = self.formulation.stiffness_matrix(P)
        pattern = st.pattern
        with self._stage("Assembly"):
            if self.coo:
                # every rank hands PETSc its values, none or not (collective)
                values = self._jacobian_values(evaluation, X.getArray(readonly=True), u_local)
                if free_operator is None:
                    coo.set_values(P, values)
                else:              # the free dofs' matrix alone holds them (pimpm.linear.FreeDofsOperator)
                    free_operator.update(values, st.constraint_scale / self.residual_scale)
                    P.assemble()
                if self.free_matrix is not None:
                    coo.set_values(self.free_matrix, np.take(values, self.free_entries, out=self.free_values))
                if J != P:
                    J.assemble()
                return
            if any(term.couples_particles or term.jacobian_blocks(X.getArray(readonly=True)) is not None
                   for term in self.terms):
                raise NotImplementedError("nodal terms with a derivative need the COO assembly "
                                          "(velocity formulation)")
            K.zeroEntries()
            if evaluation is not None:          # (collective with F-bar on the nodes)
                K.setValuesLocalCSR(pattern.scalar_indptr, pattern.scalar_indices,
                                    self._tangent_values(evaluation), addv=PETSc.InsertMode.ADD_VALUES)
            K.assemble()
            self.formulation.finish_stiffness(st, P, self.diag, self.row_offset, grid.dim)   # momentum: K R
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

    def _jacobian_values(self, evaluation, u_owned, u_local):
        """This rank's COO values of the whole Jacobian: the tangent blocks
        (zeros if a particle inverted), times the HHT factor, plus the mass
        term on owned diagonals, with the prescribed rows and columns
        eliminated (zeros, and ``constraint_scale`` on the owner's
        diagonal), all over ``residual_scale``. What MatScale, MatSetDiagonal
        and MatZeroRowsColumns do to the summed matrix in the CSR path,
        done on this rank's share before PETSc sums the shares: equal to
        round-off (bitwise on one rank), without their communication."""
        st = self.state
        if evaluation is None:
            values = np.zeros(len(st.pattern.scalar_indices))
        else:
            values = self._tangent_values(evaluation)
        zero, owned_diagonal, fixed_diagonal = self._constraint_positions()
        if st.integrator.stiffness_factor != 1.0:       # HHT: (1 + alpha) K
            values *= st.integrator.stiffness_factor
        if st.dynamic:
            values[owned_diagonal] += st.mass_coefficient * st.mass
        for term in self.terms:
            if term.couples_particles:
                term.add_jacobian_values(u_local, self.grid, st.pattern, values)
            blocks = term.jacobian_blocks(u_owned)
            if blocks is not None:
                nodes, matrices = blocks
                positions = st.pattern.block_positions(self.grid.owned_local_nodes[nodes], self.grid.dim)
                np.add.at(values, positions.reshape(-1), matrices.reshape(-1))
        values[zero] = 0.0
        values[fixed_diagonal] = st.constraint_scale
        values *= 1.0 / self.residual_scale
        return values

    def _constraint_positions(self):
        """Positions in this step's COO values of the entries in a prescribed
        row or column (ghost nodes included), of every owned dof's diagonal
        (owned order; the pattern keeps them all) and of the prescribed
        owned dofs' diagonals. Made at the step's first Jacobian (collective:
        the prescribed ghost dofs come from their owners)."""
        st, grid = self.state, self.grid
        positions = st.constraint_positions
        if positions is None:
            pattern = st.pattern
            n_dofs = len(pattern.scalar_indptr) - 1
            rows, cols = pattern.scalar_rows, pattern.scalar_indices
            fixed = grid.owned_to_local(st.fixed.astype(float)).reshape(-1) > 0.5
            zero = np.nonzero(fixed[rows] | fixed[cols])[0]
            diagonal = np.full(n_dofs, -1, dtype=np.int64)
            on_diagonal = np.nonzero(rows == cols)[0]
            diagonal[rows[on_diagonal]] = on_diagonal
            owned_dofs = (grid.owned_local_nodes[:, None] * grid.dim + np.arange(grid.dim)).reshape(-1)
            owned_diagonal = diagonal[owned_dofs]
            positions = st.constraint_positions = (zero, owned_diagonal, owned_diagonal[st.fixed])
        return positions

    def _tangent_values(self, evaluation):
        """Every particle's stiffness blocks summed into the values of the
        step's pattern (scalar CSR order; zeros on a rank with no particles)."""
        st, grid = self.state, self.grid
        pattern = st.pattern
        values = st.tangent_values
        if values is None:
            values = st.tangent_values = np.empty(len(pattern.scalar_indices))
        cells = st.cells
        nodal = cells is not None and cells.kind == "nodes"
        coupling = evaluation.node_coupling(st) if nodal else None       # collective
        if not len(st.F_n):
            values[:] = 0.0
            return values
        particle_step.tangent_blocks(
            st.kinematics.kernel_code, tuple(range(grid.dim)), tuple(range(st.S.shape[1])),
            self.symmetric_density, st.node_index,
            st.active, st.S, st.G, st.radius if st.radius is not None else _NO_RADIUS, evaluation.F_inc,
            evaluation.tangent, evaluation.hoop, grid.ghost_ijk,
            pattern.width, pattern.indptr, pattern.slot_position, values)
        if nodal:
            fbar.check_node_boxes(fbar_kernels.node_blocks(
                cells.half, cells.centres, *coupling, *cells.ghost_shape(), pattern.width, pattern.indptr,
                pattern.slot_position, values))
        elif cells is not None and cells.count:
            outside = fbar_kernels.cell_blocks(
                st.kinematics.kernel_code, tuple(range(grid.dim)), fbar.cell_box_side(st), cells.order, cells.start,
                st.node_index, st.active, st.S, st.G, st.radius if st.radius is not None else _NO_RADIUS,
                evaluation.F_inc, evaluation.fbar_q, evaluation.fbar_weight, grid.ghost_ijk, pattern.width,
                pattern.indptr, pattern.slot_position, values)
            fbar.check_cell_boxes(outside)
        return values


def pattern_matrix(grid, pattern, use_coo=False):
    """An AIJ matrix (block size dim, the DMDA's numbering) holding exactly
    the couplings of ``pattern``; an entry outside the pattern afterwards is
    an error. ``use_coo``: preallocated for COO assembly in the order of the
    pattern's values (:mod:`pimpm.coo`); otherwise preallocated for the
    DMDA's box stencil, filled with zeros on the pattern and assembled,
    which drops the unused room. Collective."""
    dim = grid.dim
    X = grid.da.createGlobalVec()
    sizes = (X.getLocalSize(), X.getSize())
    X.destroy()
    J = PETSc.Mat().create(comm=grid.da.getComm())
    J.setSizes((sizes, sizes), bsize=dim)
    J.setType(PETSc.Mat.Type.AIJ)
    lgmap = grid.lgmap() if hasattr(grid, "lgmap") else grid.da.getLGMap()   # block size dim
    J.setLGMap(lgmap, lgmap)
    if use_coo:
        coo.preallocate_local(J, pattern.scalar_rows, pattern.scalar_indices)
        coo.set_values(J, np.zeros(len(pattern.scalar_indices)))
    else:
        own, other = grid.box_preallocation(pattern.width)
        J.setPreallocationNNZ((np.repeat(own * dim, dim).astype(PETSc.IntType),
                               np.repeat(other * dim, dim).astype(PETSc.IntType)))
        J.setValuesLocalCSR(pattern.scalar_indptr, pattern.scalar_indices,
                            np.zeros(len(pattern.scalar_indices)), addv=PETSc.InsertMode.ADD_VALUES)
        J.assemble()
        # every assembly sends the same off-rank entries: keep the communication set-up
        J.setOption(PETSc.Mat.Option.SUBSET_OFF_PROC_ENTRIES, True)
    J.setOption(PETSc.Mat.Option.NEW_NONZERO_LOCATION_ERR, True)
    return J
