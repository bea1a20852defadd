"""Linear-solver pieces of the Newton step: Guilkey & Weiss's
iterative-then-direct fallback (section 3.3), the direct solver on the free
dofs and the rigid-body modes for GAMG (the presets: :mod:`pimpm.presets`;
the matrix-free tangent's product is physics: pimpm/implicit/shell.py).

All of them are configured through the PETSc options database, so every
choice can be refined or overridden from the command line.
"""
from contextlib import contextmanager

import numpy as np
from petsc4py import PETSc


#: preconditioners that keep structure derived from the first matrix they
#: were set up with (PCMG: its Galerkin coarse operators; PCASM: its
#: overlapping subdomains, grown on the first matrix's graph) when the KSP is
#: handed a new matrix with a new nonzero pattern, as each step's is: they are
#: reset then (:func:`reset_for_new_pattern`). Measured on the 0.5 cm billet
#: (2 particles per cell, 4 steps, docs/PERFORMANCE.md "Multigrid on MPM
#: tangents"): -pc_type mg -pc_mg_levels 2 took 156 GMRES iterations a
#: Newton iteration from the second step on without the reset and 12 with it
#: (15 in the first step); ASM on 2 ranks 49 against 44. GAMG rebuilds itself
#: (and fails after PCReset), ILU, block Jacobi and BoomerAMG took the same
#: iterations either way.
RESET_ON_NEW_PATTERN = ("mg", "asm")


def reset_for_new_pattern(ksp):
    """Reset ``ksp``'s preconditioner if it is one of RESET_ON_NEW_PATTERN
    (the step's matrix has a new nonzero pattern); the preconditioner of a
    :class:`FallbackKSP`'s iterative solver likewise. Collective."""
    if ksp.getType() == PETSc.KSP.Type.PYTHON:
        context = ksp.getPythonContext()
        inner = getattr(context, "iterative", None)
        if inner is not None:
            reset_for_new_pattern(inner)
        return
    pc = ksp.getPC()
    if pc.getType() in RESET_ON_NEW_PATTERN:
        pc.reset()


class FallbackKSP:
    """Context of a ``python`` KSP: the iterative solver configured by the
    ordinary ``-ksp_*``/``-pc_*`` options solves first; if it fails, the same
    system is solved by the direct solver (``-fallback_ksp_*``/``-fallback_pc_*``,
    MUMPS LU by default), as Guilkey & Weiss (2003, section 3.3) do.

    The direct solver sees only the free dofs (:meth:`set_free`: the rows of
    prescribed dofs hold only their diagonal, as for :class:`FreeDofsKSP`):
    the 0.5 mm 3D upsetting's fallback used to factorize all 266,511 unknowns,
    of which about a tenth are free, and sat in MUMPS for longer than 15
    minutes. A system with more free dofs than ``max_free_dofs`` is not
    factorized at all: the failed iterative solve stands, Newton fails and the
    step is cut (``skipped`` counts them)."""

    def __init__(self, max_free_dofs=None):
        self.iterative = None
        self.direct = None
        self.fallbacks = 0          # number of linear solves that needed the direct solver
        self.skipped = 0            # failed solves too large for the direct solver
        self.max_free_dofs = max_free_dofs
        self.free = None            # owned dofs: free? (None: factorize the whole system)

    def _inner(self, ksp):
        if self.iterative is None:
            comm = ksp.getComm()
            self.iterative = PETSc.KSP().create(comm=comm)
            dm = ksp.getDM()
            if dm is not None:
                # the grid's DMDA, for preconditioners that use it (geometric
                # multigrid coarsens it; without a DM, -pc_type mg crashed
                # PETSc with a segmentation violation); the operators stay ours
                self.iterative.setDM(dm)
                self.iterative.setDMActive(False)
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

    def set_free(self, free):
        """The step's owned free-dof mask (the direct solve's unknowns)."""
        self.free = np.asarray(free, dtype=bool)

    def solve(self, ksp, b, x):
        # the operators change every Newton iteration (and are a matrix-free
        # MFFD operator with -snes_mf_operator): always hand the current ones on
        A, P = ksp.getOperators()
        self.iterative.setOperators(A, P)
        self.iterative.solve(b, x)
        reason = self.iterative.getConvergedReason()
        its = self.iterative.getIterationNumber()
        if reason < 0:
            free = self.free if self.free is not None else np.ones(b.getLocalSize(), dtype=bool)
            n_free = ksp.getComm().tompi4py().allreduce(int(np.count_nonzero(free)))
            if self.max_free_dofs is not None and n_free > self.max_free_dofs:
                self.skipped += 1
            else:
                self.fallbacks += 1
                reason = self._direct_solve(P, b, x, free)
                its += self.direct.getIterationNumber()
        ksp.setIterationNumber(its)
        ksp.setConvergedReason(reason)

    def _direct_solve(self, P, b, x, free):
        """x = P^-1 b by the direct solver on the free dofs (the prescribed
        rows: right-hand side over the diagonal); returns its converged reason."""
        start = P.getOwnershipRange()[0]
        rows = PETSc.IS().createGeneral((start + np.flatnonzero(free)).astype(PETSc.IntType),
                                        comm=P.getComm())
        sub = P.createSubMatrix(rows, rows)
        xs, bs = sub.createVecs()
        try:
            bs.setArray(b.getArray(readonly=True)[free])
            self.direct.setOperators(sub, sub)
            self.direct.solve(bs, xs)
            _with_prescribed(P, b, free, xs, x)
            return self.direct.getConvergedReason()
        finally:                       # the factors go now (also after a PETSc error), not at the next fallback
            self.direct.reset()
            for obj in (rows, sub, xs, bs):
                obj.destroy()

    def view(self, ksp, viewer):
        viewer.printfASCII("  iterative solver with direct fallback on the free dofs (Guilkey & Weiss 3.3):\n")
        if self.iterative is not None:
            self.iterative.view(viewer)
            self.direct.view(viewer)


def _with_prescribed(A, b, free, x_free, x):
    """x: the free dofs' solution ``x_free`` where ``free`` (owned dofs),
    and b over A's diagonal on the prescribed rows (they hold only their
    diagonal: :class:`FreeDofsKSP`)."""
    rhs = b.getArray(readonly=True)
    diagonal = A.getDiagonal()
    out = np.empty_like(rhs)
    prescribed = ~free
    out[prescribed] = rhs[prescribed] / diagonal.getArray(readonly=True)[prescribed]
    out[free] = x_free.getArray(readonly=True)
    diagonal.destroy()
    x.setArray(out)


class FreeDofsOperator:
    """Context of a ``python`` Mat: the Newton matrix of a step that
    :class:`FreeDofsKSP` solves, held as what that solver needs of it. The
    whole matrix has its prescribed rows and columns eliminated (each
    prescribed row holds only its diagonal, ``diagonal``), so it is the free
    dofs' matrix (``free_matrix``, ``free``: the owned dofs' mask) beside a
    diagonal, and its product and diagonal are those. Assembling the whole
    grid's matrix as well cost a COO preallocation a step, a second
    MatSetValuesCOO every Newton iteration and its memory (docs/PERFORMANCE.md,
    "3D at 0.5 mm"). :meth:`whole` assembles it on demand (the
    finite-difference checks of the tests)."""

    def __init__(self, free_matrix, free, make_whole):
        self.free_matrix = free_matrix
        self.free = np.asarray(free, dtype=bool)
        self.diagonal = 1.0             # the prescribed rows' diagonal (:meth:`update`)
        self.values = None              # the last Jacobian's COO values (:meth:`whole`)
        self._make_whole = make_whole
        self.x, self.y = free_matrix.createVecs()

    def update(self, values, diagonal):
        """The Newton iteration's values (the whole matrix's COO values, which
        the free matrix got too) and the prescribed rows' diagonal."""
        self.values, self.diagonal = values, diagonal

    def _apply(self, x, y, transpose):
        xa = x.getArray(readonly=True)
        out = np.empty_like(xa)
        out[~self.free] = self.diagonal * xa[~self.free]
        self.x.setArray(xa[self.free])
        (self.free_matrix.multTranspose if transpose else self.free_matrix.mult)(self.x, self.y)
        out[self.free] = self.y.getArray(readonly=True)
        y.setArray(out)

    def mult(self, mat, x, y):
        self._apply(x, y, False)

    def multTranspose(self, mat, x, y):
        self._apply(x, y, True)

    def getDiagonal(self, mat, d):
        free_diagonal = self.free_matrix.getDiagonal()
        out = np.full(len(self.free), self.diagonal)
        out[self.free] = free_diagonal.getArray(readonly=True)
        free_diagonal.destroy()
        d.setArray(out)

    def whole(self):
        """The whole grid's matrix, assembled from the last Newton
        iteration's values (a new Mat the caller destroys). Collective."""
        return self._make_whole(self.values)

    def release(self):
        for vec in (self.x, self.y):
            vec.destroy()


def free_dofs_operator(mat):
    """The :class:`FreeDofsOperator` of a python Mat, or None for any other matrix."""
    if mat.getType() == PETSc.Mat.Type.PYTHON and isinstance(mat.getPythonContext(), FreeDofsOperator):
        return mat.getPythonContext()
    return None


#: the lagged solves' relative tolerance (on the true residual) and iteration
#: limit; a solve that does not converge within the limit factorizes anew.
#: An inexact Newton step (Dembo, Eisenstat & Steihaug 1982): each Newton
#: iteration still cuts the residual by orders of magnitude, and Newton's own
#: test decides the answer. On the 0.5 mm 3D upsetting's first four steps
#: (docs/PERFORMANCE.md, "3D at 0.5 mm") 1e-4 takes 8.4 GMRES iterations a
#: Newton iteration where 1e-10 took 19.5, for the same Newton iterations
#: (8, 5, 4, 5) and the platen force to 1e-10; 1e-3 saves another tenth of
#: the GMRES iterations for the same Newton iterations and step cuts (the
#: whole runs to 60% at 2 and 1 mm: 372 and 864 against 417 and 922 GMRES
#: iterations for 55 and 108 Newton iterations, the platen force unchanged
#: to the 5 digits printed; at 0.5 mm 504.6 s against 526.6 s for the same
#: steps, cut and force)
LAGGED_RTOL = 1e-3
LAGGED_MAX_IT = 30
#: a lagged solve that needed this many iterations or more has the next
#: system factorized anew, rather than GMRES running out of its iterations
#: there. The 0.5 mm 3D upsetting to 60% (2 ranks, docs/PERFORMANCE.md): 67
#: factorizations and 3,098 triangular solves, the Solve stage 307 s, where
#: without it 62 and 3,643 took 322 s (23 of those factorizations after a
#: lagged GMRES had run out of its 30 iterations); at 1 mm 14.8 s against
#: 16.9 s (10 and 15 iterations: 15.2 and 15.5 s); Newton unchanged
LAGGED_REFRESH_IT = 20
#: MUMPS's INFOG(1) when a work array estimated at analysis was too small for
#: the numerical factorization (delayed pivots of a nearly singular tangent)
MUMPS_WORKSPACE_ERRORS = (-8, -9, -11, -14, -15, -17, -20)
#: factorizations retried with twice the work space (ICNTL(14)) before giving up
WORKSPACE_RETRIES = 3


class FreeDofsKSP:
    """Context of a ``python`` KSP for the direct solvers: the factorization
    sees only the free dofs. The Newton matrix keeps every prescribed dof
    (grid faces, rigid bodies, and the nodes no particle reaches, about half
    of the 0.25 cm billet's 27,370 unknowns) as a row and column holding only
    its diagonal; such a row's unknown is its right-hand side over that
    diagonal, and the other rows do not see it. The inner KSP (the ordinary
    ``-ksp_*``/``-pc_*``/``-mat_mumps_*`` options) factorizes the step's
    matrix on the free dofs (:meth:`pimpm.implicit.StepProblem.create_free_jacobian`,
    assembled from the values the whole matrix gets). PETSc's PCREDISTRIBUTE
    does the same, but extracts the smaller matrix anew at every Newton
    iteration (MatCreateSubMatrix) and moves rows between ranks. Measured in
    docs/PERFORMANCE.md ("The direct solver on the free dofs only").

    With ``reuse_factorization`` the step's first system is factorized and
    the later ones (the tangent changes from one Newton iterate to the next,
    its pattern does not) are solved by right-preconditioned GMRES with that
    factorization as preconditioner, to LAGGED_RTOL on the true residual;
    one that needs more than LAGGED_MAX_IT iterations is factorized anew, and
    one that needed LAGGED_REFRESH_IT or more has the next one factorized
    (the options prefix ``pimpm_reuse_`` tunes that GMRES). In 3D a
    triangular solve costs a few percent of a factorization (0.5 mm
    upsetting: 32 ms against 1.9 s), so 10-20 of them per Newton iteration
    halve a step's time (docs/PERFORMANCE.md, "3D at 0.5 mm")."""

    def __init__(self, reuse_factorization=False):
        self.inner = None
        self.matrix = None          # the step's matrix on the free dofs
        self.free = None            # owned dofs: free?
        self.b = self.x = None
        #: factorize once per step; later Newton iterations solve by GMRES
        #: preconditioned with that factorization (:meth:`solve`)
        self.reuse = reuse_factorization
        self.lagged = None          # that GMRES (shares the inner KSP's PC)
        self.factored = False       # does the PC hold a factorization of this step's matrix?
        self.stale = False          # did the last lagged solve need LAGGED_REFRESH_IT iterations or more?
        self.refactorizations = 0   # lagged solves that had to factorize anew
        #: MUMPS's work-space increase (ICNTL(14), percent) after a factorization
        #: ran out of it (None: MUMPS's own or the options')
        self.workspace = None
        self.workspace_retries = 0  # factorizations repeated with more work space
        #: the largest factorization so far: (free dofs, bytes MUMPS used on all
        #: ranks, INFOG(22)), or None (no MUMPS factorization yet)
        self.largest_factorization = None

    def _inner(self, ksp):
        if self.inner is None:
            self.inner = PETSc.KSP().create(comm=ksp.getComm())
            if self.reuse:
                self.lagged = PETSc.KSP().create(comm=ksp.getComm())
                self.lagged.setOptionsPrefix("pimpm_reuse_")
                self.lagged.setType(PETSc.KSP.Type.GMRES)
                # right preconditioning: the test is on the true residual
                self.lagged.setPCSide(PETSc.PC.Side.RIGHT)
                self.lagged.setTolerances(rtol=LAGGED_RTOL, atol=0.0, max_it=LAGGED_MAX_IT)
                self.lagged.setGMRESRestart(LAGGED_MAX_IT)

    def setFromOptions(self, ksp):
        self._inner(ksp)
        self.inner.setFromOptions()
        if self.lagged is not None:
            self.lagged.setFromOptions()
            self.lagged.setPC(self.inner.getPC())

    def setUp(self, ksp):
        self._inner(ksp)

    def set_matrix(self, matrix, free):
        """Begin a step: its matrix on the free dofs and the owned dofs'
        free mask (the factorization starts afresh: new pattern, new size).
        Only the PC is reset: KSPReset would also drop the viewers that
        -ksp_view and -ksp_view_mat set up."""
        self.drop_factorization()
        if self.lagged is not None:
            self.lagged.reset()         # its Krylov vectors have the last step's size (the PC stays shared)
        for obj in (self.b, self.x):
            if obj is not None:
                obj.destroy()
        self.matrix, self.free = matrix, free
        self.x, self.b = matrix.createVecs()
        self.inner.setOperators(matrix, matrix)

    def drop_factorization(self):
        """Forget the factorization (after a failed solve)."""
        self.inner.getPC().reset()
        self.factored = False

    def solve(self, ksp, b, x):
        A, _ = ksp.getOperators()
        self.b.setArray(b.getArray(readonly=True)[self.free])
        its, reason = self._solve_free()
        _with_prescribed(A, b, self.free, self.x, x)
        ksp.setIterationNumber(its)
        ksp.setConvergedReason(reason)

    def _solve_free(self):
        """Solve the free dofs' system: (iterations, converged reason)."""
        if self.lagged is not None and self.factored and not self.stale:
            # the step's first factorization preconditions GMRES on today's matrix
            self.inner.getPC().setReusePreconditioner(True)     # the flag is the shared PC's
            self.lagged.setOperators(self.matrix, self.matrix)
            self.x.set(0.0)
            self.lagged.solve(self.b, self.x)
            reason = self.lagged.getConvergedReason()
            its = self.lagged.getIterationNumber()
            if reason > 0:
                # GMRES is running out of the factorization: the next system gets a new one
                self.stale = its >= LAGGED_REFRESH_IT
                return its, reason
            self.refactorizations += 1
        else:
            its = 0
        self.inner.getPC().setReusePreconditioner(False)
        for attempt in range(WORKSPACE_RETRIES + 1):
            self.inner.setOperators(self.matrix, self.matrix)      # again after a reset PC
            with _mumps_workspace(self.workspace):
                self.inner.solve(self.b, self.x)
            reason = self.inner.getConvergedReason()
            grown = _grown_workspace(self.inner.getPC()) if reason < 0 else None
            if grown is None or attempt == WORKSPACE_RETRIES:
                break
            # MUMPS ran out of the work space its analysis estimated (a tangent
            # near a limit point pivots late): factorize again with twice as
            # much, and keep that for the rest of the run
            self.workspace = grown
            self.workspace_retries += 1
            self.drop_factorization()
        self.factored = reason > 0
        self.stale = False
        if self.factored:
            used = mumps_bytes(self.inner.getPC())
            if used is not None and (self.largest_factorization is None or used > self.largest_factorization[1]):
                self.largest_factorization = (self.matrix.getSize()[0], used)
        return its + self.inner.getIterationNumber(), reason

    def release(self):
        """Destroy the inner objects (collective; not named ``destroy``, which
        petsc4py would call back as the outer KSP goes, maybe after Python's
        own objects are gone)."""
        for obj in (self.lagged, self.inner, self.b, self.x):
            if obj is not None:
                obj.destroy()

    def view(self, ksp, viewer):
        viewer.printfASCII("  direct solver on the free dofs only:\n")
        if self.inner is not None:
            self.inner.view(viewer)


def _mumps_factor(pc):
    """The factor matrix of ``pc`` if it is a MUMPS LU or Cholesky, else None."""
    if pc.getType() not in (PETSc.PC.Type.LU, PETSc.PC.Type.CHOLESKY) \
            or pc.getFactorSolverType() != "mumps":
        return None
    return pc.getFactorMatrix()


def mumps_bytes(pc):
    """Bytes of memory MUMPS's factorization in ``pc`` used, summed over the
    ranks (INFOG(22), in units of 10^6 bytes), or None if ``pc`` holds no
    MUMPS factorization. The same on every rank."""
    factor = _mumps_factor(pc)
    return None if factor is None else 1e6 * float(factor.getMumpsInfog(22))


def _grown_workspace(pc):
    """Twice the work-space increase (ICNTL(14)) of a MUMPS factorization of
    ``pc`` that failed for want of work space, else None. The same on every
    rank (INFOG is global)."""
    factor = _mumps_factor(pc)
    if factor is None or factor.getMumpsInfog(1) not in MUMPS_WORKSPACE_ERRORS:
        return None
    return 2 * max(int(factor.getMumpsIcntl(14)), 20)


@contextmanager
def _mumps_workspace(percent):
    """-mat_mumps_icntl_14 ``percent`` in the options database while a
    factorization is set up (None: leave the database alone)."""
    if percent is None:
        yield
        return
    db = PETSc.Options()
    before = db.getString("mat_mumps_icntl_14") if db.hasName("mat_mumps_icntl_14") else None
    db.setValue("mat_mumps_icntl_14", str(percent))
    try:
        yield
    finally:
        if before is None:
            db.delValue("mat_mumps_icntl_14")
        else:
            db.setValue("mat_mumps_icntl_14", before)


def rigid_body_near_null_space(grid):
    """Rigid-body modes of the grid (translations and rotations) for GAMG
    (with several velocity fields, pimpm.fields.FieldGrid: of each field)."""
    coords = grid.coordinates() if hasattr(grid, "coordinates") else grid.da.getCoordinates()
    coords.setBlockSize(grid.dim)
    return PETSc.NullSpace().createRigidBody(coords)
