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



def test_a_petsc_error_on_one_rank_stops_every_rank(tmp_path):
    """A PETSc error that only some ranks raise inside the Newton solve
    (geometric multigrid coarsening a DMDA whose local part does not coarsen
    on rank 0 did: -pc_type mg -pc_mg_levels 2 on the 2-rank billet) leaves the
    other ranks inside a collective call: the failing rank waits
    DESYNC_TIMEOUT for them and stops every rank, instead of cutting the step
    alone and hanging the run."""
    from pimpm.solver import DESYNC_TIMEOUT
    proc, elapsed = run_with_failure(tmp_path, "jacobian:1:2")
    assert proc.returncode != 0
    assert elapsed < DESYNC_TIMEOUT + 30.0
    assert ("pimpm: error on rank 1 of 2: PETSc error 75 in the Newton solve on this rank alone, while the "
            "other ranks are still inside that collective call") in proc.stderr


def test_a_petsc_error_on_every_rank_is_a_failed_step(tmp_path):
    """The same error on every rank (as MUMPS reports a failed factorization)
    is a failed step, cut and retried on every rank: no rank stops the others."""
    proc, elapsed = run_with_failure(tmp_path, "jacobian:-1:2")
    assert proc.returncode == 1, proc.stderr[-2000:]
    said = proc.stdout + proc.stderr
    assert "PETSc error 75 in the linear solve (singular tangent?) after 0 iterations; cutting the step" in said
    assert "even after 4 step cuts" in said
    assert "MPI_ABORT" not in said

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


def _bar_config(directory):
    import yaml
    from pimpm.config import validate
    with open(BAR) as f:
        raw = yaml.safe_load(f)
    raw["output"] = {"directory": str(directory), "every": 1, "checkpoint_every": 2}
    return validate(raw)


def test_a_full_disk_stops_the_run_cleanly_and_it_continues_once_there_is_room(tmp_path, monkeypatch, capsys):
    """Issue 32, defect 6: a full disk (the file system's free space made to
    run out after step 5's output) is one line and status 1, the files as
    after the last good write (no .tmp left), and --restart continues the run
    from its last checkpoint to the same end."""
    import petsc4py
    petsc4py.init([])
    from mpi4py import MPI
    from pimpm.analysis import run
    from pimpm.io import space
    out = tmp_path / "out"
    calls = {"n": 0}

    def free_bytes(directory):
        calls["n"] += 1                # the initial output, then each step: its results, checkpoint
        return 10**12 if calls["n"] <= 9 else 1000
    monkeypatch.setattr(space, "free_bytes", free_bytes)
    status = run(_bar_config(out), MPI.COMM_WORLD, echo=lambda *a, **k: None)
    err = capsys.readouterr().err
    assert status == 1
    assert "pimpm: error: not enough room in" in err and "no space left on device" in err
    assert "continues from" in err and "--restart" in err
    assert not [p for p in os.listdir(out) if p.endswith(".tmp")]
    import h5py
    with h5py.File(out / "checkpoint.h5", "r") as f:
        assert 0 < int(f.attrs["step"]) < 10
    monkeypatch.setattr(space, "free_bytes", lambda directory: 10**12)
    status = run(_bar_config(out), MPI.COMM_WORLD, echo=lambda *a, **k: None, restart=True)
    assert status == 0
    with h5py.File(out / "results.h5", "r") as f:
        assert sorted(int(s) for s in f["steps"]) == list(range(11))


def test_a_disk_that_fills_on_two_ranks_stops_both_without_a_hang(tmp_path):
    """A real full file system (a 2 MiB tmpfs; needs root to mount): two
    ranks stop together, status 1, one message, no traceback."""
    tiny = tmp_path / "tiny"
    tiny.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(tiny)],
                      capture_output=True).returncode != 0:
        pytest.skip("cannot mount a tmpfs here (not root)")
    try:
        with open(tiny / "filler", "wb") as f:      # leave about 1.3 MiB: the first steps fit
            f.write(b"\0" * (700 * 1024))
        cmd = [MPIEXEC, "-n", "2", sys.executable, "-m", "pimpm", BAR, "--output", str(tiny / "o"),
               "--set", "output.every=1", "--set", "output.checkpoint_every=1",
               "--set", "time.end_time=1000"]
        proc = subprocess.run(cmd, env=mpi_env(), cwd=tmp_path, capture_output=True, text=True, timeout=120)
        assert proc.returncode == 1, proc.stderr[-3000:]
        assert "Traceback" not in proc.stderr
        assert proc.stderr.count("pimpm: error:") == 1 and "no space left on device" in proc.stderr.lower()
        assert not [p for p in os.listdir(tiny / "o") if p.endswith(".tmp")]
    finally:
        subprocess.run(["umount", str(tiny)], capture_output=True)


def test_a_grid_too_small_for_the_ranks_is_refused_on_every_rank(tmp_path):
    """Issue 32: a 3D GIMP grid of 2 cells a side on 4 ranks (process grid
    1x2x2) made PETSc's DMDA stop ranks 1-3 with 'error code 63' tracebacks
    while rank 0 waited; it is one line and exit 2 now, before anything is written."""
    from helpers import run_pimpm
    proc = run_pimpm(4, [os.path.join(ROOT, "inputs", "upsetting_3d.yaml"), "--output", "out",
                         "--set", "grid.cells=[2,2,2]"], cwd=tmp_path, timeout=120)
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr and "error code" not in proc.stderr
    assert "grid.cells = [2, 2, 2]: on 4 ranks" in proc.stderr and "fewer ranks" in proc.stderr
    assert not (tmp_path / "out").exists()


def _runs_as_another_user():
    """subprocess arguments that run pimpm as a user permissions bind: root
    runs it as 'nobody' (root writes anywhere), if 'nobody' can reach the
    checkout; None when it cannot."""
    if os.geteuid() != 0:
        return {}
    path = ROOT
    while path != os.path.dirname(path):
        if not os.stat(path).st_mode & 0o001:      # no search permission for others
            return None
        path = os.path.dirname(path)
    return {"user": 65534, "group": 65534, "extra_groups": []}


def test_an_output_directory_that_cannot_be_written_is_refused_before_anything_is_written():
    """Issue 32: an output directory that exists but cannot be written was
    run into, and the first HDF5 write ended in a PermissionError traceback
    (status 1). A fresh run and a --restart into it are one line and status
    2 now, every file as it was. Root writes anywhere, so as root the runs
    are made as 'nobody'."""
    import shutil
    import tempfile
    user = _runs_as_another_user()
    if user is None:
        pytest.skip("'nobody' cannot reach the checkout")
    work = tempfile.mkdtemp(prefix="pimpm-unwritable-")
    try:
        os.chmod(work, 0o777)
        first = subprocess.run([sys.executable, "-m", "pimpm", BAR, "--output", "o", "--set",
                                "output.checkpoint_every=1", "--set", "time.end_time=5.17"],
                               env=mpi_env(), cwd=work, capture_output=True, text=True, timeout=120)
        assert first.returncode == 0, first.stderr[-2000:]
        os.makedirs(os.path.join(work, "fresh"))
        for d in ("o", "fresh"):
            os.chmod(os.path.join(work, d), 0o555)

        def snapshot():
            return {os.path.join(r, p): open(os.path.join(r, p), "rb").read()
                    for d in ("o", "fresh") for r, _, files in os.walk(os.path.join(work, d)) for p in files}

        before = snapshot()
        env = dict(mpi_env(), HOME=work, NUMBA_CACHE_DIR=os.path.join(work, "numba-cache"))
        for args, name in (([], "fresh"), (["--restart", "--set", "output.checkpoint_every=1"], "o")):
            proc = subprocess.run([sys.executable, "-m", "pimpm", BAR, "--output", name, *args], env=env,
                                  cwd=work, capture_output=True, text=True, timeout=120, **user)
            assert proc.returncode == 2, proc.stderr[-2000:]
            assert "Traceback" not in proc.stderr
            assert proc.stderr.count("pimpm: error:") == 1
            assert f"output.directory = '{name}'" in proc.stderr and "cannot create files in it" in proc.stderr
            assert snapshot() == before
    finally:
        for d in ("o", "fresh"):
            if os.path.isdir(os.path.join(work, d)):
                os.chmod(os.path.join(work, d), 0o755)
        shutil.rmtree(work)
