#!/usr/bin/env python3
"""Whole runs of the billet, this tree against a baseline commit, side by side.

For each case (inputs/billet.yaml with grid.shape_functions set to linear and
to gimp; 1 and 2 ranks) both trees run in turn, alternating, --repeats times;
the table gives medians of the whole-process wall time, the stage times of
PETSc's -log_view (Constitutive update, Assembly, Solve), Newton iterations
and the largest particle imbalance (history.csv; the baseline has no such
column: computed from the particle ranks of results.h5 at the first step).
The baseline runs from a git worktree (created if missing) with its own
inputs/billet.yaml. Writes JSON.

    python scripts/bench_parallel.py [--baseline b88024b] [--repeats 3]
        [--shapes linear gimp] [--ranks 1 2] [--json docs/bench_parallel.json]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "scripts"))
from bench_solvers import parse_log          # noqa: E402

STAGES = ("Constitutive update", "Assembly", "Solve")


def worktree(commit):
    path = os.path.join(tempfile.gettempdir(), f"pimpm-baseline-{commit}")
    if not os.path.isdir(path):
        subprocess.run(["git", "-C", ROOT, "worktree", "add", "--detach", path, commit], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return path


def run(tree, shape, ranks, workdir):
    with open(os.path.join(tree, "inputs", "billet.yaml")) as f:
        config = yaml.safe_load(f)
    config["grid"]["shape_functions"] = shape
    config["output"] = {"directory": "out", "every": 1000}
    path = os.path.join(workdir, "billet.yaml")
    with open(path, "w") as f:
        yaml.safe_dump(config, f)
    env = dict(os.environ, PYTHONPATH=tree, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    cmd = ["mpiexec", "-n", str(ranks), sys.executable, "-m", "pimpm", path, "--overwrite", "-log_view"]
    start = time.perf_counter()
    proc = subprocess.run(cmd, cwd=workdir, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        return {"ok": False, "error": (proc.stdout + proc.stderr)[-500:]}
    stages, _ = parse_log(proc.stdout)
    history = np.genfromtxt(os.path.join(workdir, "out", "history.csv"), delimiter=",", names=True)
    imbalance = (float(np.max(history["particle_imbalance"]))
                 if "particle_imbalance" in history.dtype.names else None)
    return {"ok": True, "wall_s": wall, "newton": int(history["newton_iterations"].sum()),
            "steps": len(history), "imbalance": imbalance,
            "platen_force_y": float(history["platen_force_y"][-1]),
            **{stage: stages.get(stage) for stage in STAGES}}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--baseline", default="b88024b")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--shapes", nargs="+", default=["linear", "gimp"])
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--json", default=os.path.join(ROOT, "docs", "bench_parallel.json"))
    args = ap.parse_args()
    trees = {"baseline": worktree(args.baseline), "current": ROOT}
    rows = []
    for shape in args.shapes:
        for ranks in args.ranks:
            runs = {name: [] for name in trees}
            for _ in range(args.repeats):
                for name, tree in trees.items():          # alternating
                    with tempfile.TemporaryDirectory() as workdir:
                        runs[name].append(run(tree, shape, ranks, workdir))
            row = {"shape": shape, "ranks": ranks}
            for name, results in runs.items():
                good = [r for r in results if r["ok"]]
                row[name] = {key: (float(np.median([r[key] for r in good]))
                                   if good and good[0][key] is not None else None)
                             for key in ("wall_s", "newton", "imbalance", "platen_force_y", *STAGES)}
                row[name]["failed"] = len(results) - len(good)
            row["ratio"] = row["current"]["wall_s"] / row["baseline"]["wall_s"]
            rows.append(row)
            print(json.dumps(row), flush=True)
    print(f"\n| shape functions | ranks | baseline {args.baseline} (s) | current (s) | current / baseline "
          "| Newton its (baseline, current) | largest particle imbalance (current) "
          "| constitutive + assembly share (baseline, current) |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        b, c = r["baseline"], r["current"]

        def share(x):
            return ((x["Constitutive update"] or 0) + (x["Assembly"] or 0)) / x["wall_s"]
        print(f"| {r['shape']} | {r['ranks']} | {b['wall_s']:.1f} | {c['wall_s']:.1f} | {r['ratio']:.2f} | "
              f"{b['newton']:.0f}, {c['newton']:.0f} | {c['imbalance'] or float('nan'):.2f} | "
              f"{share(b):.0%}, {share(c):.0%} |")
    with open(args.json, "w") as f:
        json.dump({"baseline": args.baseline, "repeats": args.repeats, "rows": rows}, f, indent=1)
    print(f"\nwritten: {args.json}")


if __name__ == "__main__":
    main()
