#!/usr/bin/env python3
"""What a particle costs in resident memory: the 3D upsetting
(inputs/upsetting_3d.yaml, GIMP) on one grid with 2, 3 and 4 particles per
cell along each axis, whole runs of a few steps under `mpiexec -n RANKS`,
the peak resident set of the largest rank (/usr/bin/time) against the
material particles per rank. The slope of a least-squares line through
them is what a particle adds (its fields, history and the step's kernel
arrays); the intercept is what does not grow with the particles (the
interpreter and libraries, the grid, the matrix and its factors). Issue 31
asks for at most 2 KB a particle.

With --baseline REV the same runs of that commit (its own git worktree,
whose kernels compile in a first, untimed run) alternate with this
tree's; each cell is the median of --repeats.

    python scripts/bench_memory.py [--size 1] [--ppc 2 3 4] [--ranks 1]
        [--end-time 3e-3] [--repeats 2] [--baseline REV] [--json docs/data/bench_memory.json]
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from pimpm_runs import mpi_env  # noqa: E402
from worktrees import worktree  # noqa: E402

INPUT = "inputs/upsetting_3d.yaml"


def run(tree, size, ppc, ranks, end_time):
    """One whole run: (peak resident MiB of the largest rank, material
    particles, steps)."""
    cells = [round(24 / size), round(24 / size), round(18 / size)]
    with tempfile.TemporaryDirectory() as out:
        cmd = ["/usr/bin/time", "-f", "PEAK_KB %M", "mpiexec", "-n", str(ranks), sys.executable, "-m", "pimpm",
               os.path.join(tree, INPUT), "--output", out, "--overwrite",
               "--set", f"grid.cells=[{cells[0]},{cells[1]},{cells[2]}]",
               "--set", f"time.dt={1.0e-3 * size / 2.0!r}", "--set", f"time.end_time={end_time!r}",
               "--set", f"bodies[0].particles_per_cell={ppc}"]
        proc = subprocess.run(cmd, capture_output=True, text=True, env=mpi_env(tree), cwd=tree)
    if proc.returncode != 0:
        raise SystemExit(f"run failed ({' '.join(cmd)}):\n{proc.stderr[-2000:]}")
    peak = [int(line.split()[1]) for line in proc.stderr.splitlines() if line.startswith("PEAK_KB")]
    body = [line for line in proc.stdout.splitlines() if "body      cylinder:" in line][0]
    particles = int(body.split(":")[1].split("particles")[0])
    steps = [line for line in proc.stdout.splitlines() if line.startswith("pimpm: finished")][0].split()[2]
    return peak[0] / 1024.0, particles, int(steps)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=float, default=1.0, help="cell size in mm (default 1)")
    ap.add_argument("--ppc", type=int, nargs="+", default=[2, 3, 4], help="particles per cell along each axis")
    ap.add_argument("--ranks", type=int, default=1)
    ap.add_argument("--end-time", type=float, default=3e-3, help="default 3e-3: six steps at 1 mm")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--baseline", default=None, help="a commit to run side by side (its own worktree)")
    ap.add_argument("--json", default=None)
    args = ap.parse_args()

    trees = {"this tree": ROOT}
    if args.baseline:
        trees[args.baseline] = worktree(args.baseline)
        run(trees[args.baseline], args.size, args.ppc[0], args.ranks, 2 * 1.0e-3 * args.size / 2.0)  # compile
    peaks = {(t, p): [] for t in trees for p in args.ppc}
    counts = {}
    for _ in range(args.repeats):
        for ppc in args.ppc:
            for name, tree in trees.items():
                peak, particles, steps = run(tree, args.size, ppc, args.ranks, args.end_time)
                peaks[name, ppc].append(peak)
                counts[ppc] = (particles, steps)
                print(f"  {name}: {ppc} per cell, {particles} particles, {steps} steps: {peak:.0f} MiB", flush=True)
    results = []
    print(f"\n3D upsetting, {args.size:g} mm cells, {args.ranks} rank(s), to t = {args.end_time:g}; "
          f"peak resident MiB of the largest rank (median of {args.repeats})")
    print("| tree | " + " | ".join(f"{counts[p][0] // args.ranks:,} particles a rank" for p in args.ppc)
          + " | KiB a particle (slope) | MiB without particles (intercept) |")
    print("|---" * (len(args.ppc) + 3) + "|")
    for name in trees:
        per_rank = np.array([counts[p][0] / args.ranks for p in args.ppc])
        median = np.array([statistics.median(peaks[name, p]) for p in args.ppc])
        slope, intercept = np.polyfit(per_rank, median, 1)
        kib = slope * 1024.0
        print(f"| {name} | " + " | ".join(f"{m:.0f}" for m in median) + f" | {kib:.2f} | {intercept:.0f} |")
        results.append({"tree": name, "particles_per_rank": per_rank.tolist(), "peak_mib_median": median.tolist(),
                        "peak_mib_all": [peaks[name, p] for p in args.ppc], "kib_per_particle": kib,
                        "intercept_mib": intercept})
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"command": " ".join(sys.argv), "size_mm": args.size, "ranks": args.ranks,
                       "end_time": args.end_time, "steps": {str(p): counts[p][1] for p in args.ppc},
                       "results": results}, f, indent=1)


if __name__ == "__main__":
    main()
