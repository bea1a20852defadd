#!/usr/bin/env python3
"""Solver benchmark: every preset on the quasi-static billet (2D) and a 3D
elastic block compression, at three resolutions (the finest >= 1e5
unknowns), on 1 and 2 MPI ranks, all in one run so the ratios mean
something. Prints a table and writes JSON.

    python scripts/bench_solvers.py [--steps 2] [--ranks 1 2] [--presets ...]
                                    [--levels 0 1 2] [--json docs/data/bench_solvers.json]

Each case runs ``mpiexec -n R python -m pimpm case.yaml -pimpm_preset P
-log_view -memory_view`` in a scratch directory and reads history.csv (Newton
and linear iterations, time in steps) and PETSc's log (time per stage,
maximum resident memory).
"""
import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time

import numpy as np
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PRESETS = ("mumps", "cg-gamg", "gmres-gamg", "jfnk", "matrix-free")
TIMEOUT = 900          # seconds per case
# docs/PERFORMANCE.md's solver tables were measured with linear shape functions
# (the default before GIMP); --shape gimp measures today's default
SHAPE_FUNCTIONS = "linear"
STAGES = ("P2G", "Solve", "Constitutive update", "Assembly", "G2P", "Migration", "Output")


def billet(level, steps, shape=SHAPE_FUNCTIONS):
    """G&W 5.1.1 billet, quasi-static; h = 0.5, 0.25, 0.125 cm; 2x2 particles
    per cell; the platen moves half a cell per step."""
    h = 0.5 / 2**level
    nx, ny = int(round(40 / h)), int(round(21 / h))
    return {
        "title": f"billet h={h}",
        "grid": {"lower": [0, 0], "upper": [40.0, 21.0], "cells": [nx, ny],
                 "shape_functions": shape, "boundary": {"xmin": "symmetry", "ymin": "symmetry"}},
        "materials": {"rubber": {"model": "neo_hookean", "shear_modulus": 6.0e6,
                                 "bulk_modulus": 6.0e7, "density": 10.0}},
        "bodies": [
            {"name": "billet", "material": "rubber", "particles_per_cell": 2,
             "geometry": {"type": "box", "lower": [0, 0], "upper": [20.0, 20.0]}},
            {"name": "platen", "rigid": True, "particles_per_cell": 2, "velocity": [0, -h / 2],
             "geometry": {"type": "box", "lower": [0, 20.0], "upper": [39.0, 20.0 + h]}},
        ],
        "time": {"integrator": "quasi_static", "dt": 1.0, "end_time": float(steps)},
        "output": {"directory": "out", "every": 1000},
    }


def block3d(level, steps, shape=SHAPE_FUNCTIONS):
    """3D elastic block (compressible neo-Hookean, E = 1e3, nu = 0.3) on three
    symmetry planes, compressed by a bonded rigid platen; 8, 16, 32 cells per
    axis (the finest: 35 937 nodes, 107 811 unknowns); 2x2x2 particles per cell."""
    n = 8 * 2**level
    h = 1.5 / n
    top = 1.0
    return {
        "title": f"3D block n={n}",
        "grid": {"lower": [0, 0, 0], "upper": [1.5, 1.5, 1.5], "cells": [n, n, n],
                 "shape_functions": shape, "boundary": {"xmin": "symmetry", "ymin": "symmetry", "zmin": "symmetry"}},
        "materials": {"m": {"model": "neo_hookean_compressible", "youngs_modulus": 1000.0,
                            "poisson_ratio": 0.3, "density": 1.0}},
        "bodies": [
            {"name": "block", "material": "m", "particles_per_cell": 2,
             "geometry": {"type": "box", "lower": [0, 0, 0], "upper": [1.0, 1.0, top]}},
            {"name": "platen", "rigid": True, "particles_per_cell": 2, "velocity": [0, 0, -0.02],
             "geometry": {"type": "box", "lower": [0, 0, top], "upper": [1.25, 1.25, top + h]}},
        ],
        "time": {"integrator": "quasi_static", "dt": 1.0, "end_time": float(steps)},
        "output": {"directory": "out", "every": 1000},
    }


def parse_log(text):
    stages = {}
    block = re.search(r"Summary of Stages:.*?\n(.*?)\n\n", text, re.S)
    if block:
        for line in block.group(1).splitlines():
            m = re.match(r"\s*\d+:\s+(.+?):\s+([\d.e+-]+)\s+([\d.]+)%", line)
            if m:
                stages[m.group(1).strip()] = float(m.group(2))
    memory = None
    m = re.search(r"Maximum \(over computational time\) process memory:\s+total\s+([\d.e+]+)\s+max\s+([\d.e+]+)", text)
    if m:
        memory = float(m.group(1))
    return stages, memory


def run_case(problem, level, preset, ranks, steps, workdir, shape=SHAPE_FUNCTIONS):
    config = (billet if problem == "billet-2d" else block3d)(level, steps, shape)
    with open(os.path.join(workdir, "case.yaml"), "w") as f:
        yaml.safe_dump(config, f)
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    cmd = ["mpiexec", "-n", str(ranks), sys.executable, "-m", "pimpm", "case.yaml", "--overwrite",
           "-pimpm_preset", preset, "-log_view", "-memory_view"]
    row = {"problem": problem, "level": level, "preset": preset, "ranks": ranks}
    start = time.perf_counter()
    try:
        proc = subprocess.run(cmd, cwd=workdir, env=env, capture_output=True, text=True,
                              timeout=TIMEOUT)
    except subprocess.TimeoutExpired as exc:
        summary = re.search(r"(\d+) unknowns", exc.stdout.decode() if exc.stdout else "")
        row.update(unknowns=int(summary.group(1)) if summary else None, particles=None, ok=False,
                   error=f"timeout after {TIMEOUT} s", total_wall_s=TIMEOUT)
        return row
    total = time.perf_counter() - start
    summary = re.search(r"(\d+) unknowns", proc.stdout)
    particles = sum(int(n) for n in re.findall(r"body\s+\S+: (\d+) particles \(material", proc.stdout))
    row.update(unknowns=int(summary.group(1)) if summary else None, particles=particles,
               total_wall_s=total, ok=proc.returncode == 0)
    if proc.returncode != 0:
        row["error"] = (proc.stdout + proc.stderr)[-800:]
        return row
    history = np.atleast_1d(np.genfromtxt(os.path.join(workdir, "out", "history.csv"),
                                          delimiter=",", names=True))
    newton = float(history["newton_iterations"].sum())
    stages, memory = parse_log(proc.stdout)
    stage_total = sum(stages.get(s, 0.0) for s in STAGES) + stages.get("Main Stage", 0.0)
    row.update(
        steps=int(len(history)), newton_per_step=newton / len(history),
        linear_per_newton=float(history["linear_iterations"].sum()) / max(newton, 1.0),
        fallbacks=int(history["linear_fallbacks"].sum()), step_cuts=int(history["step_cuts"].sum()),
        step_wall_s=float(history["wall_time"].sum()),
        stage_share={s: stages.get(s, 0.0) / stage_total for s in STAGES if stage_total},
        peak_memory_mb=memory / 2**20 if memory else None,
        bulge_or_force=float(history[[n for n in history.dtype.names if n.endswith("force_y")
                                      or n.endswith("force_z")][-1]][-1]),
    )
    return row


def print_table(rows):
    head = ("| problem | unknowns | particles | preset | ranks | Newton/step | linear/Newton | "
            "time in steps (s) | P2G | constitutive | assembly | solve (rest) | G2P | peak memory, all ranks (MB) |")
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    for r in rows:
        if not r["ok"]:
            why = r.get("error", "failed").split(":")[0] if "error" in r else "failed"
            print(f"| {r['problem']} | {r['unknowns']} | {r['particles']} | {r['preset']} | {r['ranks']} "
                  f"| {why} | | | | | | | | |")
            continue
        sh = r["stage_share"]
        pct = lambda s: f"{100 * sh.get(s, 0):.0f}%"
        # PETSc stages are exclusive: "Solve" is the time in SNES outside the
        # nested "Constitutive update" and "Assembly" stages (linear solves,
        # residual scatters, line search bookkeeping)
        solve_only = sh.get("Solve", 0)
        print(f"| {r['problem']} | {r['unknowns']} | {r['particles']} | {r['preset']} | {r['ranks']} | "
              f"{r['newton_per_step']:.1f} | {r['linear_per_newton']:.1f}"
              f"{' (' + str(r['fallbacks']) + ' fallbacks)' if r['fallbacks'] else ''} | "
              f"{r['step_wall_s']:.2f} | {pct('P2G')} | {pct('Constitutive update')} | {pct('Assembly')} | "
              f"{100 * solve_only:.0f}% | {pct('G2P')} | "
              + (f"{r['peak_memory_mb']:.0f} |" if r["peak_memory_mb"] else "n/a |"))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=2)
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--presets", nargs="+", default=list(PRESETS))
    ap.add_argument("--levels", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--problems", nargs="+", default=["billet-2d", "block-3d"])
    ap.add_argument("--all", action="store_true", help="also run matrix-free at the finest level")
    ap.add_argument("--table", metavar="JSON", help="only print the table of an earlier run")
    ap.add_argument("--json", default=os.path.join(ROOT, "docs", "data", "bench_solvers.json"))
    ap.add_argument("--shape", choices=["linear", "gimp", "bspline"], default=SHAPE_FUNCTIONS,
                    help="grid.shape_functions of every case (default: linear)")
    args = ap.parse_args()
    if args.table:
        with open(args.table) as f:
            print_table(json.load(f))
        return
    rows = []
    for problem in args.problems:
        for level in args.levels:
            for preset in args.presets:
                if preset == "matrix-free" and level >= 2 and not args.all:
                    # GMRES+Jacobi needs ~10^3 iterations per Newton step there:
                    # hours on 2 cores (--all runs it anyway)
                    rows.append({"problem": problem, "level": level, "preset": preset, "ranks": None,
                                 "unknowns": None, "particles": None, "ok": False,
                                 "error": "skipped: too slow (use --all)"})
                    continue
                for ranks in args.ranks:
                    with tempfile.TemporaryDirectory() as workdir:
                        row = run_case(problem, level, preset, ranks, args.steps, workdir, args.shape)
                    rows.append(row)
                    print(json.dumps({k: v for k, v in row.items() if k != "stage_share"}), flush=True)
                    with open(args.json, "w") as f:
                        json.dump(rows, f, indent=1)
    print()
    print_table(rows)


if __name__ == "__main__":
    main()
