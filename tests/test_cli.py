"""The command line, ``python -m pimpm``, run as a user runs it (a subprocess,
serial or under mpiexec, with a fresh temporary directory as cwd).

The product's promises checked here:

* bad input or usage: ONE line ``pimpm: error: ...`` on stderr naming the key,
  the value and what was expected; exit status 2; no Python traceback; nothing
  written (no output directory, no partial output); printed once under MPI;
* results already in the output directory are never silently replaced (exit 2,
  the message names the directory and ``--overwrite``);
* numerical failure: exit status 1, the results up to the last good step kept;
* ``--check`` validates and prints the summary without writing anything;
* a run writes results.h5, particles.xdmf, grid.xdmf and history.csv, one
  progress line and one history row per step;
* PETSc options reach PETSc: command line > YAML ``solver.petsc`` > defaults.

Every pimpm process costs about a second (imports and MPI start-up), so the
independent runs are started a few at a time and checked one by one.
"""
import csv
import glob
import math
import os
import re
import subprocess
import sys

import h5py
import numpy as np
import pytest
import yaml

from helpers import MPIEXEC, ROOT, mpi_env, run_pimpm, write_yaml

INPUTS = sorted(glob.glob(os.path.join(ROOT, "inputs", "*.yaml")))
BAR = os.path.join(ROOT, "inputs", "bar_tension.yaml")
OUTPUT_FILES = ("results.h5", "particles.xdmf", "grid.xdmf", "history.csv")
HISTORY_COLUMNS = ["step", "time", "dt", "newton_iterations", "linear_iterations",
                   "residual_initial", "residual_final", "kinetic_energy", "strain_energy",
                   "total_energy", "external_work"]
ERROR = "pimpm: error:"

needs_mpiexec = pytest.mark.skipif(MPIEXEC is None, reason="mpiexec not found")


# --------------------------------------------------------------------------- helpers

def bar(directory="out", end_time=None, petsc=None):
    """The shipped bar-in-tension input (10 steps, < 1 s) writing to ``directory``."""
    with open(BAR) as f:
        cfg = yaml.safe_load(f)
    cfg["output"] = {"directory": directory}
    if end_time is not None:
        cfg["time"]["end_time"] = end_time
    if petsc is not None:
        cfg["solver"] = {"petsc": petsc}
    return cfg


def listing(directory):
    """Every file and directory below ``directory`` (relative paths)."""
    found = set()
    for root, dirs, files in os.walk(directory):
        for name in dirs + files:
            found.add(os.path.relpath(os.path.join(root, name), directory))
    return found


def error_lines(text):
    return [line for line in text.splitlines() if line.startswith(ERROR)]


def show(proc):
    return f"exit status {proc.returncode}\n--- stdout:\n{proc.stdout}\n--- stderr:\n{proc.stderr}"


def command(nranks, args):
    """The command line helpers.run_pimpm runs."""
    python = [sys.executable, "-m", "pimpm"] + [str(a) for a in args]
    if nranks is None:
        return python
    return [MPIEXEC, "-n", str(nranks)] + (["--oversubscribe"] if nranks > 2 else []) + python


def run_together(jobs, timeout=120, parallel=4):
    """Run several pimpm commands, ``parallel`` at a time: ``jobs`` maps a name
    to (nranks, args, cwd). Returns name -> CompletedProcess (returncode None
    if the run hung and was killed)."""
    results, running = {}, []

    def finish(name, proc):
        try:
            out, err = proc.communicate(timeout=timeout)
            code = proc.returncode
        except subprocess.TimeoutExpired:
            proc.kill()
            out, err = proc.communicate()
            code, err = None, err + "\n[test] killed: the run hung"
        results[name] = subprocess.CompletedProcess(proc.args, code, out, err)

    for name, (nranks, args, cwd) in jobs.items():
        if len(running) >= parallel:
            finish(*running.pop(0))
        running.append((name, subprocess.Popen(
            command(nranks, args), cwd=cwd, env=mpi_env(), stdout=subprocess.PIPE,
            stderr=subprocess.PIPE, text=True)))
    for name, proc in running:
        finish(name, proc)
    return results


def h5_steps(path):
    with h5py.File(path, "r") as f:
        return sorted(int(s) for s in f["steps"])


def read_history(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def snapshot(directory):
    out = {}
    for name in OUTPUT_FILES:
        path = os.path.join(directory, name)
        with open(path, "rb") as f:
            out[name] = (os.stat(path).st_mtime_ns, f.read())
    return out


# --------------------------------------------------------------------------- --help

def test_help_prints_usage_without_input(tmp_path):
    proc = run_pimpm(None, ["--help"], cwd=tmp_path, timeout=60)
    assert proc.returncode == 0, show(proc)
    assert "usage:" in proc.stdout and "INPUT.yaml" in proc.stdout
    for option in ("--check", "--overwrite", "--help"):
        assert option in proc.stdout
    assert proc.stderr == ""
    assert listing(tmp_path) == set()


def test_petsc_help_is_passed_to_petsc(tmp_path):
    """-help is PETSc's: with an input and --check, the solver's options are listed."""
    write_yaml(tmp_path / "bar.yaml", bar())
    proc = run_pimpm(None, ["bar.yaml", "--check", "-help"], cwd=tmp_path, timeout=60)
    assert proc.returncode == 0, show(proc)
    assert "-snes_type" in proc.stdout and "-ksp_type" in proc.stdout
    assert "input is valid" in proc.stdout
    assert listing(tmp_path) == {"bar.yaml"}


# --------------------------------------------------------------------------- --check

def expected_summary(path):
    """Summary facts computed from a shipped input (boxes aligned with cells)."""
    with open(path) as f:
        cfg = yaml.safe_load(f)
    g, t = cfg["grid"], cfg["time"]
    dim = len(g["lower"])
    h = [(float(g["upper"][i]) - float(g["lower"][i])) / g["cells"][i] for i in range(dim)]
    bodies = {}
    for b in cfg["bodies"]:
        ppc = b.get("particles_per_cell", 2)
        ppc = ppc if isinstance(ppc, list) else [ppc] * dim
        geo = b["geometry"]
        if geo["type"] == "mesh":           # n^dim particles per element (pimpm/meshes.py)
            import meshio
            mesh = meshio.read(os.path.join(os.path.dirname(path), geo["file"]))
            kinds = ("triangle", "quad") if dim == 2 else ("tetra", "hexahedron")
            elements = sum(len(c.data) for c in mesh.cells if c.type in kinds)
            bodies[b["name"]] = elements * geo.get("particles_per_element", 2) ** dim
        elif geo["type"] == "particles":    # a CSV cloud: a particle a row after the header
            with open(os.path.join(os.path.dirname(path), geo["file"])) as f:
                rows = [line for line in f if line.strip() and not line.startswith("#")]
            bodies[b["name"]] = len(rows) - 1
        elif geo["type"] == "box":
            bodies[b["name"]] = math.prod(
                round((float(geo["upper"][i]) - float(geo["lower"][i])) / h[i] * ppc[i])
                for i in range(dim))
        else:   # a ball or a cylinder: count the sub-cells (pimpm/seeding.py)
            axes = [float(g["lower"][i]) + (np.arange(g["cells"][i] * ppc[i]) + 0.5) * h[i] / ppc[i]
                    for i in range(dim)]
            points = np.stack([m.ravel() for m in np.meshgrid(*axes, indexing="ij")], axis=1)
            half = np.array([h[i] / ppc[i] / 2.0 for i in range(dim)])
            if geo["type"] == "ball":          # centre strictly inside
                inside = np.sum((points - np.array(geo["center"], float)) ** 2, axis=1) \
                    < float(geo["radius"]) ** 2
            elif geo["type"] == "half_space":  # centre strictly on the inner side of the plane
                normal = np.array(geo["normal"], float)
                inside = (points - np.array(geo["point"], float)) @ (normal / np.linalg.norm(normal)) < 0.0
            elif geo["type"] == "surface":     # one segment (the shipped ramp): the side on its left,
                import meshio                  # within a cell of it, sub-cells clipped to that box
                mesh = meshio.read(os.path.join(os.path.dirname(path), geo["file"]))
                (first, last), = [c.data for c in mesh.cells if c.type == "line"][0]
                start, end = mesh.points[first, :dim], mesh.points[last, :dim]
                normal = np.array([end[1] - start[1], start[0] - end[0]])
                box_lo = np.maximum(np.minimum(start, end) - h, np.array(g["lower"], float))
                box_hi = np.minimum(np.maximum(start, end) + h, np.array(g["upper"], float))
                lo, hi = np.maximum(points - half, box_lo), np.minimum(points + half, box_hi)
                inside = np.all(hi - lo > 1e-9 * half, axis=1) & ((0.5 * (lo + hi) - start) @ normal < 0.0)
            else:                              # overlaps the box, centre strictly inside radially
                radial = [d for d in range(dim) if d != "xyz".index(geo["axis"])]
                inside = np.all((points + half > np.array(geo["lower"], float) + 1e-9 * half)
                                & (points - half < np.array(geo["upper"], float) - 1e-9 * half), axis=1)
                inside &= np.sum((points[:, radial] - np.array(geo["center"], float)[radial]) ** 2,
                                 axis=1) < float(geo["radius"]) ** 2
            bodies[b["name"]] = int(inside.sum())
    if "dt" not in t:           # explicit with an automatic step
        return "x".join(str(c) for c in g["cells"]), bodies, None, None
    steps = math.ceil(float(t["end_time"]) / float(t["dt"]) - 1e-9)
    cells = "x".join(str(c) for c in g["cells"])
    return cells, bodies, float(t["dt"]), steps


def check_summary(stdout, path, nranks):
    cells, bodies, dt, steps = expected_summary(path)
    assert stdout.count("pimpm: input is valid") == 1, stdout
    assert len(re.findall(r"^\s*grid\s", stdout, re.M)) == 1, stdout
    assert re.search(rf"^\s*grid\s+{cells} cells", stdout, re.M), stdout
    ranks = re.findall(r"^\s*ranks\s+(\d+)", stdout, re.M)
    assert ranks == [str(nranks)], stdout
    for name, count in bodies.items():
        found = re.findall(rf"^\s*body\s+{re.escape(name)}: (\d+) particles", stdout, re.M)
        assert found == [str(count)], (name, stdout)
    time_line = re.findall(r"^\s*time\s.*$", stdout, re.M)
    assert len(time_line) == 1, stdout
    if dt is None:
        assert "automatic dt" in time_line[0], time_line
    else:
        assert f"dt {dt:g}" in time_line[0] and f"{steps} steps" in time_line[0], time_line


@pytest.fixture(scope="module")
def shipped_checks(tmp_path_factory):
    """``--check`` of every shipped input, each in a directory of its own,
    several at a time (run_together): path -> (CompletedProcess, directory)."""
    base = tmp_path_factory.mktemp("check")
    jobs = {}
    for k, path in enumerate(INPUTS):
        work = base / f"{k}"
        work.mkdir()
        jobs[path] = (None, [path, "--check"], work)
    results = run_together(jobs, timeout=120)
    return {path: (results[path], jobs[path][2]) for path in INPUTS}


@pytest.mark.parametrize("path", INPUTS, ids=[os.path.basename(p) for p in INPUTS])
def test_check_shipped_input(path, shipped_checks):
    proc, work = shipped_checks[path]
    assert proc.returncode == 0, show(proc)
    check_summary(proc.stdout, path, 1)
    assert not re.search(r"^step\s", proc.stdout, re.M)  # nothing was run
    assert listing(work) == set(), "--check must write nothing"


@needs_mpiexec
def test_check_on_two_ranks_prints_summary_once(tmp_path):
    try:
        proc = run_pimpm(2, [BAR, "--check"], cwd=tmp_path, timeout=10)
    except subprocess.TimeoutExpired:
        pytest.fail("python -m pimpm INPUT --check hung under mpiexec -n 2")
    assert proc.returncode == 0, show(proc)
    check_summary(proc.stdout, BAR, 2)
    assert listing(tmp_path) == set()


# --------------------------------------------------------------------------- bad input
#
# Each case: setup(directory) writes what it needs there and returns the
# command-line arguments; then the substrings the error line must contain
# (key path and offending value).

def yaml_case(edit, *extra):
    def setup(directory):
        cfg = bar()
        edit(cfg)
        write_yaml(os.path.join(directory, "bad.yaml"), cfg)
        return ["bad.yaml", *extra]
    return setup


def text_case(text):
    def setup(directory):
        with open(os.path.join(directory, "bad.yaml"), "w") as f:
            f.write(text)
        return ["bad.yaml"]
    return setup


def with_file(name, content, option):
    """The bar input and a file ``name`` with ``content`` passed as ``option name``."""
    def setup(directory):
        with open(os.path.join(directory, name), "wb") as f:
            f.write(content)
        write_yaml(os.path.join(directory, "bad.yaml"), bar())
        return ["bad.yaml", option, name]
    return setup


def directory_in_output(name):
    """Earlier results beside a directory where pimpm writes ``name``, with --overwrite."""
    def setup(directory):
        write_yaml(os.path.join(directory, "bad.yaml"), bar(directory="out"))
        os.makedirs(os.path.join(directory, "out", name))
        with open(os.path.join(directory, "out", "history.csv"), "w") as f:
            f.write("step\n1\n")
        return ["bad.yaml", "--overwrite"]
    return setup


def set_key(path, value):
    """An edit setting cfg[path...] = value (path is a list of keys/indices)."""
    def edit(cfg):
        node = cfg
        for key in path[:-1]:
            node = node[key]
        node[path[-1]] = value
    return edit


def output_is_a_file(directory):
    with open(os.path.join(directory, "taken"), "w") as f:
        f.write("not a directory\n")
    write_yaml(os.path.join(directory, "bad.yaml"), bar(directory="taken"))
    return ["bad.yaml"]


def fifo_input(directory):
    """The input is a FIFO nobody writes to: reading it would block forever."""
    os.mkfifo(os.path.join(directory, "bad.yaml"))
    return ["bad.yaml"]


def link_in_output(name, target_exists=True):
    """A pre-placed symbolic link where pimpm writes one of its files."""
    def setup(directory):
        write_yaml(os.path.join(directory, "bad.yaml"), bar(directory="out"))
        os.makedirs(os.path.join(directory, "out"))
        target = os.path.join(directory, "victim.txt")
        if target_exists:
            with open(target, "w") as f:
                f.write("precious\n")
        os.symlink(target, os.path.join(directory, "out", name))
        return ["bad.yaml"]
    return setup


BAD_INPUTS = {
    "negative shear modulus": (
        None, yaml_case(set_key(["materials", "elastic"], {
            "model": "neo_hookean", "shear_modulus": -5.0, "bulk_modulus": 800.0,
            "density": 10.0})),
        ["materials.elastic.shear_modulus", "-5.0", "expected a positive number"]),
    "f_bar not a boolean or an average": (
        None, yaml_case(set_key(["materials", "elastic", "f_bar"], "sometimes")),
        ["materials.elastic.f_bar", "'sometimes'", "true, false, cells or nodes"]),
    "f_bar_blend without f_bar": (
        None, yaml_case(set_key(["materials", "elastic", "f_bar_blend"], 0.1)),
        ["materials.elastic.f_bar_blend = 0.1", "no f_bar_blend while materials.elastic.f_bar is false"]),
    "f_bar in plane stress": (
        None, yaml_case(lambda cfg: (cfg["materials"]["elastic"].update(f_bar=True),
                                     cfg.update(kinematics="plane_stress"))),
        ["materials.elastic.f_bar", "plane_stress", "does not lock"]),
    "unknown top-level key": (
        None, yaml_case(set_key(["solvr"], {"petsc": {}})),
        ["solvr", "unknown key", "solver"]),
    "unknown material": (
        None, yaml_case(set_key(["bodies", 0, "material"], "steel")),
        ["bodies[0].material", "'steel'", "elastic"]),
    "body outside the grid": (
        None, yaml_case(set_key(["bodies", 0, "geometry", "upper"], [0.8, 0.3])),
        ["bodies[0].geometry.upper[0]", "0.8", "grid"]),
    "particles_per_cell 0": (
        None, yaml_case(set_key(["bodies", 0, "particles_per_cell"], 0)),
        ["bodies[0].particles_per_cell", "= 0", "integer >= 1"]),
    "string for a number": (
        None, yaml_case(set_key(["time", "dt"], "fast")),
        ["time.dt", "'fast'", "positive number"]),
    "dt 0": (
        None, yaml_case(set_key(["time", "dt"], 0)),
        ["time.dt = 0", "positive number"]),
    "non-integer cells": (
        None, yaml_case(set_key(["grid", "cells"], [7, 2.5])),
        ["grid.cells[1]", "2.5", "integer"]),
    "bad input with --check": (
        None, yaml_case(set_key(["time", "end_time"], -1.0), "--check"),
        ["time.end_time", "-1.0", "positive number"]),
    "YAML syntax error": (
        None, text_case("grid: {lower: [0, 0], upper: [1, 1], cells: [2, 2]\nmaterials: [\n"),
        ["bad.yaml:2", "YAML syntax error"]),
    "top level not a mapping": (
        None, text_case("- grid\n- bodies\n"),
        ["(top level)", "['grid', 'bodies']", "mapping"]),
    "missing file": (
        None, lambda directory: ["nope.yaml"],
        ["nope.yaml", "not found"]),
    "unknown pimpm option": (
        None, yaml_case(lambda cfg: None, "--frobnicate"),
        ["--frobnicate"]),
    "output directory is a file": (
        None, output_is_a_file,
        ["output.directory", "'taken'", "not a directory"]),
    "two ranks: negative shear modulus": (
        2, yaml_case(set_key(["materials", "elastic"], {
            "model": "neo_hookean", "shear_modulus": -5.0, "bulk_modulus": 800.0,
            "density": 10.0})),
        ["materials.elastic.shear_modulus", "-5.0", "expected a positive number"]),
    # Bad input that only PETSc or the file system can detect:
    "YAML PETSc option with a bad value": (
        None, yaml_case(set_key(["solver"], {"petsc": {"ksp_type": "nonsense"}})),
        ["solver.petsc.ksp_type", "nonsense"]),
    "command-line PETSc option with a bad value": (
        None, yaml_case(lambda cfg: None, "-ksp_type", "nonsense"),
        ["ksp_type", "nonsense"]),
    "command-line PETSc option with a value of the wrong type": (
        None, yaml_case(lambda cfg: None, "-snes_max_it", "abc"),
        ["-snes_max_it", "abc", "rejected by PETSc"]),
    "YAML PETSc option with a value of the wrong type": (
        None, yaml_case(set_key(["solver"], {"petsc": {"snes_rtol": "abc"}})),
        ["solver.petsc.snes_rtol", "abc", "rejected by PETSc"]),
    "negative Newton iteration limit": (
        None, yaml_case(lambda cfg: None, "-snes_max_it", "-3"),
        ["-snes_max_it", "-3", "integer >= 1"]),
    "negative Krylov tolerance in the YAML": (
        None, yaml_case(set_key(["solver"], {"preset": "gmres-gamg", "fallback": False,
                                             "petsc": {"ksp_rtol": -5}})),
        ["solver.petsc.ksp_rtol", "-5", "number >= 0"]),
    "momentum formulation with a symmetric solver": (
        None, yaml_case(lambda cfg: cfg["time"].update(integrator="newmark", formulation="momentum"),
                        "-pimpm_preset", "cg-gamg"),
        ["cg-gamg", "time.formulation: momentum", "gmres-gamg"]),
    "non-symmetric finite-strain J2 tangent with conjugate gradients": (
        None, yaml_case(set_key(["materials", "elastic"], {
            "model": "j2_finite_strain", "youngs_modulus": 1000.0, "poisson_ratio": 0.3,
            "density": 10.0, "yield_stress": 5.0, "hardening_modulus": 1.0}), "-pimpm_preset", "cg-gamg"),
        ["-pimpm_preset", "cg-gamg", "j2_finite_strain", "gmres-gamg"]),
    "output directory cannot be created": (
        None, yaml_case(set_key(["output"], {"directory": "/dev/null/sub"})),
        ["output.directory", "/dev/null/sub"]),
    # issue 13's table of inputs that used to escape (docs/RELIABILITY.md)
    "self-referencing alias": (None, text_case("title: &a [*a]\n"), ["bad.yaml:1", "alias *a"]),
    "a million cells per axis, --check": (
        None, yaml_case(set_key(["grid", "cells"], [1000000, 1000000]), "--check"),
        ["grid.cells = [1000000, 1000000]", "32-bit indices"]),
    "dt 1e-12 with end_time 1": (
        None, yaml_case(lambda cfg: cfg["time"].update(dt=1e-12, end_time=1.0)),
        ["time.end_time = 1.0", "at most 10,000,000 steps"]),
    "moduli 1e308": (
        None, yaml_case(lambda cfg: cfg["materials"]["elastic"].update(youngs_modulus=1e308)),
        ["materials.elastic.youngs_modulus = 1e+308", "finite, normal"]),
    "input is a FIFO": (None, fifo_input, ["bad.yaml: is a FIFO"]),
    "input is /dev/zero": (None, lambda directory: ["/dev/zero"], ["/dev/zero: is a device"]),
    "iterative preset with a bad KSP type": (
        None, yaml_case(lambda cfg: None, "-pimpm_preset", "cg-gamg", "-ksp_type", "nonsense"),
        ["-ksp_type", "nonsense"]),
    "iterative preset with a bad value type": (
        2, yaml_case(lambda cfg: None, "-pimpm_preset", "gmres-gamg", "-ksp_max_it", "abc"),
        ["-ksp_max_it abc", "rejected by PETSc"]),
    "iterative preset, bad option in the YAML": (
        None, yaml_case(set_key(["solver"], {"preset": "gmres-gamg", "petsc": {"ksp_type": "nonsense"}})),
        ["solver.petsc.ksp_type", "nonsense"]),
    "negative Krylov tolerance": (
        None, yaml_case(lambda cfg: None, "-pimpm_preset", "cg-gamg", "-ksp_rtol", "-5"),
        ["-ksp_rtol", "-5", "number >= 0"]),
    # issue 32: escapes
    "pimpm's flag with one dash": (None, yaml_case(lambda cfg: None, "-check"), ["-check: expected --check"]),
    "--check --restart without a checkpoint": (None, yaml_case(lambda cfg: None, "--check", "--restart"),
                                                ["no usable checkpoint.h5"]),
    "an empty output directory": (None, yaml_case(lambda cfg: None, "--output", ""),
                                  ["--output ''", "expected a directory name"]),
    "a body name with a newline": (
        None, yaml_case(lambda cfg: cfg["bodies"][0].update(name="bar\nx")),
        ["bodies[0].name", "without control characters"]),
    "an integer beyond the float range": (
        None, yaml_case(lambda cfg: cfg["materials"]["elastic"].update(youngs_modulus=10 ** 400)),
        ["materials.elastic.youngs_modulus", "expected"]),
    "an axisymmetric grid at negative radius": (
        None, yaml_case(lambda cfg: cfg.update(kinematics="axisymmetric") or cfg["grid"].update(lower=[-0.7, 0.0])),
        ["grid.lower = [-0.7, 0.0]", "x >= 0 with kinematics: axisymmetric"]),
    # issue 32: runs that would never end
    "a first step of 1e-200 that never grows": (
        None, yaml_case(lambda cfg: cfg["time"].update(dt_initial=1e-200, ramp_factor=1.0)),
        ["time.end_time", "time.dt_initial = 1e-200 (time.ramp_factor 1)"]),
    "2000 step cuts": (
        None, yaml_case(lambda cfg: cfg["time"].update(max_cuts=2000)),
        ["time.max_cuts = 2000", "from 0 to 50"]),
    # issue 32: option values PETSc takes but that make the run meaningless or fail later
    "NaN line-search damping": (
        None, yaml_case(lambda cfg: None, "-snes_linesearch_damping", "nan"),
        ["-snes_linesearch_damping = nan", "finite number > 0"]),
    "negative MUMPS workspace increase": (
        None, yaml_case(lambda cfg: None, "-mat_mumps_icntl_14", "-100"),
        ["-mat_mumps_icntl_14 = -100", "integer >= 0"]),
    "negative matrix-free differencing parameter in the YAML": (
        None, yaml_case(set_key(["solver"], {"petsc": {"mat_mffd_err": -1}})),
        ["solver.petsc.mat_mffd_err = -1", "finite number > 0"]),
    "fallback GMRES restart 0": (
        None, yaml_case(lambda cfg: None, "-fallback_ksp_gmres_restart", "0"),
        ["-fallback_ksp_gmres_restart = 0", "integer >= 1"]),
    "python KSP without a context": (
        None, yaml_case(lambda cfg: None, "-ksp_type", "python"), ["-ksp_type = python", "PETSc type"]),
    "negative Guilkey-Weiss tolerance": (
        None, yaml_case(lambda cfg: None, "-pimpm_gw_displacement_tol", "-1"),
        ["-pimpm_gw_displacement_tol -1", "positive, finite number"]),
    "NaN Guilkey-Weiss tolerance with the PETSc test": (
        None, yaml_case(lambda cfg: None, "-pimpm_gw_energy_tol", "nan"),
        ["-pimpm_gw_energy_tol nan", "positive, finite number"]),
    "an options file in the YAML": (
        None, yaml_case(set_key(["solver"], {"petsc": {"options_file": "opts.txt"}})),
        ["solver.petsc.options_file", "on the command line"]),
    # issue 32: tolerances that make every step "converge" at once
    "infinite Newton tolerance": (
        None, yaml_case(lambda cfg: None, "-snes_atol", "inf"), ["-snes_atol = inf", "finite number >= 0"]),
    "relative Newton tolerance beyond the float range": (
        None, yaml_case(lambda cfg: None, "-snes_rtol", "1e400"), ["-snes_rtol = inf", "number >= 0 and < 1"]),
    "relative Newton tolerance of 1 in the YAML": (
        None, yaml_case(set_key(["solver"], {"petsc": {"snes_rtol": 1.0}})),
        ["solver.petsc.snes_rtol = 1", "number >= 0 and < 1"]),
    "NaN Krylov tolerance": (
        None, yaml_case(lambda cfg: None, "-pimpm_preset", "cg-gamg", "-ksp_atol", "nan"),
        ["-ksp_atol = nan", "finite number >= 0"]),
    "unknown factorization package": (
        None, yaml_case(lambda cfg: None, "-pc_factor_mat_solver_type", "nonsense"),
        ["-pc_factor_mat_solver_type = 'nonsense'", "factorization package"]),
    "unknown line search": (
        None, yaml_case(lambda cfg: None, "-snes_linesearch_type", "nonsense"),
        ["-snes_linesearch_type nonsense", "rejected by PETSc"]),
    "fallback flag not a boolean": (
        None, yaml_case(lambda cfg: None, "-pimpm_fallback", "abc"),
        ["-pimpm_fallback"]),
    "options file that does not exist": (
        None, yaml_case(lambda cfg: None, "-options_file", "/nonexistent"),
        ["-options_file /nonexistent", "readable file"]),
    # issue 32: PETSc would stop these with an error block and a traceback
    "an options file with a line that is no option": (
        None, with_file("opts.txt", b"-snes_rtol 1e-6\nthis is not an option\n", "-options_file"),
        ["-options_file opts.txt line 2", "'this'", "-option [value]"]),
    "a binary options file": (
        None, with_file("opts.txt", bytes(range(256)) * 4, "-options_file"),
        ["-options_file opts.txt", "UTF-8"]),
    "a YAML options file with a syntax error": (
        None, with_file("opts.yaml", b"snes_rtol: [1, 2\n", "-options_file_yaml"),
        ["-options_file_yaml opts.yaml", "YAML syntax error"]),
    "a YAML options file that is a list": (
        None, with_file("opts.yaml", b"- snes_rtol\n", "-options_file_yaml"),
        ["-options_file_yaml opts.yaml", "mapping"]),
    "overlapping deformable bodies": (
        None, yaml_case(lambda cfg: cfg["bodies"].insert(1, dict(cfg["bodies"][0], name="twin"))),
        ["bodies[1].geometry", "lie inside body", "overlap"]),
    # issue 32: --overwrite removed the other results, then could not remove this one
    "a directory where results.h5 goes, with --overwrite": (
        None, directory_in_output("results.h5"), ["out/results.h5", "is not a file"]),
    "a link where the XDMF temporary goes": (
        None, link_in_output("particles.xdmf.tmp"), ["particles.xdmf.tmp", "symbolic link"]),
    "--set with a bad value, two ranks": (
        2, yaml_case(lambda cfg: None, "--set", "time.dt=-1"),
        ["--set time.dt=-1", "time.dt = -1", "positive number"]),
    "--set without a value": (
        None, yaml_case(lambda cfg: None, "--set", "time.dt"),
        ["--set time.dt", "KEY.PATH=VALUE"]),
    "--output that is a file": (
        None, lambda directory: output_is_a_file(directory) + ["--output", "taken"],
        ["output.directory", "'taken'", "not a directory"]),
    "a dangling link where history.csv goes": (
        None, link_in_output("history.csv", target_exists=False), ["history.csv", "symbolic link"]),
}



@pytest.fixture(scope="module")
def bad_runs(tmp_path_factory):
    """Runs every BAD_INPUTS case (a few at a time); name -> (proc, files before, files after)."""
    jobs, before = {}, {}
    for i, (name, (nranks, setup, _)) in enumerate(BAD_INPUTS.items()):
        if nranks is not None and MPIEXEC is None:
            continue
        directory = str(tmp_path_factory.mktemp(f"bad{i}"))
        args = setup(directory)
        before[name] = listing(directory)
        jobs[name] = (nranks, args, directory)
    procs = run_together(jobs)
    return {name: (procs[name], before[name], listing(jobs[name][2])) for name in jobs}


@pytest.mark.parametrize("name", [
    pytest.param(name) for name in BAD_INPUTS])
def test_bad_input_one_error_exit_2_nothing_written(name, bad_runs):
    nranks, _, wanted = BAD_INPUTS[name]
    if name not in bad_runs:
        pytest.skip("mpiexec not found")
    proc, before, after = bad_runs[name]
    assert proc.returncode == 2, show(proc)
    assert "Traceback" not in proc.stderr, show(proc)
    lines = error_lines(proc.stderr)
    assert len(lines) == 1, show(proc)  # once, also under MPI
    for text in wanted:
        assert text in lines[0], f"{text!r} not in {lines[0]!r}"
    assert error_lines(proc.stdout) == [] and proc.stdout.strip() == "", show(proc)
    assert after == before, "bad input must write nothing"


# --------------------------------------------------------------------------- a good run

@pytest.fixture(scope="module")
def bar_run(tmp_path_factory):
    directory = tmp_path_factory.mktemp("bar")
    write_yaml(directory / "bar.yaml", bar(directory="bar_out"))
    proc = run_pimpm(None, ["bar.yaml"], cwd=directory, timeout=120)
    return proc, directory / "bar_out"


def test_run_writes_results(bar_run):
    proc, out = bar_run
    assert proc.returncode == 0, show(proc)
    assert "Traceback" not in proc.stderr and error_lines(proc.stderr) == []
    assert sorted(os.listdir(out)) == sorted(OUTPUT_FILES)
    assert h5_steps(out / "results.h5") == list(range(11))
    for xdmf in ("particles.xdmf", "grid.xdmf"):
        text = (out / xdmf).read_text()
        assert len(re.findall(r"<Time Value=", text)) == 11, xdmf
        assert "results.h5:/steps/000010/" in text


def test_history_has_one_row_per_step(bar_run):
    proc, out = bar_run
    header, rows = read_history(out / "history.csv")
    # the documented columns, in this order (others may come in between)
    wanted = HISTORY_COLUMNS + ["puller_force_x", "puller_force_y", "particle_imbalance", "wall_time"]
    assert [c for c in header if c in wanted] == wanted, header
    assert header[-1] == "wall_time" and len(set(header)) == len(header)
    assert [int(r[0]) for r in rows] == list(range(1, 11))
    assert all(len(r) == len(header) for r in rows)
    col = {name: [float(r[i]) for r in rows] for i, name in enumerate(header)}
    assert col["time"][-1] == pytest.approx(10.34)
    assert sum(col["dt"]) == pytest.approx(10.34)
    assert col["newton_iterations"][0] >= 1
    assert all(f < 0 for f in col["puller_force_x"])  # the bar pulls back
    # energy balance of the elastic bar pulled from rest: the puller's work
    # (its force, trapezoidal in time, times its velocity) is the energy stored
    total = np.array(col["kinetic_energy"]) + np.array(col["strain_energy"])
    np.testing.assert_allclose(col["total_energy"], total, rtol=1e-12)
    assert col["external_work"][-1] > 0
    np.testing.assert_allclose(col["external_work"], total, rtol=0.01)
    assert all(e > 0 for e in col["strain_energy"])


def test_progress_line_per_step(bar_run):
    proc, out = bar_run
    pattern = re.compile(
        r"^step\s+(\d+)\s+t\s+(\S+)\s+dt\s+(\S+)\s+newton\s+(\d+)\s+linear\s+(\d+)\s+"
        r"\|R\|\s+(\S+) -> (\S+)\s+puller F=\((\S+), (\S+)\)\s+wall\s+(\S+) s(\s.*)?$")
    lines = [line for line in proc.stdout.splitlines() if line.startswith("step ")]
    assert len(lines) == 10, proc.stdout
    header, rows = read_history(out / "history.csv")
    for line, row in zip(lines, rows):
        m = pattern.match(line)
        assert m, line
        value = dict(zip(header, row))
        assert int(m[1]) == int(value["step"])
        assert float(m[2]) == pytest.approx(float(value["time"]), rel=1e-5)
        assert float(m[3]) == pytest.approx(float(value["dt"]), rel=1e-3)
        assert int(m[4]) == int(value["newton_iterations"])
        assert int(m[5]) == int(value["linear_iterations"])
        assert float(m[8]) == pytest.approx(float(value["puller_force_x"]), rel=1e-3)


# --------------------------------------------------------------------------- results are protected

def test_existing_results_are_not_overwritten(tmp_path):
    write_yaml(tmp_path / "bar.yaml", bar(directory="bar_out"))
    first = run_pimpm(None, ["bar.yaml"], cwd=tmp_path, timeout=120)
    assert first.returncode == 0, show(first)
    before = snapshot(tmp_path / "bar_out")

    again = run_pimpm(None, ["bar.yaml"], cwd=tmp_path, timeout=120)
    assert again.returncode == 2, show(again)
    assert "Traceback" not in again.stderr
    lines = error_lines(again.stderr)
    assert len(lines) == 1, show(again)
    assert "bar_out" in lines[0] and "--overwrite" in lines[0], lines[0]
    assert not re.search(r"^step\s", again.stdout, re.M), "it must not run"
    assert snapshot(tmp_path / "bar_out") == before, "results were modified"

    forced = run_pimpm(None, ["bar.yaml", "--overwrite"], cwd=tmp_path, timeout=120)
    assert forced.returncode == 0, show(forced)
    assert os.stat(tmp_path / "bar_out" / "results.h5").st_mtime_ns != \
        before["results.h5"][0]
    assert h5_steps(tmp_path / "bar_out" / "results.h5") == list(range(11))
    _, rows = read_history(tmp_path / "bar_out" / "history.csv")
    assert len(rows) == 10  # replaced, not appended


def test_output_and_set_on_the_command_line(tmp_path):
    """--output DIR and --set KEY=VALUE change the run as if the file said so;
    the file's own output directory is left alone."""
    write_yaml(tmp_path / "bar.yaml", bar(directory="bar_out"))
    proc = run_pimpm(2 if MPIEXEC else None,
                     ["bar.yaml", "--output", "elsewhere", "--set", "time.end_time=1.034",
                      "--set", "bodies[0].particles_per_cell=[3, 1]"], cwd=tmp_path, timeout=120)
    assert proc.returncode == 0, show(proc)
    assert not (tmp_path / "bar_out").exists()
    out = tmp_path / "elsewhere"
    assert h5_steps(out / "results.h5") == [0, 1]
    with h5py.File(out / "results.h5") as f:
        body = f["steps/000000/particles/body"][...]
    # the bar's 3 x 3 cells get 3 x 1 particles each instead of 2 x 2; the puller keeps 12
    assert (body == 0).sum() == 27 and (body == 1).sum() == 12


# --------------------------------------------------------------------------- PETSc options

def solver_types(stdout):
    """(ksp type, pc type) of the KSP that solves, from -snes_view output
    (inside pimpm's python KSP, when there is one: the direct solver on the
    free dofs, the fallback's iterative solver)."""
    ksps = [m for m in re.finditer(r"KSP Object:.*\n\s+type: (\S+)", stdout) if m[1] != "python"]
    assert ksps, stdout
    pc = re.compile(r"PC Object:.*\n\s+type: (\S+)").search(stdout, ksps[0].end())
    assert pc, stdout
    return ksps[0][1], pc[1]


@pytest.fixture(scope="module")
def option_runs(tmp_path_factory):
    """One-step bars: defaults, YAML solver.petsc, YAML + command line."""
    directory = str(tmp_path_factory.mktemp("options"))
    write_yaml(os.path.join(directory, "plain.yaml"), bar("plain_out", end_time=1.034))
    write_yaml(os.path.join(directory, "cg.yaml"),
               bar("cg_out", end_time=1.034, petsc={"ksp_type": "cg", "pc_type": "jacobi",
                                                    "ksp_rtol": 1e-12}))
    write_yaml(os.path.join(directory, "cli.yaml"),
               bar("cli_out", end_time=1.034, petsc={"ksp_type": "cg", "pc_type": "jacobi",
                                                     "ksp_rtol": 1e-12}))
    return run_together({
        "monitor": (None, ["plain.yaml", "-snes_monitor"], directory),
        "yaml": (None, ["cg.yaml", "-snes_view"], directory),
        "cli": (None, ["cli.yaml", "-snes_view", "-ksp_type", "preonly", "-pc_type", "lu"],
                directory),
    })


def test_command_line_option_reaches_petsc(option_runs, bar_run):
    proc = option_runs["monitor"]
    assert proc.returncode == 0, show(proc)
    assert "SNES Function norm" in proc.stdout
    assert "SNES Function norm" not in bar_run[0].stdout  # not there without the option


def test_yaml_petsc_options_are_used(option_runs):
    proc = option_runs["yaml"]
    assert proc.returncode == 0, show(proc)
    assert solver_types(proc.stdout) == ("cg", "jacobi")


def test_command_line_overrides_yaml(option_runs):
    proc = option_runs["cli"]
    assert proc.returncode == 0, show(proc)
    assert solver_types(proc.stdout) == ("preonly", "lu")


# --------------------------------------------------------------------------- numerical failure

def fly_away(every):
    """A free block moving at 0.1 per step towards x = 1 (Newmark, no forces):
    fine for 7 steps, then its particles would leave the grid, even after step cuts."""
    return {
        "grid": {"lower": [0.0, 0.0], "upper": [1.0, 1.0], "cells": [10, 10]},
        "materials": {"m": {"model": "neo_hookean", "youngs_modulus": 1000.0,
                            "poisson_ratio": 0.3, "density": 10.0}},
        "bodies": [{"name": "block", "material": "m", "velocity": [0.1, 0.0],
                    "geometry": {"type": "box", "lower": [0.1, 0.1], "upper": [0.3, 0.3]}}],
        "time": {"integrator": "newmark", "dt": 1.0, "end_time": 20.0},
        "output": {"directory": "fly_out", "every": every},
    }


@pytest.fixture(scope="module")
def failed_runs(tmp_path_factory):
    newton = str(tmp_path_factory.mktemp("newton"))
    write_yaml(os.path.join(newton, "bar.yaml"), bar(directory="bar_out", petsc={
        "snes_max_it": 1, "snes_rtol": 1e-30, "snes_atol": 1e-300, "snes_stol": 1e-300}))
    fly = str(tmp_path_factory.mktemp("fly"))
    write_yaml(os.path.join(fly, "fly.yaml"), fly_away(every=3))
    procs = run_together({"newton": (None, ["bar.yaml"], newton),
                          "fly": (None, ["fly.yaml"], fly)})
    return {"newton": (procs["newton"], os.path.join(newton, "bar_out")),
            "fly": (procs["fly"], os.path.join(fly, "fly_out"))}


def test_newton_failure_exits_1_and_keeps_results(failed_runs):
    proc, out = failed_runs["newton"]
    assert proc.returncode == 1, show(proc)
    assert "Traceback" not in proc.stderr, show(proc)
    lines = error_lines(proc.stdout + proc.stderr)
    assert len(lines) == 1, show(proc)
    assert "Newton did not converge" in lines[0] and "bar_out" in lines[0], lines[0]
    # the results of the good steps, and a checkpoint of the last one to continue from
    assert sorted(os.listdir(out)) == sorted(OUTPUT_FILES + ("checkpoint.h5", "checkpoint.sha256"))
    assert h5_steps(os.path.join(out, "results.h5")) == [0]  # the initial state only
    header, rows = read_history(os.path.join(out, "history.csv"))
    assert header[0] == "step" and rows == []
    assert "/steps/000001/" not in open(os.path.join(out, "particles.xdmf")).read()


def test_numerical_failure_message_is_on_stderr(failed_runs):
    proc, _ = failed_runs["newton"]
    lines = error_lines(proc.stderr)
    assert len(lines) == 1 and "Newton did not converge" in lines[0], show(proc)


def last_good_step(proc):
    m = re.search(r"Results up to step (\d+)", proc.stdout + proc.stderr)
    assert m, show(proc)
    return int(m[1])


def test_failure_after_good_steps_keeps_nothing_beyond_them(failed_runs):
    proc, out = failed_runs["fly"]
    assert proc.returncode == 1, show(proc)
    assert "Traceback" not in proc.stderr, show(proc)
    lines = error_lines(proc.stdout + proc.stderr)
    assert len(lines) == 1 and "leave the grid" in lines[0], show(proc)
    good = last_good_step(proc)
    assert good >= 7, show(proc)
    _, rows = read_history(os.path.join(out, "history.csv"))
    assert [int(r[0]) for r in rows] == list(range(1, good + 1))
    steps = h5_steps(os.path.join(out, "results.h5"))
    assert steps[0] == 0 and max(steps) <= good
    assert all(s % 3 == 0 for s in steps if s != good), steps  # every: 3


def test_failure_writes_the_last_good_step(failed_runs):
    """With output.every 3 the last good step (not a multiple of 3) is written
    too: 'results up to the last good step are kept'."""
    proc, out = failed_runs["fly"]
    good = last_good_step(proc)
    assert good % 3 != 0, "the scenario should fail between two output steps"
    assert good in h5_steps(os.path.join(out, "results.h5"))
    assert f"/steps/{good:06d}/" in open(os.path.join(out, "particles.xdmf")).read()


def test_body_without_particles_is_bad_input(tmp_path):
    """A body that holds no sub-cell centre would silently vanish. (A box
    smaller than a sub-cell gets one particle with its volume.)"""
    with open(BAR) as f:
        raw = yaml.safe_load(f)
    raw["bodies"][0]["geometry"] = {"type": "ball", "center": [0.41, 0.005], "radius": 0.002}
    raw["output"] = {"directory": "tiny_out"}
    write_yaml(tmp_path / "tiny.yaml", raw)
    proc = run_pimpm(None, ["tiny.yaml"], cwd=tmp_path)
    assert proc.returncode == 2
    lines = [l for l in proc.stderr.splitlines() if l.strip()]
    assert len(lines) == 1 and lines[0].startswith("pimpm: error: bodies[0].geometry")
    assert "'bar' gets no particles" in lines[0] and "Traceback" not in proc.stderr
    assert not (tmp_path / "tiny_out").exists()
