"""Run one check script of this directory for several cases in one MPI job
(run under mpiexec): ``batch.py SCRIPT ARGS... [+ ARGS...]`` (SCRIPT's path
relative to this directory, or absolute), each group of
arguments separated by ``+`` being one run of SCRIPT. Starting Python, MPI,
PETSc and the compiled kernels takes about a second a job, more than most
checks; the tests run dozens of cases a rank count (tests/helpers.py,
``BatchedChecks``).

Rank 0 prints ``=== case: ARGS`` before a case's output and ``=== status: N``
after it (the script's exit status; its exit is caught). PETSc's options
database is restored after each case. A case that raises on any rank stops
the job (MPI_Abort), since the other ranks may wait in a collective call;
the job's exit status is 1 if any case failed."""
import os
import runpy
import sys
import traceback

import petsc4py

petsc4py.init(sys.argv[:1])
from mpi4py import MPI  # noqa: E402
from petsc4py import PETSc  # noqa: E402

SEPARATOR = "+"


def cases(arguments):
    """The argument groups between the separators."""
    groups, current = [], []
    for argument in arguments:
        if argument == SEPARATOR:
            groups.append(current)
            current = []
        else:
            current.append(argument)
    groups.append(current)
    return groups


def main():
    comm = MPI.COMM_WORLD
    script = os.path.join(os.path.dirname(os.path.abspath(__file__)), sys.argv[1])
    db = PETSc.Options()
    failed = False
    for case in cases(sys.argv[2:]):
        saved = db.getAll()
        if comm.rank == 0:
            print(f"=== case: {' '.join(case)}", flush=True)
        sys.argv = [script] + case
        try:
            runpy.run_path(script, run_name="__main__")
            status = 0
        except SystemExit as stop:
            status = stop.code if isinstance(stop.code, int) else (0 if stop.code is None else 1)
        except BaseException:  # noqa: B902 - any failure: the other ranks may be in a collective
            sys.stdout.flush()
            sys.stderr.write(f"=== case {' '.join(case)} raised on rank {comm.rank}:\n{traceback.format_exc()}")
            sys.stderr.flush()
            comm.Abort(1)
        for key in db.getAll():
            if key not in saved:
                db.delValue(key)
        for key, value in saved.items():
            db.setValue(key, value)
        sys.stdout.flush()
        if comm.rank == 0:
            print(f"=== status: {status}", flush=True)
        failed = failed or status != 0
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
