#!/usr/bin/env python3
"""The 3D upsetting (inputs/upsetting_3d.yaml, the quarter cylinder of Sulsky
& Kaul 3.2.7) at several cell sizes: whole runs under `mpiexec -n RANKS`,
one step moving the platen half a cell (dt = 1e-3 h / 2 mm, as the 2 mm
input does), to --reduction of the height (default 60%).

Variants (any subset, --variants): `default` (the program's 3D defaults),
`per-iteration` (a factorization at every Newton iteration and the plain
predictor: -pimpm_reuse_factorization false -pimpm_linear_predictor false),
`gmres-gamg` (-pimpm_preset gmres-gamg -pimpm_fallback false), `gmres-hypre`
(likewise with BoomerAMG),
`baseline` (`--baseline REV` run from its own git worktree with
-pimpm_preset gmres-gamg -pimpm_fallback false, the set-up issue 31 measured)
and `baseline-default` (that worktree with its own defaults: a change side by
side with its parent); a worktree's kernels compile in a first, untimed run. Rounds alternate
the variants; each cell is the median of --repeats.

Prints a table (steps, step cuts, Newton iterations per step, Krylov
iterations per Newton iteration (median over steps), the first 10 steps'
wall time (the history's per-step times), the whole process's wall time,
peak resident memory of the largest rank, particles; with --log-view each
-log_view stage's share of the run, of its first repeat) and writes JSON.
--max-steps stops a run by its end time after about that many steps
(end time = N dt) for runs too slow to finish.

    python scripts/bench_3d.py [--sizes 2 1 0.5] [--ranks 2] [--repeats 1]
        [--variants default per-iteration] [--baseline 89dbf38] [--max-steps N]
        [--contact bonded|tied] [--log-view] [--json docs/data/bench_3d.json]
"""
import argparse
import csv
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time

import h5py
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from pimpm_runs import mpi_env  # noqa: E402
from worktrees import worktree  # noqa: E402

INPUT = "inputs/upsetting_3d.yaml"
HALF_HEIGHT = 15.0                 # mm
OPTIONS = {"default": [],
           "per-iteration": ["-pimpm_reuse_factorization", "false", "-pimpm_linear_predictor", "false"],
           "gmres-gamg": ["-pimpm_preset", "gmres-gamg", "-pimpm_fallback", "false"],
           "gmres-hypre": ["-pimpm_preset", "gmres-hypre", "-pimpm_fallback", "false"],
           "baseline": ["-pimpm_preset", "gmres-gamg", "-pimpm_fallback", "false"],
           "baseline-default": []}


def stage_shares(stdout):
    """Each -log_view stage's share of the run in percent (its time on the
    slowest rank against the run's), from the "Summary of Stages" table,
    whose rows read " 3:           Solve: 5.5904e+00  43.0% ...": {name:
    percent}; empty without -log_view."""
    table = stdout.partition("Summary of Stages")[2]
    rows = re.findall(r"^\s*\d+:\s+(.+?):\s+\S+\s+([0-9.]+)%", table, flags=re.MULTILINE)
    return {name: float(percent) for name, percent in rows}


def run(tree, options, size, ranks, end_time, out):
    """One whole run; its history and what the process cost."""
    cells = [round(24 / size), round(24 / size), round(18 / size)]
    dt = 1.0e-3 * size / 2.0
    cmd = ["/usr/bin/time", "-f", "PEAK_KB %M", "mpiexec", "-n", str(ranks), sys.executable, "-m", "pimpm",
           os.path.join(tree, INPUT), "--output", out, "--overwrite",
           "--set", f"grid.cells=[{cells[0]},{cells[1]},{cells[2]}]", "--set", f"time.dt={dt!r}",
           "--set", f"time.end_time={end_time!r}"] + options
    start = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=mpi_env(tree), cwd=tree)
    wall = time.perf_counter() - start
    with open(os.path.join(out, "history.csv")) as f:
        rows = list(csv.DictReader(f))
    peak = [int(line.split()[1]) for line in proc.stderr.splitlines() if line.startswith("PEAK_KB")]
    particles = [line for line in proc.stdout.splitlines() if "body      cylinder:" in line]
    newton = [int(r["newton_iterations"]) for r in rows]
    krylov = [int(r["linear_iterations"]) / max(1, int(r["newton_iterations"])) for r in rows]
    errors = [line for line in proc.stderr.splitlines() if line.startswith("pimpm: error")]
    radius, trend = shape_at_end(out, rows, size)
    return {"completed": proc.returncode == 0, "error": errors[-1] if errors else "", "wall": wall,
            "steps": len(rows),
            "reached": float(rows[-1]["time"]) / end_time if rows else 0.0,
            "cuts": sum(int(r["step_cuts"]) for r in rows),
            "newton_per_step": statistics.mean(newton) if rows else 0.0,
            "newton_step1": newton[0] if rows else 0,
            "krylov_per_newton_median": statistics.median(krylov) if rows else 0.0,
            "first10_wall": sum(float(r["wall_time"]) for r in rows[:10]),
            "peak_rss_mb": peak[0] / 1024.0 if peak else None,
            "particles": particles[0].split(":")[1].split("particles")[0].strip() if particles else "",
            "force_kN": -float(rows[-1]["platen_force_z"]) * 4 / 1000.0 if rows else None,
            "force_trend_kN": trend, "radius_mid_height_mm": radius,
            "stage_shares_percent": stage_shares(proc.stdout)}


def shape_at_end(out, rows, size):
    """The radius at mid-height of the last step written (the largest
    radius of the cylinder's particles within two cells of the mid-plane z =
    0, as pimpm.measures.midplane_radius in axisymmetry), and the load's
    trend at the last step's reduction: a quadratic through the whole-model
    loads from 30% reduction on (scripts/upsetting_validation.py's; single
    steps scatter about it with the grid reset). None where not defined."""
    radius = trend = None
    try:
        with h5py.File(os.path.join(out, "results.h5"), "r") as f:
            last = f["steps"][sorted(f["steps"])[-1]]["particles"]
            x, body = last["position"][...], last["body"][...]
        band = (body == 0) & (x[:, 2] < 2.0 * size)
        radius = float(np.hypot(x[band, 0], x[band, 1]).max()) if band.any() else None
    except (OSError, KeyError):
        pass
    reduction = np.array([float(r["time"]) for r in rows]) * 1000.0 / HALF_HEIGHT
    force = np.array([-float(r["platen_force_z"]) * 4 / 1000.0 for r in rows])
    late = reduction >= 0.3 - 1e-9
    if late.sum() >= 3:
        trend = float(np.polyval(np.polyfit(reduction[late], force[late], 2), reduction[-1]))
    return radius, trend


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=float, nargs="+", default=[2.0, 1.0, 0.5])
    ap.add_argument("--ranks", type=int, nargs="+", default=[2])
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--reduction", type=float, default=0.6)
    ap.add_argument("--variants", nargs="+", default=["default", "per-iteration"], choices=list(OPTIONS))
    ap.add_argument("--baseline", default="89dbf38", help="the commit the `baseline` variants run")
    ap.add_argument("--max-steps", type=int, default=None)
    ap.add_argument("--contact", default=None, choices=["bonded", "tied"],
                    help="the platen's contact law in this tree's runs (default: the input's, tied; "
                         "the baseline runs its own input)")
    ap.add_argument("--log-view", action="store_true",
                    help="run with -log_view and report each stage's share of the run")
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    contact = [] if args.contact is None else ["--set", f"bodies[1].contact={args.contact}"]
    from_baseline = {v for v in args.variants if v.startswith("baseline")}      # run from --baseline's worktree
    trees = {v: (worktree(args.baseline) if v in from_baseline else ROOT) for v in args.variants}
    results = []
    with tempfile.TemporaryDirectory() as scratch:
        for tree in set(trees.values()):          # compile the kernels once, untimed
            run(tree, [], 2.0, 1, 1.0e-3, os.path.join(scratch, "warm"))
        for size in args.sizes:
            end_time = args.reduction * HALF_HEIGHT * 1.0e-3          # the platen moves 1 mm per ms
            if args.max_steps:
                end_time = min(end_time, args.max_steps * 1.0e-3 * size / 2.0)
            for ranks in args.ranks:
                runs = {v: [] for v in args.variants}
                for _ in range(args.repeats):
                    for v in args.variants:
                        out = os.path.join(scratch, v)
                        extra = (contact if v not in from_baseline else []) + (["-log_view"] if args.log_view else [])
                        runs[v].append(run(trees[v], extra + OPTIONS[v], size, ranks, end_time, out))
                for v in args.variants:
                    median = {k: (statistics.median([r[k] for r in runs[v]])
                                  if isinstance(runs[v][0][k], float) and all(r[k] is not None for r in runs[v])
                                  else runs[v][0][k]) for k in runs[v][0]}
                    results.append(dict(size_mm=size, ranks=ranks, variant=v, end_time=end_time,
                                        tree=args.baseline if v in from_baseline else "working tree",
                                        **median))
                    r = results[-1]
                    print(f"{size:5.2f} mm  {ranks} ranks  {v:16s} {'done' if r['completed'] else 'FAILED':6s} "
                          f"steps {r['steps']:3d} ({100 * r['reached']:.0f}% of the way)  cuts {r['cuts']}  "
                          f"newton/step {r['newton_per_step']:.1f} (step 1: {r['newton_step1']})  "
                          f"krylov/newton {r['krylov_per_newton_median']:.1f}  first 10 steps "
                          f"{r['first10_wall']:.1f} s  whole {r['wall']:.1f} s  peak {r['peak_rss_mb'] or 0:.0f} MB  "
                          f"particles {r['particles']}  force {r['force_kN'] or 0:.1f} kN (trend "
                          f"{r['force_trend_kN'] or 0:.1f})  radius at mid-height "
                          f"{r['radius_mid_height_mm'] or 0:.2f} mm", flush=True)
                    if r["stage_shares_percent"]:
                        print("      stages: " + ", ".join(f"{k} {p:.1f}%" for k, p in r["stage_shares_percent"].items()),
                              flush=True)
                    if r["error"]:
                        print("      " + r["error"], flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"command": " ".join(sys.argv), "results": results}, f, indent=1)


if __name__ == "__main__":
    main()
