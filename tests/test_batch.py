"""tests/mpi/batch.py, which runs a check script's cases in one MPI job
(tests/helpers.py BatchedChecks): each case gets its own output and exit
status, a failing case fails alone, and one that raises on a rank stops the
job instead of hanging it."""
import pytest

from helpers import MPIEXEC, BatchedChecks

pytestmark = [pytest.mark.skipif(MPIEXEC is None, reason="mpiexec not found"), pytest.mark.mpi]

#: a check script: prints its arguments and the ranks, sets a PETSc option,
#: exits with the status its first argument names, or raises on the last rank
SCRIPT = '''
import sys
import petsc4py
petsc4py.init(sys.argv[:1])
from mpi4py import MPI
from petsc4py import PETSc
comm = MPI.COMM_WORLD
db = PETSc.Options()
if comm.rank == 0:
    print(f"args={' '.join(sys.argv[1:])} ranks={comm.size} leaked={db.hasName('check_option')}")
db.setValue("check_option", "1")
if sys.argv[1] == "raise" and comm.rank == comm.size - 1:
    raise RuntimeError("this case fails on one rank")
comm.Barrier()
sys.exit(int(sys.argv[1]) if sys.argv[1] != "raise" else 0)
'''


@pytest.fixture
def script(tmp_path):
    path = tmp_path / "exit_check.py"
    path.write_text(SCRIPT)
    return str(path)


@pytest.mark.parametrize("nranks", [1, 2])
def test_each_case_gets_its_own_output_and_status(script, nranks):
    cases = [(nranks, ["0", "a"]), (nranks, ["3", "b"]), (nranks, ["0", "c"])]
    checks = BatchedChecks(script, cases, timeout=120)
    for (_, args), status in zip(cases, (0, 3, 0)):
        proc = checks.result(nranks, args)
        assert proc.returncode == status, proc.stdout + proc.stderr
        # the case's own output, and no option left over from the case before
        assert f"args={' '.join(args)} ranks={nranks} leaked=False" in proc.stdout, proc.stdout
        assert proc.stdout.count("args=") == 1, proc.stdout


def test_a_case_that_raises_on_one_rank_stops_the_job(script):
    checks = BatchedChecks(script, [(2, ["0", "first"]), (2, ["raise", "second"]), (2, ["0", "third"])],
                           timeout=60)
    proc = checks.result(2, ["0", "first"])
    assert proc.returncode == 0, proc.stdout + proc.stderr
    proc = checks.result(2, ["raise", "second"])
    assert proc.returncode is None and "this case fails on one rank" in proc.stderr, proc.stderr
    proc = checks.result(2, ["0", "third"])
    assert proc.returncode is None, proc.stdout + proc.stderr
