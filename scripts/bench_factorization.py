#!/usr/bin/env python3
"""Time the direct solver on Jacobians saved from a real run, outside the
run: analysis + first factorization, then refactorization + solve with the
same pattern, for any MUMPS (or other factorization) options given on the
command line. For tuning the direct solver, and for seeing how it scales
with the number of ranks, without the particle work around it.

Save the Jacobians of a run first (PETSc appends every matrix it factorizes
to one binary file; the 0.25 cm billet's 327 Newton iterations take 2.4 GB).
By default pimpm factorizes the free dofs only, and those matrices are
saved; ``-pimpm_free_dofs_only false`` saves the whole Newton matrices:

    mpiexec -n 1 python -m pimpm case.yaml -ksp_view_mat binary:J.bin -pimpm_free_dofs_only false

then, on 1 and 2 ranks, e.g.:

    mpiexec -n 2 python scripts/bench_factorization.py -mat J.bin -which 0,100,326 \
        -reps 5 -mat_mumps_icntl_7 2 [-mat_mumps_icntl_8 0] [-spd] [-json out.json]

``-which``: the 0-based positions of the matrices in the file; ``-spd``:
mark the matrix SPD (MUMPS SYM=1 instead of LDL^T with pivoting); ``-free``:
factorize only the free unknowns, i.e. drop the rows and columns that are a
diagonal entry alone (the prescribed and massless dofs, which pimpm keeps in
the system as identity rows), to see what keeping them costs. Prints the
fastest of ``-reps`` repetitions and the relative residual of the solve.
"""
import json
import sys
import time

import numpy as np
import petsc4py

petsc4py.init(sys.argv)
from petsc4py import PETSc  # noqa: E402


def load(path, wanted, comm):
    """The matrices at positions ``wanted`` of the binary file."""
    viewer = PETSc.Viewer().createBinary(path, "r", comm=comm)
    mats = {}
    for k in range(max(wanted) + 1):
        A = PETSc.Mat().create(comm=comm)
        A.setType(PETSc.Mat.Type.AIJ)
        A.load(viewer)
        if k in wanted:
            mats[k] = A
        else:
            A.destroy()
    viewer.destroy()
    return mats


def free_rows(A):
    """Index set of the rows of ``A`` with an off-diagonal entry that is not
    zero (the others are identity rows of prescribed or massless dofs; their
    columns are zero too, pimpm eliminates them symmetrically)."""
    start, end = A.getOwnershipRange()
    indptr, columns, values = A.getValuesCSR()
    rows = np.repeat(np.arange(start, end), np.diff(indptr))
    coupled = np.zeros(end - start, dtype=bool)
    off = (columns != rows) & (values != 0.0)
    coupled[rows[off] - start] = True
    return PETSc.IS().createGeneral((np.nonzero(coupled)[0] + start).astype(PETSc.IntType),
                                    comm=A.getComm())


def time_factorization(A, reps, comm):
    """Fastest (analysis + factorization) and (refactorization + solve) in
    seconds, and the relative residual of the last solve."""
    b = A.createVecLeft()
    b.setRandom()
    x = b.duplicate()
    first, again = [], []
    for _ in range(reps):
        ksp = PETSc.KSP().create(comm=comm)
        ksp.setOperators(A)
        ksp.setType(PETSc.KSP.Type.PREONLY)
        pc = ksp.getPC()
        pc.setType(PETSc.PC.Type.CHOLESKY)
        pc.setFactorSolverType("mumps")
        ksp.setFromOptions()                 # the command line has the last word
        comm.barrier()
        t0 = time.perf_counter()
        ksp.setUp()                          # symbolic + numeric
        comm.barrier()
        t1 = time.perf_counter()
        A.assemble()                         # new values, same pattern: numeric only
        ksp.solve(b, x)
        comm.barrier()
        t2 = time.perf_counter()
        first.append(t1 - t0)
        again.append(t2 - t1)
        ksp.destroy()
    r = A.createVecLeft()
    A.mult(x, r)
    r.axpy(-1.0, b)
    return min(first), min(again), r.norm() / b.norm()


def main():
    opts = PETSc.Options()
    comm = PETSc.COMM_WORLD
    path = opts.getString("mat", "J.bin")
    wanted = [int(s) for s in opts.getString("which", "0").split(",")]
    reps = opts.getInt("reps", 3)
    spd = opts.getBool("spd", False)
    free = opts.getBool("free", False)
    rows = []
    for k, A in sorted(load(path, wanted, comm).items()):
        if free:
            keep = free_rows(A)
            full, A = A, A.createSubMatrix(keep, keep)
            keep.destroy()
            full.destroy()
        A.setOption(PETSc.Mat.Option.SYMMETRIC, True)
        if spd:
            A.setOption(PETSc.Mat.Option.SPD, True)
        first, again, residual = time_factorization(A, reps, comm)
        rows.append({"matrix": k, "unknowns": A.getSize()[0], "analysis_and_factor_ms": 1e3 * first,
                     "refactor_and_solve_ms": 1e3 * again, "relative_residual": residual})
        PETSc.Sys.Print(f"matrix {k:4d}  {A.getSize()[0]} unknowns  {comm.size} rank(s)  "
                        f"analysis + factorization {1e3 * first:7.1f} ms  "
                        f"refactorization + solve {1e3 * again:7.1f} ms  residual {residual:.1e}")
        A.destroy()
    out = opts.getString("json", "")
    if out and comm.rank == 0:
        with open(out, "w") as f:
            json.dump({"ranks": comm.size, "options": sys.argv[1:], "free_only": free, "rows": rows}, f,
                      indent=1)


if __name__ == "__main__":
    main()
