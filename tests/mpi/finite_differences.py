"""The central-difference check of an assembled Jacobian that the MPI
check scripts share (tests/mpi/jacobian_check.py,
tests/mpi/contact_jacobian_check.py)."""
import numpy as np
from mpi4py import MPI


def jacobian_error(problem, J, X, R, free_local, comm, h):
    """Compare the assembled ``J`` at ``X`` with central differences (step
    ``h``) of ``problem.form_residual``, column by column over the free dofs
    (``free_local``: this rank's owned free dofs; R: a work Vec). Returns
    (largest difference, largest finite-difference entry) over all ranks and
    this rank's dense rows of J (owned rows x all columns). Collective."""
    J_local = J.convert("dense").getDenseArray().copy()
    free_global = np.concatenate(comm.allgather(free_local))
    start, end = X.getOwnershipRange()
    J_fd = np.zeros_like(J_local)
    for j in range(X.getSize()):               # test code: a loop over columns is fine here
        if not free_global[j]:
            continue
        cols = []
        for sign in (1.0, -1.0):
            Xp = X.copy()
            if start <= j < end:
                Xp.getArray()[j - start] += sign * h
            problem.form_residual(None, Xp, R)
            cols.append(R.getArray().copy())
        J_fd[:, j] = (cols[0] - cols[1]) / (2 * h)
    A = J_local[np.ix_(free_local, free_global)]
    B = J_fd[np.ix_(free_local, free_global)]
    err = comm.allreduce(float(np.max(np.abs(A - B))) if A.size else 0.0, op=MPI.MAX)
    scale = comm.allreduce(float(np.max(np.abs(B))) if B.size else 0.0, op=MPI.MAX)
    return err, scale, J_local
