"""Whole pimpm runs for the benchmark and validation scripts: the command
under ``mpiexec`` with the environment OpenMPI needs (root, oversubscribed
2-core machines) and this checkout on the Python path, timed."""
import csv
import os
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def mpi_env(tree=ROOT):
    """The environment of a run of the checkout at ``tree`` (this one, or a
    baseline's git worktree) under mpiexec."""
    e = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
             OMPI_MCA_rmaps_base_oversubscribe="1")
    e["PYTHONPATH"] = tree + os.pathsep + e.get("PYTHONPATH", "")
    return e


def run_pimpm(input_path, overrides, ranks, out):
    """Run ``input_path`` with ``--set`` overrides on ``ranks`` ranks into
    ``out``: (wall time of the whole process in s, history.csv rows as
    dicts). Exits with the run's output if it fails."""
    cmd = ["mpiexec", "-n", str(ranks), sys.executable, "-m", "pimpm", input_path, "--output", out, "--overwrite"]
    for o in overrides:
        cmd += ["--set", o]
    start = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=mpi_env())
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}")
    with open(os.path.join(out, "history.csv")) as f:
        return wall, list(csv.DictReader(f))
