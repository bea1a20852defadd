"""PETSc plumbing of the Newton solve (G&W 3.3 steps 3-6): SNES on the DMDA
with the problem's residual and tangent (:mod:`pimpm.implicit.problem`),
solver presets, options, the iterative-then-direct fallback and the
convergence test. What the solver is made of is resolved first, as data
(:func:`pimpm.presets.resolve`: command line > YAML ``solver.petsc`` >
per-problem adjustments > preset > the program's defaults); PETSc reads the
options from its database.
"""
import atexit
import sys
import time
import weakref
from contextlib import contextmanager

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from .convergence import GuilkeyWeissTest
from .implicit.shell import TangentShell
from . import presets
from .line_search import FullStepFirst
from .linear import (FallbackKSP, FreeDofsKSP, free_dofs_operator, reset_for_new_pattern,
                     rigid_body_near_null_space)
from .stages import log_stage


#: how long (s) a rank whose part of a collective PETSc call raised an error
#: waits for the other ranks to come out of that call. A failure that PETSc
#: reports on every rank (MUMPS's factorization of a singular tangent) brings
#: them out together; one that only some ranks raise (geometric multigrid
#: coarsening a DMDA whose local part does not coarsen on this rank) leaves
#: the others waiting inside the call for ever.
DESYNC_TIMEOUT = 10.0


def failed_on_some_rank(comm, code, where):
    """After a collective PETSc call (``where``, for the message) that
    raised a PETSc error with ``code`` on this rank (0 if it returned): the
    largest error code raised on any rank, the same on every rank (0:
    none). The caller keeps the code, not the exception: its traceback
    would hold the solver's frames, and with them PETSc objects with Python
    contexts, past PetscFinalize (a crash at exit). Each rank must call
    this after the call, so that a step that failed anywhere fails
    everywhere. A rank that raised waits up to
    DESYNC_TIMEOUT for the others; if they do not come, they are still
    inside the call, which failed on this rank alone, and no step can be
    retried: it says so and stops every rank (MPI_Abort, status 1) rather
    than leave them waiting."""
    if comm.size == 1:
        return code
    request = comm.Ibarrier()
    if code:
        deadline = time.monotonic() + DESYNC_TIMEOUT
        while not request.Test():
            if time.monotonic() > deadline:
                sys.stdout.flush()
                sys.stderr.write(f"pimpm: error on rank {comm.rank} of {comm.size}: PETSc error {code} in "
                                 f"{where} on this rank alone, while the other ranks are still inside that "
                                 f"collective call (a PETSc option this grid or partition cannot take?); "
                                 f"stopping all ranks\n")
                sys.stderr.flush()
                comm.Abort(1)
            time.sleep(0.005)
    else:
        request.Wait()
    return comm.allreduce(code, op=MPI.MAX)


def diagnose_solver_options(config, err):
    """A one-line message for a PETSc error raised while the solver read its
    options: names the offending ``*_type`` option when it can find it."""
    if isinstance(err, ValueError):
        return str(err)
    db = PETSc.Options()
    yaml_options = config["solver"]["petsc"]
    candidates = dict(yaml_options)
    candidates.update({k: db.getString(k) for k in ("ksp_type", "pc_type", "snes_type")
                       if db.hasName(k)})
    makers = {"ksp_type": PETSc.KSP, "pc_type": PETSc.PC, "snes_type": PETSc.SNES}
    for name, value in candidates.items():
        kind = next((k for k in makers if name == k or name.endswith("_" + k)), None)
        if kind is None:
            continue
        obj = makers[kind]().create(comm=PETSc.COMM_SELF)
        try:
            obj.setType(value)
        except PETSc.Error:
            where = f"solver.petsc.{name}" if yaml_options.get(name) == value else f"-{name}"
            return f"{where} = {value!r}: expected a {kind.split('_')[0].upper()} type known to PETSc"
        finally:
            obj.destroy()
    culprit = _rejected_option(yaml_options)
    if culprit is not None:
        return culprit
    return (f"PETSc rejected the solver options (error code {getattr(err, 'ierr', err)}): "
            f"expected valid option values in solver.petsc and on the command line")


def _option_source(name, yaml_options):
    """How a message names option ``name``: its YAML key if the input gives it, else -name."""
    return f"solver.petsc.{name}" if name in yaml_options else f"-{name}"


def _check_tolerances(snes, yaml_options, ksp=None):
    """PETSc takes negative tolerances and iteration limits; pimpm would then
    report a numerical failure. Refuse them here, naming the option.
    ``ksp``: the KSP that solves (the inner one of a python KSP)."""
    rtol, atol, stol, max_it = snes.getTolerances()
    values = {"snes_rtol": rtol, "snes_atol": atol, "snes_stol": stol, "snes_max_it": max_it}
    ksp = ksp or snes.getKSP()
    if ksp.getType() == PETSc.KSP.Type.PYTHON:
        ksp = None
    if ksp is not None:
        k_rtol, k_atol, _, k_max_it = ksp.getTolerances()
        values.update(ksp_rtol=k_rtol, ksp_atol=k_atol, ksp_max_it=k_max_it)
    for name, value in values.items():
        # an infinite tolerance makes every step "converge" at once, a relative one of
        # 1 or more after the first iteration: silent wrong answers (issue 32)
        if name.endswith("max_it"):
            bad, what = value < 1, "an integer >= 1"
        elif name.endswith("rtol"):
            bad, what = not 0.0 <= value < 1.0, "a number >= 0 and < 1"
        else:
            bad, what = not 0.0 <= value < float("inf"), "a finite number >= 0"
        if bad:
            raise ValueError(f"{_option_source(name, yaml_options)} = {value:g}: expected {what}")


#: PETSc options whose values PETSc takes but that make a run meaningless or
#: fail later as a "numerical failure" (issue 32): name -> (is it good?, what is expected)
OPTION_RANGES = {
    "snes_linesearch_damping": (lambda v: 0.0 < v < float("inf"), "a finite number > 0"),
    "snes_linesearch_maxstep": (lambda v: 0.0 < v < float("inf"), "a finite number > 0"),
    "snes_linesearch_max_it": (lambda v: v >= 1 and v == int(v), "an integer >= 1"),
    "mat_mffd_err": (lambda v: 0.0 < v < float("inf"), "a finite number > 0"),
    "mat_mumps_icntl_14": (lambda v: v >= 0 and v == int(v), "an integer >= 0 (a percentage)"),
    "mat_mumps_icntl_23": (lambda v: v >= 0 and v == int(v), "an integer >= 0 (megabytes; 0: MUMPS decides)"),
    "ksp_gmres_restart": (lambda v: v >= 1 and v == int(v), "an integer >= 1"),
    "pc_gamg_agg_nsmooths": (lambda v: v >= 0 and v == int(v), "an integer >= 0"),
}
#: object types that need a Python context pimpm cannot be given from options
PYTHON_TYPES = ("ksp_type", "pc_type", "snes_type", "mat_type", "snes_linesearch_type")


def _check_option_values(yaml_options, program_options, prefixes=("", "fallback_")):
    """Refuse the values of :data:`OPTION_RANGES` PETSc would take, and
    python object types (their context is pimpm's to set), naming the
    option (solver.petsc.NAME or -NAME). ``program_options``: the preset's
    and the YAML's (:func:`scoped_options`); the command line's win."""
    db = PETSc.Options()

    def lookup(key):
        if db.hasName(key):
            return db.getString(key)
        return None if key not in program_options else str(program_options[key])

    for prefix in prefixes:
        for name, (good, what) in OPTION_RANGES.items():
            full = prefix + name
            text = lookup(full)
            if text is None:
                continue
            try:
                value = float(text)
            except (TypeError, ValueError):
                value = None
            if value is None or not good(value):
                raise ValueError(f"{_option_source(full, yaml_options)} = {presets.shown(text)}: expected {what}")
        for name in PYTHON_TYPES:
            full = prefix + name
            if (lookup(full) or "").strip().lower() == "python":
                raise ValueError(f"{_option_source(full, yaml_options)} = python: expected a PETSc type "
                                 f"(a python {name[:-5]} needs a context that options cannot give)")


def _check_factorizations(snes, yaml_options, fallback=None, ksp=None):
    """A factorization package that PETSc does not have for the chosen
    factorization (-pc_factor_mat_solver_type nonsense, or superlu for a
    Cholesky) fails at the first solve, which pimpm would report as a
    numerical failure. Try each on a 1x1 matrix now, naming the option.
    ``ksp``: the KSP that solves (the inner one of a python KSP)."""
    pcs = [("", (ksp or snes.getKSP()).getPC())]
    if fallback is not None and fallback.direct is not None:
        pcs = [("", fallback.iterative.getPC()), ("fallback_", fallback.direct.getPC())]
    for prefix, pc in pcs:
        kind = pc.getType()
        if kind not in ("lu", "cholesky", "ilu", "icc"):
            continue
        package = pc.getFactorSolverType()
        if package is None:
            continue
        A = PETSc.Mat().createAIJ((1, 1), nnz=1, comm=PETSc.COMM_SELF)
        A.setValue(0, 0, 1.0)
        A.assemble()
        ksp = PETSc.KSP().create(comm=PETSc.COMM_SELF)
        try:
            ksp.setOperators(A)
            ksp.setType(PETSc.KSP.Type.PREONLY)
            ksp.getPC().setType(kind)
            ksp.getPC().setFactorSolverType(package)
            ksp.setUp()
        except PETSc.Error:
            name = prefix + "pc_factor_mat_solver_type"
            raise ValueError(f"{_option_source(name, yaml_options)} = {package!r}: expected a factorization package PETSc has for "
                             f"-{prefix}pc_type {kind} (mumps; superlu_dist and petsc for lu)") from None
        finally:
            ksp.destroy()
            A.destroy()


def _rejected_option(yaml_options):
    """The first option (YAML ``solver.petsc`` or command line) that a scratch
    SNES rejects when it is the only option in the database, as a message;
    None if none is rejected alone. The database is restored afterwards."""
    db = PETSc.Options()
    saved = db.getAll()
    candidates = [(f"solver.petsc.{k}", k, str(v)) for k, v in yaml_options.items()]
    candidates += [(f"-{k}", k, v) for k, v in saved.items() if not k.startswith("pimpm_")]
    try:
        for key in saved:
            db.delValue(key)
        for where, name, value in candidates:
            db.setValue(name, value)
            snes = PETSc.SNES().create(comm=PETSc.COMM_SELF)
            try:
                snes.setFromOptions()
            except PETSc.Error:
                given = f"{where} {presets.shown(value)}" if where.startswith("-") else f"{where} = {value!r}"
                return f"{given}: rejected by PETSc (expected a value of the type the option takes)"
            finally:
                snes.destroy()
                db.delValue(name)
    finally:
        for key, value in saved.items():
            db.setValue(key, value)
    return None


class NewtonSolver:
    """SNES, the tangent matrix made by the problem (exactly preallocated by
    the DMDA, or a shell for the matrix-free preset), and the solution and
    residual vectors. ``problem`` is a :class:`pimpm.implicit.StepProblem`."""

    def __init__(self, grid, problem, solver_config, stages=None):
        self.grid = grid
        self.problem = problem
        self.da = grid.da
        self.stages = stages or {}
        plan = presets.resolve(solver_config, command_line_options(), symmetric=problem.symmetric,
                               dim=grid.dim, assembles_on_pattern=problem.assembles_on_pattern,
                               coo=problem.coo, asymmetry=problem.asymmetry,
                               contact={term.contact_kind for term in problem.terms} - {None})
        self.plan = plan
        self.preset = plan.preset
        self.matrix_free = plan.matrix_free
        self.options = plan.options
        self.fallback = None
        self.gw_test = None
        if plan.convergence[0] == "guilkey_weiss":
            self.gw_test = GuilkeyWeissTest(*plan.convergence[1:])
        self.X = self.da.createGlobalVec()
        self.R = self.da.createGlobalVec()
        self.symmetric = plan.symmetric
        self.near_null_space = plan.near_null_space
        self.on_pattern = plan.on_pattern
        # a direct solver factorizes the free dofs only (pimpm.linear.FreeDofsKSP)
        self.free_dofs = None
        use_fallback, use_free_dofs = plan.fallback, plan.free_dofs
        if self.on_pattern:        # a placeholder until the first step's pattern is known
            self.J = diagonal_matrix(self.da)
        else:
            self.J = problem.create_jacobian(self.matrix_free)
        self._set_matrix_options(self.J)
        self.snes = PETSc.SNES().create(comm=self.da.getComm())
        self.snes.setDM(self.da)
        self.snes.setFunction(problem.form_residual, self.R)
        self.snes.setJacobian(problem.form_jacobian, self.J, self.J)
        if self.gw_test is not None:
            self.snes.setConvergenceTest(self.gw_test)
        if use_fallback or use_free_dofs:
            ksp = self.snes.getKSP()
            ksp.setOptionsPrefix("pimpm_outer_")       # the inner solvers read -ksp_*, -pc_*
            ksp.setType(PETSc.KSP.Type.PYTHON)
            # the inner solvers precondition; PETSc's default here would factorize
            # the whole matrix (ILU, or ICC when symmetric) at every Newton iteration
            ksp.getPC().setType(PETSc.PC.Type.NONE)
            if use_fallback:
                self.fallback = FallbackKSP(max_free_dofs=plan.fallback_max_dofs)
                ksp.setPythonContext(self.fallback)
            else:
                self.free_dofs = FreeDofsKSP(reuse_factorization=plan.reuse_factorization)
                ksp.setPythonContext(self.free_dofs)
        self.line_search = None
        with scoped_options(self.options):
            self.snes.setFromOptions()
            if use_fallback or use_free_dofs:
                self.snes.getKSP().setUp()
            # contact: the full Newton step when it cuts the residual norm enough, else
            # l2's; made here, where it sees the input's -snes_linesearch_monitor too
            if plan.full_step_first is not None:
                self.line_search = FullStepFirst(self.snes, problem.form_residual, self.R, plan.full_step_first)
        self.destroyed = False
        _LIVE_SOLVERS.add(self)
        try:
            _check_option_values(solver_config["petsc"], self.options)
            _check_tolerances(self.snes, solver_config["petsc"], self.linear_ksp())
            _check_factorizations(self.snes, solver_config["petsc"], self.fallback, self.linear_ksp())
        except ValueError:
            self.destroy()        # before PetscFinalize: the python KSP context
            raise

    def _set_matrix_options(self, J, whole_grid=True):
        """Symmetry flags, and GAMG's rigid-body modes on a matrix over the
        whole grid (``whole_grid``; not on the free dofs' matrix)."""
        if self.symmetric:
            J.setOption(PETSc.Mat.Option.SYMMETRIC, True)
            J.setOption(PETSc.Mat.Option.SYMMETRY_ETERNAL, True)
        if self.near_null_space and whole_grid:
            J.setNearNullSpace(rigid_body_near_null_space(self.grid))

    def prepare(self, state, step=0):
        """Begin a step (``step``: its number): the problem's state, and a
        tangent matrix made on the step's own nonzero pattern (it changes as
        particles move; the Newton iterations of the step then reuse its
        symbolic factorization). A matrix per step also makes a step's
        factorization depend on that step alone: a direct solver's analysis
        may use the values of the matrix it first sees, and a run continued
        from a checkpoint must repeat the uninterrupted one bit for bit.
        Collective."""
        self.problem.begin(state, step)
        if self.fallback is not None:
            self.fallback.set_free(~state.fixed)
        if not self.on_pattern:
            return
        free_matrix = None
        if self.free_dofs is not None:
            # the last step's factors go before this step's matrix is made, not
            # after (at 0.5 mm in 3D they are about a gigabyte a rank)
            self.free_dofs.drop_factorization()
            free = ~state.fixed
            free_matrix = self.problem.create_free_jacobian(state.pattern, free)
            self._set_matrix_options(free_matrix, whole_grid=False)
            self.free_dofs.set_matrix(free_matrix, free)
        if free_matrix is not None and not self._mf_operator():
            # the direct solver needs the free dofs' matrix alone: the whole one is not assembled
            J = self.problem.create_free_dofs_operator(free_matrix, free)
        else:
            J = self.problem.create_jacobian(False, state.pattern)
        self._set_matrix_options(J)
        if self._mf_operator():       # the operator stays the finite-difference one
            self.snes.setJacobian(self.problem.form_jacobian, None, J)
        else:
            self.snes.setJacobian(self.problem.form_jacobian, J, J)
        _destroy_matrix(self.J)
        self.J = J
        reset_for_new_pattern(self.snes.getKSP())

    def end_step(self):
        """The step is over (its particles updated, or it failed): drop its
        particle state (:meth:`pimpm.implicit.StepProblem.end_step`) and what
        a matrix-free tangent keeps of it."""
        self.problem.end_step()
        if self.J is not None and self.J.getType() == PETSc.Mat.Type.PYTHON:
            context = self.J.getPythonContext()
            if isinstance(context, TangentShell):
                context.release()

    def whole_jacobian(self):
        """The step's Newton matrix over the whole grid, assembled (as the last
        Jacobian left it): ``J`` itself, or made from the free dofs' operator's
        values (a new Mat: destroy it). For checks; collective."""
        operator = free_dofs_operator(self.J)
        return self.J if operator is None else operator.whole()

    def destroy(self):
        """Free the PETSc objects now (collective); Python contexts held by
        PETSc (python KSP, shell matrix) must not outlive PetscFinalize."""
        if self.destroyed:
            return
        self.destroyed = True
        if self.fallback is not None and self.fallback.iterative is not None:
            self.fallback.iterative.destroy()
            self.fallback.direct.destroy()
        if self.free_dofs is not None:
            self.free_dofs.release()
        if self.line_search is not None:
            self.line_search.destroy()
        # After an exception in a callback the traceback may still hold the
        # SNES, which PetscFinalize would then destroy, calling back into a
        # finalized interpreter: drop its Python contexts now (the shell
        # matrix through SNESReset, the python KSP by a change of type)
        self.snes.reset()
        outer = self.snes.getKSP()
        if outer.getType() == PETSc.KSP.Type.PYTHON:
            outer.setType(PETSc.KSP.Type.PREONLY)
        _destroy_matrix(self.J)
        for obj in (self.snes, self.X, self.R):
            obj.destroy()
        self.problem.destroy()

    def describe(self):
        """One line naming the solver (for the run summary)."""
        ksp = self.snes.getKSP()
        if self.fallback is not None:
            inner = self.fallback.iterative
            linear = (f"{inner.getType()}+{inner.getPC().getType()} with direct fallback "
                      f"({self.fallback.direct.getType()}+{self.fallback.direct.getPC().getType()})")
        elif self.free_dofs is not None:
            inner = self.free_dofs.inner
            linear = f"{inner.getType()}+{inner.getPC().getType()} on the free dofs"
            if self.free_dofs.lagged is not None:
                linear += ", factorized once per step (GMRES on its later iterations)"
        else:
            linear = f"{ksp.getType()}+{ksp.getPC().getType()}"
        test = "Guilkey-Weiss eq. 13" if self.gw_test else "PETSc (rtol/atol/stol)"
        if self.plan.linear_predictor:
            test += "; linearized start from rest"
        db = PETSc.Options()
        line_search = db.getString("snes_linesearch_type", self.options.get("snes_linesearch_type", "bt"))
        if self.line_search is not None:
            line_search = f"the full step if it cuts |R| to {self.line_search.threshold:g} of it, else l2's fit"
        operator = ", matrix-free operator" if self._mf_operator() else ""
        return (f"preset {self.preset}: SNES {self.snes.getType()} (line search {line_search}"
                f"{operator}), linear {linear}, convergence {test}")

    def _mf_operator(self):
        return self.plan.mf_operator

    def linear_ksp(self):
        """The KSP that solves the Newton systems: the fallback's iterative
        one, the free-dof direct one, or SNES's own."""
        if self.fallback is not None:
            return self.fallback.iterative
        if self.free_dofs is not None:
            return self.free_dofs.inner
        return self.snes.getKSP()

    def _drop_factorizations(self):
        """After a PETSc error in a linear solve (e.g. MUMPS on a singular
        tangent): forget the preconditioners' factors, so that the next
        solve factorizes afresh."""
        self.snes.getKSP().getPC().reset()
        if self.free_dofs is not None:
            self.free_dofs.drop_factorization()

    def linear_predictor(self, state, guess):
        """A better start for a step whose integrator predicts no motion of
        the free dofs (a body at rest when a tool starts to move): the
        prescribed values of ``guess`` and the free dofs' linearized response
        to them, y solving K(0) y = -dR/du(0)[w], w the prescribed part of
        the guess, K(0) the step's tangent at u = 0 (its first Newton matrix;
        the derivative by a forward difference of the residual, whose error
        only moves the starting point). Starting from ``guess`` itself puts
        the whole prescribed increment into the first cell layer under a tool,
        which yields and may invert: the 0.5 mm 3D upsetting then needed a
        step cut and 20 Newton iterations for its first step, 7 from this
        predictor (docs/PERFORMANCE.md). Returns None (collectively) when
        nothing is prescribed to move, a residual inverts a particle or the
        linear solve fails. Call after :meth:`prepare`. Collective."""
        problem, grid = self.problem, self.grid
        fixed = state.fixed
        w = np.where(fixed, guess, 0.0)
        size = grid.comm.allreduce(float(np.max(np.abs(w), initial=0.0)), op=MPI.MAX)
        if size == 0.0:
            return None
        zero = np.zeros_like(w)
        base = problem.unconstrained_residual(zero, grid.owned_to_local(zero))
        base = None if base is None else base.copy()
        # a prescribed increment of 1e-6 cells: well inside the elastic range
        eps = 1e-6 * float(np.min(grid.spacing)) / size
        moved = problem.unconstrained_residual(eps * w, grid.owned_to_local(eps * w))
        problem.residual_evaluations = 0             # not Newton's backtracks
        if grid.comm.allreduce(base is None or moved is None):
            return None
        b, y = self.R.duplicate(), self.X.duplicate()
        rhs = b.getArray()
        rhs[:] = -(moved - base) / (eps * problem.residual_scale)
        rhs[fixed] = 0.0
        del rhs
        self.X.set(0.0)
        with log_stage(self.stages.get("Solve")), scoped_options(self.options):
            problem.form_jacobian(self.snes, self.X, self.J, self.J)
            ksp = self.snes.getKSP()
            ksp.setOperators(self.J, self.J)
            code = 0
            try:
                ksp.solve(b, y)
            except PETSc.Error as err:
                code = err.ierr or 1
            failed = failed_on_some_rank(grid.comm, code, "the linear predictor's solve")
            solved = not failed and ksp.getConvergedReason() > 0
            if failed:
                self._drop_factorizations()
        out = y.getArray(readonly=True).copy()
        b.destroy()
        y.destroy()
        if not solved:
            return None
        out[fixed] = w[fixed]
        return out

    def solve(self, state, initial_guess, step=0):
        """Newton on the incremental grid displacement of ``state``'s step
        (``step``: its number, for messages) from ``initial_guess`` (owned
        dofs, or a function of no arguments that makes them once the step's
        solver is prepared). Returns (u_owned, info)."""
        problem = self.problem
        self.prepare(state, step)
        if callable(initial_guess):
            initial_guess = initial_guess()
        fallbacks_before = self.fallback.fallbacks if self.fallback else 0
        skipped_before = self.fallback.skipped if self.fallback else 0
        self.X.getArray()[:] = initial_guess
        self.snes.setConvergenceHistory(length=1000, reset=True)
        error_code = 0          # the PETSc error code this rank raised in the solve (0: none)
        # the options stay in the database for the whole solve: PCSetUp (GAMG
        # level smoothers, the MUMPS factor) reads them at first use
        with log_stage(self.stages.get("Solve")), scoped_options(self.options):
            try:
                self.snes.solve(None, self.X)
            except PETSc.Error as err:
                # e.g. MUMPS solving with a factorization that failed on a
                # singular tangent: a failed step, cut and retried like the
                # others, after dropping the preconditioner's factors
                error_code = err.ierr or 1
            # the largest PETSc error code any rank raised (0: none)
            error_code = failed_on_some_rank(self.grid.comm, error_code, "the Newton solve")
            if error_code:
                self._drop_factorizations()
        reason = self.snes.getConvergedReason()
        norms, lits = self.snes.getConvergenceHistory()
        its = self.snes.getIterationNumber()
        linear = self.snes.getLinearSolveIterations()
        # Residual evaluations beyond one per Newton iteration are line-search
        # backtracks; with -snes_mf_operator the Krylov products evaluate the
        # residual too, so backtracks cannot be counted this way (-1).
        extra = -1 if self._mf_operator() else problem.residual_evaluations - 1 - its
        if error_code:
            reason = min(int(reason), -1)
        reason_name = (_reason_name(reason) if not error_code else
                       f"PETSc error {error_code} in the linear solve (singular tangent?)")
        if (reason == PETSc.SNES.ConvergedReason.CONVERGED_SNORM_RELATIVE and self.gw_test is None
                and len(norms) and norms[-1] > max(self.snes.getTolerances()[1], SNORM_RESIDUAL_FRACTION * norms[0])):
            reason = PETSc.SNES.ConvergedReason.DIVERGED_LINE_SEARCH
            reason_name = (f"the Newton step fell below snes_stol with the residual still {norms[-1] / norms[0]:.2g} "
                           f"of its start (a stalled line search, or too large an snes_stol)")
        if self.fallback is not None and self.fallback.skipped > skipped_before:
            reason_name += (f" (the iterative solver failed; the direct fallback was not tried: more "
                            f"than solver.fallback_max_dofs = {self.fallback.max_free_dofs} free dofs)")
        info = {
            "reason": int(reason),
            "reason_name": reason_name,
            "converged": reason > 0 and not error_code,
            "newton_iterations": its,
            "linear_iterations": linear,
            "backtracks": int(extra) if extra < 0 else max(0, int(extra)),
            "linear_fallbacks": (self.fallback.fallbacks - fallbacks_before) if self.fallback else 0,
            "residual_history": np.array(norms, dtype=float),
            "inverted": bool(self.grid.comm.allreduce(problem.inverted)),
            "thickness_failed": bool(self.grid.comm.allreduce(problem.thickness_failed)),
        }
        return self.X.getArray(readonly=True).copy(), info


#: PETSc stops Newton when a step is shorter than snes_stol times the iterate
#: (CONVERGED_SNORM_RELATIVE), whatever the residual: a line search that took
#: a tiny step then "converges" with the residual still large (seen while
#: pimpm.line_search was developed: the frictionless upsetting's step 19 ended
#: at |R| 6.5 from 12.5, with twice the platen force). Such a stop counts as
#: converged only where the residual has fallen to this fraction of its start
#: (or below snes_atol); otherwise the step fails and is cut
SNORM_RESIDUAL_FRACTION = 1e-4


def command_line_options():
    """PETSc's options database as {name: value} (no dash): the command
    line, and whatever a caller has put there."""
    return {k: ("" if v is None or v is True else str(v)) for k, v in PETSc.Options().getAll().items()}


def _destroy_matrix(J):
    """Destroy ``J`` and the vectors of a free dofs' operator it holds."""
    operator = free_dofs_operator(J)
    if operator is not None:
        operator.release()
    J.destroy()


def diagonal_matrix(da):
    """An assembled identity on the DMDA's unknowns (AIJ, block size dof)."""
    X = da.createGlobalVec()
    sizes = (X.getLocalSize(), X.getSize())
    J = PETSc.Mat().createAIJ((sizes, sizes), bsize=da.getDof(), nnz=(1, 0), comm=da.getComm())
    X.set(1.0)
    J.setDiagonal(X)
    J.assemble()
    X.destroy()
    return J


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
    into PETSc's database only while a solver is set up or solves (options
    are read at set-up *and* at first use, as in Firedrake's
    ``OptionsManager.inserted_options``), so they never leak into other
    solvers; options already in the database (the command line) win and are
    left alone."""
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
