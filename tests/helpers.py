"""Shared test utilities: running scripts and pimpm under mpiexec, small configs."""
import os
import shutil
import subprocess
import sys

import h5py
import numpy as np
import yaml

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
MPIEXEC = shutil.which("mpiexec")


#: Open MPI's mpiexec waits 1 s between the SIGTERM and the SIGKILL it sends
#: the processes of a job one of whose processes exited with a nonzero status,
#: and takes 2 s to return after a bad input's exit status 2 even when every
#: rank has already exited (0.35 s without the wait). pimpm's ranks leave
#: together (MPI_Finalize is a fence), and a rank that cannot calls MPI_Abort,
#: so the wait protects nothing here, but a run signalled through mpiexec
#: (test_restart.start keeps it); the tests run many such jobs
NO_KILL_WAIT = {"OMPI_MCA_odls_base_sigkill_timeout": "0"}


def mpi_env():
    env = dict(os.environ)
    env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", **NO_KILL_WAIT)
    env["PYTHONPATH"] = ROOT + os.pathsep + env.get("PYTHONPATH", "")
    return env


def run_mpi(nranks, args, timeout=600, cwd=None):
    """Run ``python args...`` under ``mpiexec -n nranks`` (oversubscribing
    when needed). Returns the CompletedProcess."""
    cmd = [MPIEXEC, "-n", str(nranks)]
    if nranks > 2:
        cmd.append("--oversubscribe")
    cmd += [sys.executable] + [str(a) for a in args]
    return subprocess.run(cmd, env=mpi_env(), capture_output=True, text=True,
                          timeout=timeout, cwd=cwd)


class BatchedChecks:
    """The cases of one check script in tests/mpi/, run as one MPI job a
    rank count (tests/mpi/batch.py) when a test first asks for one of them:
    ``checks = BatchedChecks("jacobian_check.py", [(nranks, args), ...])``,
    then ``checks.result(nranks, args)`` is that case's CompletedProcess, as
    a job of its own would have given it: its exit status (None if it did
    not run) and stdout, and the job's stderr."""

    def __init__(self, script, cases, timeout=900):
        self.script, self.timeout = script, timeout
        self.cases = {}
        for nranks, args in cases:
            self.cases.setdefault(nranks, []).append([str(a) for a in args])
        self.results = {}

    def result(self, nranks, args):
        args = [str(a) for a in args]
        if nranks not in self.results:
            self.results[nranks] = self._run(nranks)
        outputs, stderr = self.results[nranks]
        status, stdout = outputs.get(tuple(args), (None, f"case {args} did not run\n"))
        return subprocess.CompletedProcess([self.script] + args, status, stdout, stderr)

    def _run(self, nranks):
        groups = self.cases[nranks]
        arguments = [f"{HERE}/mpi/batch.py", self.script]
        for k, args in enumerate(groups):
            arguments += (["+"] if k else []) + args
        try:
            proc = run_mpi(nranks, arguments, timeout=self.timeout)
        except subprocess.TimeoutExpired:        # every case of the job fails, once
            return {}, f"the job of the {nranks}-rank cases did not finish in {self.timeout} s"
        outputs, current, lines = {}, None, []
        for line in proc.stdout.splitlines(keepends=True):
            if line.startswith("=== case: "):
                current, lines = tuple(line[len("=== case: "):].split()), []
            elif line.startswith("=== status: ") and current is not None:
                outputs[current] = (int(line.split()[-1]), "".join(lines))
                current = None
            else:
                lines.append(line)
        return outputs, proc.stderr


def run_pimpm(nranks, args, timeout=600, cwd=None):
    """Run the CLI; nranks=None runs it without mpiexec."""
    if nranks is None:
        return subprocess.run([sys.executable, "-m", "pimpm"] + [str(a) for a in args],
                              env=mpi_env(), capture_output=True, text=True,
                              timeout=timeout, cwd=cwd)
    return run_mpi(nranks, ["-m", "pimpm"] + list(args), timeout=timeout, cwd=cwd)


def write_yaml(path, config):
    with open(path, "w") as f:
        yaml.safe_dump(config, f, sort_keys=False)
    return path


def coarse_billet(integrator="quasi_static", directory="out"):
    """The G&W 5.1 billet at 1 cm cells (half the paper's resolution): 20 steps
    of half a cell to 50% compression."""
    return {
        "title": f"coarse billet ({integrator})",
        "grid": {"lower": [0.0, 0.0], "upper": [36.0, 22.0], "cells": [36, 22],
                 "boundary": {"xmin": "symmetry", "ymin": "symmetry"}},
        "materials": {"rubber": {"model": "neo_hookean", "shear_modulus": 6.0e6,
                                 "bulk_modulus": 6.0e7, "density": 10.0}},
        "bodies": [
            {"name": "billet", "material": "rubber",
             "geometry": {"type": "box", "lower": [0.0, 0.0], "upper": [20.0, 20.0]},
             "particles_per_cell": 4},
            {"name": "platen", "rigid": True,
             "geometry": {"type": "box", "lower": [0.0, 20.0], "upper": [35.0, 21.0]},
             "particles_per_cell": 2, "velocity": [0.0, -50.0]},
        ],
        "time": {"integrator": integrator, "dt": 0.01, "end_time": 0.2},
        "output": {"directory": directory},
    }


def read_history(path):
    data = np.genfromtxt(path, delimiter=",", names=True)
    return np.atleast_1d(data)


def last_particles(results):
    """Particle fields of the last step of results.h5, sorted by id."""
    with h5py.File(results, "r") as f:
        steps = sorted(f["steps"])
        group = f["steps"][steps[-1]]["particles"]
        data = {k: group[k][...] for k in group}
        time = f["steps"][steps[-1]].attrs["time"]
    order = np.argsort(data["id"])
    return {k: v[order] for k, v in data.items()}, time


def coarse_upsetting():
    """inputs/upsetting.yaml (Sulsky & Kaul 3.2.7, axisymmetric finite-strain
    J2) at 2 mm cells with a 2 mm platen, bonded (it prescribes the nodes
    its particles reach; the input's platen is tied): a small plastic
    problem. The caller sets ``time``."""
    with open(os.path.join(ROOT, "inputs", "upsetting.yaml")) as f:
        raw = yaml.safe_load(f)
    raw["bodies"][1]["contact"] = "bonded"
    raw["grid"].update(upper=[24.0, 18.0], cells=[12, 9])
    raw["bodies"][1]["geometry"].update(lower=[0.0, 15.0], upper=[22.0, 17.0])
    return raw


def run_on_ranks(tmp_path, raw, ranks, timeout=600):
    """Run the CLI on ``raw`` (its output.directory relative to the run
    directory) once per rank count; returns [(last particles, time, history)]
    in the order of ``ranks``. Asserts that every run finished."""
    results = []
    for n in ranks:
        work = tmp_path / f"ranks{n}"
        work.mkdir()
        write_yaml(work / "input.yaml", raw)
        proc = run_pimpm(n, ["input.yaml"], cwd=work, timeout=timeout)
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
        out = work / raw["output"]["directory"]
        particles, time = last_particles(out / "results.h5")
        results.append((particles, time, read_history(out / "history.csv")))
    return results


def column(cells, shape, youngs_modulus=1.0e6, steps=10):
    """inputs/column_gravity.yaml (the self-weight column, height 50) with
    ``cells`` cells along its height (square cells, one cell wide), the given
    shape functions, Young's modulus and number of pseudo-time steps.
    Returns the raw input and (density, gravity, height)."""
    with open(os.path.join(ROOT, "inputs", "column_gravity.yaml")) as f:
        raw = yaml.safe_load(f)
    height = float(raw["bodies"][0]["geometry"]["upper"][1])
    h = height / cells
    raw["grid"].update(upper=[h, height + h], cells=[1, cells + 1], shape_functions=shape)
    raw["bodies"][0]["geometry"]["upper"] = [h, height]
    material = raw["materials"]["soil"]
    material["youngs_modulus"] = youngs_modulus
    raw["time"]["dt"] = raw["time"]["end_time"] / steps
    return raw, (material["density"], -raw["time"]["gravity"][1], height)
