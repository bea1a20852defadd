#!/usr/bin/env python3
"""Do two trees give the same answers? Runs each shipped input with this
tree and with a baseline commit (a git worktree, made if missing) on the
given numbers of ranks, then compares ``history.csv`` (every column but the
wall time) and every particle and grid field of the last output step of
``results.h5`` (particles matched by their global id). Prints a table of
the largest relative difference per case (``max |a - b| / max |b|`` per
column or field, the largest of them) and writes JSON.

    python scripts/compare_answers.py --baseline 89dbf38 [--current COMMIT] [--ranks 1 2]
        [--cases billet-gimp billet-linear ...] [--baseline-twice] [--json docs/data/answers.json]

A refactoring that must not change the answers shows 0 (bitwise) or
round-off (<= 1e-12); a replaced numerical path shows how far it moves them.
On 2 ranks the direct solver (MUMPS) need not repeat bit for bit, and a
problem whose Newton iterations sit at their limit then takes other steps
from run to run: ``--baseline-twice`` measures that spread.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import h5py
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "scripts"))
from worktrees import worktree  # noqa: E402
PYTHON = os.path.join(ROOT, ".venv", "bin", "python")
if not os.path.exists(PYTHON):
    PYTHON = sys.executable

#: case -> (input file, --set overrides)
CASES = {
    "billet-gimp": ("billet.yaml", []),
    "billet-linear": ("billet.yaml", ["grid.shape_functions=linear"]),
    "billet-dynamic": ("billet_dynamic.yaml", []),
    "upsetting": ("upsetting.yaml", ["grid.shape_functions=linear"]),   # the input's until issue 28
    "upsetting-3d": ("upsetting_3d.yaml", []),
    "billet-explicit": ("billet_explicit.yaml", ["time.end_time=0.02"]),
    "four-disks": ("four_disks.yaml", []),
    "colliding-disks": ("colliding_disks.yaml", []),
}


def run(tree, case, ranks, out):
    """One whole run of ``case`` by the pimpm of ``tree`` (its own inputs) into ``out``."""
    name, sets = CASES[case]
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", PYTHONPATH=tree)
    command = ["mpiexec", "-n", str(ranks), PYTHON, "-m", "pimpm", os.path.join(tree, "inputs", name),
               "--output", out, "--overwrite"]
    for s in sets:
        command += ["--set", s]
    result = subprocess.run(command, cwd=tree, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)
    if result.returncode != 0:
        raise RuntimeError(f"{case} on {ranks} ranks in {tree} failed:\n{result.stdout[-3000:]}")


def relative(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    if a.shape != b.shape:
        return np.inf
    scale = np.max(np.abs(b)) if b.size else 0.0
    diff = np.max(np.abs(a - b)) if b.size else 0.0
    return float(diff / scale) if scale > 0 else float(diff)


def compare_history(a, b):
    ha = np.genfromtxt(os.path.join(a, "history.csv"), delimiter=",", names=True)
    hb = np.genfromtxt(os.path.join(b, "history.csv"), delimiter=",", names=True)
    if ha.dtype.names != hb.dtype.names or len(ha) != len(hb):
        return {"history": np.inf}
    return {f"history.{n}": relative(ha[n], hb[n]) for n in ha.dtype.names if n != "wall_time"}


def last_step(path):
    f = h5py.File(os.path.join(path, "results.h5"), "r")
    return f, f["steps"][sorted(f["steps"])[-1]]


def compare_results(a, b):
    fa, sa = last_step(a)
    fb, sb = last_step(b)
    out = {"results.time": relative(sa.attrs["time"], sb.attrs["time"])}
    order_a = np.argsort(sa["particles/id"][()])
    order_b = np.argsort(sb["particles/id"][()])
    for name in sb["particles"]:
        out[f"particles.{name}"] = relative(sa["particles"][name][()][order_a], sb["particles"][name][()][order_b])
    for name in sb["grid"]:
        out[f"grid.{name}"] = relative(sa["grid"][name][()], sb["grid"][name][()])
    fa.close()
    fb.close()
    return out


def compare(a, b):
    """Relative differences of every history column and last-step field of run ``a`` against ``b``."""
    diffs = compare_history(a, b)
    diffs.update(compare_results(a, b))
    return diffs


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--baseline", required=True)
    parser.add_argument("--current", default=None,
                        help="a commit to compare instead of this working tree (run from its own worktree)")
    parser.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    parser.add_argument("--work", default=os.path.join(tempfile.gettempdir(), "pimpm-compare"))
    parser.add_argument("--baseline-twice", action="store_true",
                        help="also run the baseline a second time and give its difference from itself "
                             "(parallel direct solvers need not repeat bit for bit)")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    base = worktree(args.baseline)
    current = worktree(args.current) if args.current else ROOT
    results = {}
    print(f"{'case':18s} {'ranks':>5s} {'largest difference':>20s}  where")
    for case in args.cases:
        for ranks in args.ranks:
            outs = {}
            for label, tree in (("current", current), ("baseline", base)):
                outs[label] = os.path.join(args.work, f"{case}-{ranks}-{label}")
                run(tree, case, ranks, outs[label])
            diffs = compare(outs["current"], outs["baseline"])
            worst = max(diffs, key=diffs.get)
            results[f"{case}/{ranks}"] = {"largest": diffs[worst], "where": worst, "all": diffs}
            line = f"{case:18s} {ranks:5d} {diffs[worst]:20.3e}  {worst}"
            if args.baseline_twice:
                again = os.path.join(args.work, f"{case}-{ranks}-baseline-again")
                run(base, case, ranks, again)
                spread = compare(again, outs["baseline"])
                results[f"{case}/{ranks}"]["baseline_spread"] = spread
                line += f"   (baseline against itself: {max(spread.values()):.3e})"
            print(line, flush=True)
    if args.json:
        results = {"baseline": args.baseline, "current": args.current or "working tree", "cases": results}
        os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1, sort_keys=True)


if __name__ == "__main__":
    main()
