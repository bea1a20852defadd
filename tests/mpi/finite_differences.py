"""The central-difference check of an assembled Jacobian that the MPI
check scripts share (tests/mpi/jacobian_check.py,
tests/mpi/contact_jacobian_check.py, tests/mpi/pair_jacobian_check.py)."""
import numpy as np
from mpi4py import MPI

#: a column whose difference exceeds this fraction of the largest entry is
#: differenced again with a ten times smaller step (see jacobian_error)
RECHECK = 1e-7


def _column(problem, X, R, j, start, end, h):
    """Column j of the central difference of the residual (step h), this rank's rows."""
    cols = []
    for sign in (1.0, -1.0):
        Xp = X.copy()
        if start <= j < end:
            Xp.getArray()[j - start] += sign * h
        problem.form_residual(None, Xp, R)
        cols.append(R.getArray().copy())
    return (cols[0] - cols[1]) / (2 * h)


def jacobian_error(problem, J, X, R, free_local, comm, h):
    """Compare the assembled ``J`` at ``X`` with central differences (step
    ``h``) of ``problem.form_residual``, column by column over the free dofs
    (``free_local``: this rank's owned free dofs; R: a work Vec). Returns
    (largest difference, largest finite-difference entry) over all ranks and
    this rank's dense rows of J (owned rows x all columns). Collective.

    A plastic particle within ``h`` of its yield surface puts a kink inside
    a central difference (an error of 1e-3 at h = 1e-6 that vanishes at
    1e-5 and 1e-7 alike: the 3-rank B-spline J2 check once met one). A
    column that differs by more than RECHECK of the largest entry is
    differenced again with h / 10 and keeps the closer of the two; a wrong
    tangent differs at both steps."""
    J_local = J.convert("dense").getDenseArray().copy()
    free_global = np.concatenate(comm.allgather(free_local))
    start, end = X.getOwnershipRange()
    J_fd = np.zeros_like(J_local)
    for j in range(X.getSize()):               # test code: a loop over columns is fine here
        if free_global[j]:
            J_fd[:, j] = _column(problem, X, R, j, start, end, h)
    rows = free_local

    def column_error(j, column):
        """max over all ranks' free rows of |J - column| in column j"""
        local = float(np.max(np.abs(J_local[rows, j] - column[rows]))) if rows.any() else 0.0
        return comm.allreduce(local, op=MPI.MAX)

    scale = comm.allreduce(float(np.max(np.abs(J_fd[np.ix_(rows, free_global)]))) if rows.any() else 0.0,
                           op=MPI.MAX)
    for j in np.flatnonzero(free_global):
        error = column_error(j, J_fd[:, j])
        if error > RECHECK * scale:                  # the same decision on every rank
            again = _column(problem, X, R, j, start, end, h / 10.0)
            if column_error(j, again) < error:
                J_fd[:, j] = again
    A = J_local[np.ix_(free_local, free_global)]
    B = J_fd[np.ix_(free_local, free_global)]
    err = comm.allreduce(float(np.max(np.abs(A - B))) if A.size else 0.0, op=MPI.MAX)
    return err, scale, J_local


def shell_errors(grid, problem, terms, solver_config, state, X, R, J, comm, seed=3):
    """The matrix-free product and diagonal (pimpm.implicit.shell) at ``X``
    against the assembled ``J``: (the largest relative difference of three
    random products, the relative difference of the diagonals). Collective."""
    from pimpm.implicit import StepProblem
    from pimpm.solver import NewtonSolver
    shell_problem = StepProblem(grid, problem.residual_scale, terms=terms)
    shell_solver = NewtonSolver(grid, shell_problem, dict(solver_config, preset="matrix-free"))
    shell_problem.begin(state)
    problem.form_residual(None, X, R)            # the terms' state at the iterate again
    shell_problem.form_jacobian(None, X, shell_solver.J, shell_solver.J)
    product, diagonal = operator_differences(J, shell_solver.J, X, np.random.default_rng(seed + comm.rank))
    shell_solver.destroy()
    return product, diagonal


def operator_differences(A, B, X, rng, trials=3, transpose=False):
    """How far the operator ``B`` is from ``A`` (PETSc Mats on the layout of
    the Vec ``X``): (the largest relative difference of ``trials`` products
    with random vectors, and of the transposed products too with
    ``transpose``; the relative difference of their diagonals). Collective."""
    product = 0.0
    for _ in range(trials):
        v = X.duplicate()
        v.getArray()[:] = rng.standard_normal(v.getLocalSize())
        y_a, y_b = X.duplicate(), X.duplicate()
        for mult_a, mult_b in [(A.mult, B.mult)] + ([(A.multTranspose, B.multTranspose)] if transpose else []):
            mult_a(v, y_a)
            mult_b(v, y_b)
            y_b.axpy(-1.0, y_a)
            product = max(product, y_b.norm() / y_a.norm())
    d_a, d_b = X.duplicate(), X.duplicate()
    A.getDiagonal(d_a)
    B.getDiagonal(d_b)
    d_b.axpy(-1.0, d_a)
    return product, d_b.norm() / d_a.norm()


def tangent_errors(grid, problem, terms, solver_config, state, X, R, J, comm):
    """The assembled ``J`` at ``X`` (formed there already) against central
    differences over the free dofs (:func:`jacobian_error`, step 1e-8) and
    against the matrix-free product and diagonal (:func:`shell_errors`):
    (relative error, product error, diagonal error). Collective."""
    err, scale, _ = jacobian_error(problem, J, X, R, ~state.fixed, comm, h=1e-8)
    shell_error, diagonal_error = shell_errors(grid, problem, terms, solver_config, state, X, R, J, comm)
    return err / scale, shell_error, diagonal_error
