"""A failure on one rank stops every rank (issue 13, first part): an
exception raised on rank 1 only, at the start of a step, inside the SNES
residual callback or inside the collective HDF5 write, must end the 2-rank
run within seconds with the failing rank's traceback and a non-zero exit
status, instead of leaving rank 0 waiting forever in a collective call.
The failures are injected with PIMPM_INJECT_FAILURE (pimpm/faults.py)."""
import os
import subprocess
import sys
import time

import pytest

from helpers import MPIEXEC, ROOT, mpi_env

pytestmark = pytest.mark.skipif(MPIEXEC is None, reason="mpiexec not found")

BAR = os.path.join(ROOT, "inputs", "bar_tension.yaml")


def run_with_failure(tmp_path, plan, ranks=2, options=()):
    env = dict(mpi_env(), PIMPM_INJECT_FAILURE=plan)
    cmd = [MPIEXEC, "-n", str(ranks), sys.executable, "-m", "pimpm", BAR, *options]
    start = time.monotonic()
    proc = subprocess.run(cmd, env=env, cwd=tmp_path, capture_output=True, text=True, timeout=120)
    return proc, time.monotonic() - start


@pytest.mark.parametrize("plan", ["step:1:2", "residual:1:2", "output:1:2", "output:1:0",
                                  "residual:0:1"])
def test_a_failure_on_one_rank_stops_every_rank(tmp_path, plan):
    proc, elapsed = run_with_failure(tmp_path, plan)
    where, rank, step = plan.split(":")
    assert proc.returncode != 0
    assert elapsed < 30.0
    assert f"pimpm: error on rank {rank} of 2: unexpected RuntimeError; stopping all ranks" in proc.stderr
    assert f"injected failure (PIMPM_INJECT_FAILURE) at {where}, rank {rank}, step {step}" in proc.stderr
    assert "Traceback (most recent call last)" in proc.stderr


@pytest.mark.parametrize("options", [(), ("-pimpm_preset", "gmres-gamg"), ("-pimpm_preset", "matrix-free")])
def test_a_failure_on_one_rank_of_one_is_a_traceback_and_status_1(tmp_path, options):
    """Also with pimpm's Python contexts in PETSc objects (the python KSPs of
    the direct solver on the free dofs and of the fallback, the matrix-free
    shell), which must go before PetscFinalize even when the traceback still
    holds the SNES (the last two used to crash there: MPI_ABORT, 59)."""
    proc, elapsed = run_with_failure(tmp_path, "residual:0:2", ranks=1, options=options)
    assert proc.returncode == 1 and elapsed < 30.0, proc.stderr[-2000:]
    assert "RuntimeError: injected failure" in proc.stderr


def test_a_bad_injection_plan_is_refused(monkeypatch):
    from pimpm import faults
    monkeypatch.setenv("PIMPM_INJECT_FAILURE", "somewhere:1:2")
    with pytest.raises(ValueError, match="expected WHERE:RANK:STEP"):
        faults.parse_injection("PIMPM_INJECT_FAILURE", "WHERE", faults.POINTS)
    monkeypatch.setenv("PIMPM_INJECT_FAILURE", "output:1:2")
    assert faults.parse_injection("PIMPM_INJECT_FAILURE", "WHERE", faults.POINTS) == ("output", 1, 2)
