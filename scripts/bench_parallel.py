#!/usr/bin/env python3
"""Whole runs, this tree against a baseline commit, side by side.

Cases (each a whole run to its end time, output only at the start and the end):

* ``billet-linear``, ``billet-gimp``: inputs/billet.yaml (25,600 particles,
  40 quasi-static steps, MUMPS) with grid.shape_functions set to linear and
  to gimp; run by both trees;
* ``billet-quarter``: the same billet at 0.25 cm cells (102,400 particles,
  GIMP, the platen moving half a cell per step: 80 steps);
  ``billet-quarter-linear``: the same with linear shape functions;
* ``billet-explicit``: inputs/billet_explicit.yaml, the dynamic billet with
  explicit MPM to t = 0.2 (2231 steps at the CFL step);
* ``block-3d``: the 3D block of scripts/bench_solvers.py at 32 cells per axis
  (79,507 particles, 107,811 unknowns, 4 quasi-static steps) with the
  gmres-gamg preset (MUMPS factorizes it in minutes; see PERFORMANCE.md).

For each case and number of ranks the trees run in turn, alternating,
``--repeats`` times; the table gives medians of the whole-process wall time,
the stage times of PETSc's -log_view, Newton and linear iterations, the
largest particle imbalance over the steps, the peak resident memory summed
over the ranks (-memory_view), and the answer (platen force; the billet's
bulge). The baseline runs from a git worktree of ``--baseline`` (created if
missing), with its own inputs. Then the start-up: a one-step billet run with
an empty kernel cache (cold: numba compiles) and again (warm). Writes JSON.

    python scripts/bench_parallel.py [--baseline b88024b] [--repeats 3]
        [--cases billet-linear billet-gimp billet-quarter [billet-quarter-linear] block-3d]
        [--baseline-cases billet-linear billet-gimp] [--ranks 1 2]
        [--imbalance-ranks 3] [--json docs/data/bench_parallel.json]
"""
import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

import h5py
import numpy as np
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "scripts"))
sys.path.insert(0, ROOT)
from bench_solvers import block3d, parse_log  # noqa: E402
from worktrees import worktree  # noqa: E402
from pimpm.measures import bulge_from_fields, edge_particle_id  # noqa: E402

STAGES = ("P2G", "Solve", "Constitutive update", "Assembly", "G2P", "Migration", "Output")
CASES = ("billet-linear", "billet-gimp", "billet-quarter", "billet-quarter-linear", "block-3d", "billet-explicit")


def case_input(tree, case):
    """The input of ``case`` as ``tree`` ships it, and extra command-line options."""
    if case == "block-3d":
        return block3d(2, 4, "linear"), ["-pimpm_preset", "gmres-gamg"]
    if case == "billet-explicit":              # the whole explicit run, t = 0.2
        with open(os.path.join(tree, "inputs", "billet_explicit.yaml")) as f:
            config = yaml.safe_load(f)
        config["output"] = {"directory": "out", "every": 100000}
        return config, []
    with open(os.path.join(tree, "inputs", "billet.yaml")) as f:
        config = yaml.safe_load(f)
    config["grid"]["shape_functions"] = "linear" if case.endswith("-linear") else "gimp"
    if case.startswith("billet-quarter"):        # 0.25 cm cells, half a cell per step
        config["grid"]["cells"] = [2 * n for n in config["grid"]["cells"]]
        config["bodies"][1]["geometry"]["upper"][1] = 20.25
        config["time"]["dt"] = 0.5 * config["time"]["dt"]
    config["output"] = {"directory": "out", "every": 1000}
    return config, []


def read_answer(out, billet=True):
    """Platen force and, for the billet, the bulge, from the run's output."""
    history = np.genfromtxt(os.path.join(out, "history.csv"), delimiter=",", names=True)
    force_column = [n for n in history.dtype.names if n.endswith("force_y") or n.endswith("force_z")][-1]
    answer = {"force": float(history[force_column][-1]),
              "newton": int(history["newton_iterations"].sum()),
              "linear": int(history["linear_iterations"].sum()),
              "steps": int(len(history)),
              "fallbacks": int(history["linear_fallbacks"].sum()),
              "imbalance": (float(np.max(history["particle_imbalance"]))
                            if "particle_imbalance" in history.dtype.names else None)}
    with h5py.File(os.path.join(out, "results.h5"), "r") as f:
        steps = sorted(f["steps"], key=lambda s: int(f["steps"][s].attrs["step"]))
        first, last = f["steps"][steps[0]]["particles"], f["steps"][steps[-1]]["particles"]
        if billet and "body" in first:         # positions have 3 components for ParaView also in 2D
            edge = edge_particle_id(first["id"][...], first["position"][...], first["body"][...])
            answer["bulge"] = bulge_from_fields(last["id"][...], last["displacement"][...], edge)
        if answer["imbalance"] is None and "counts_per_rank" in first.attrs:
            counts = np.asarray(first.attrs["counts_per_rank"], dtype=float)
            answer["imbalance"] = float(counts.max() / counts.mean())   # baseline: first step only
    return answer


def run(tree, case, ranks, workdir, extra_env=None, extra_options=()):
    config, options = case_input(tree, case)
    options = options + list(extra_options)
    path = os.path.join(workdir, "case.yaml")
    with open(path, "w") as f:
        yaml.safe_dump(config, f)
    env = dict(os.environ, PYTHONPATH=tree, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               **(extra_env or {}))
    cmd = ["mpiexec", "-n", str(ranks)] + (["--oversubscribe"] if ranks > 2 else []) + [
        sys.executable, "-m", "pimpm", path, "--overwrite", "-log_view", "-memory_view"] + options
    start = time.perf_counter()
    proc = subprocess.run(cmd, cwd=workdir, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        return {"ok": False, "error": (proc.stdout + proc.stderr)[-800:]}
    stages, memory = parse_log(proc.stdout)
    result = {"ok": True, "wall_s": wall, "peak_memory_mb": memory / 2**20 if memory else None,
              **{stage: stages.get(stage) for stage in STAGES}}
    result.update(read_answer(os.path.join(workdir, "out"), billet=case.startswith("billet")))
    return result


def start_up(tree):
    """Wall time of a one-step billet run with an empty kernel cache, then warm."""
    config, _ = case_input(tree, "billet-gimp")
    config["time"]["end_time"] = config["time"]["dt"]
    out = {}
    with tempfile.TemporaryDirectory() as workdir:
        with open(os.path.join(workdir, "case.yaml"), "w") as f:
            yaml.safe_dump(config, f)
        cache = os.path.join(workdir, "numba-cache")
        env = dict(os.environ, PYTHONPATH=tree, NUMBA_CACHE_DIR=cache)
        for label in ("cold", "warm"):
            start = time.perf_counter()
            subprocess.run([sys.executable, "-m", "pimpm", "case.yaml", "--overwrite"], cwd=workdir,
                           env=env, capture_output=True, check=True)
            out[label + "_s"] = time.perf_counter() - start
        shutil.rmtree(cache, ignore_errors=True)
    return out


def median_row(results):
    good = [r for r in results if r["ok"]]
    row = {"failed": len(results) - len(good)}
    if not good:
        row["error"] = results[0]["error"]
        return row
    for key, value in good[0].items():
        if key == "ok":
            continue
        values = [r[key] for r in good if r.get(key) is not None]
        row[key] = float(np.median(values)) if values else None
    return row


def share(x):
    return ((x.get("Constitutive update") or 0.0) + (x.get("Assembly") or 0.0)) / x["wall_s"]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--baseline", default="b88024b")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--cases", nargs="+", choices=CASES,
                    default=["billet-linear", "billet-gimp", "billet-quarter", "block-3d"])
    ap.add_argument("--baseline-cases", nargs="*", default=["billet-linear", "billet-gimp"], choices=CASES)
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--imbalance-ranks", type=int, nargs="*", default=[3],
                    help="extra rank counts run once (current tree) for billet-quarter's imbalance")
    ap.add_argument("--json", default=os.path.join(ROOT, "docs", "data", "bench_parallel.json"))
    ap.add_argument("--current", default=None,
                    help="a commit to measure instead of this working tree (from its own worktree)")
    ap.add_argument("--no-start-up", action="store_true", help="skip the cold/warm start-up runs")
    ap.add_argument("--current-options", default="",
                    help="command-line options for the current tree's runs only, e.g. "
                         "--current-options='-pimpm_weak_node_fraction 0' (a method the baseline lacks)")
    args = ap.parse_args()
    trees = {"baseline": worktree(args.baseline), "current": worktree(args.current) if args.current else ROOT}
    rows = []
    for case in args.cases:
        names = ["baseline", "current"] if case in args.baseline_cases else ["current"]
        for ranks in args.ranks:
            runs = {name: [] for name in names}
            for _ in range(args.repeats):
                for name in names:                      # alternating
                    with tempfile.TemporaryDirectory() as workdir:
                        extra = args.current_options.split() if name == "current" else ()
                        runs[name].append(run(trees[name], case, ranks, workdir, extra_options=extra))
            row = {"case": case, "ranks": ranks, **{name: median_row(r) for name, r in runs.items()}}
            if "baseline" in row and "wall_s" in row["baseline"] and "wall_s" in row["current"]:
                row["ratio"] = row["current"]["wall_s"] / row["baseline"]["wall_s"]
                row["force_difference"] = abs(row["current"]["force"] / row["baseline"]["force"] - 1.0)
                if row["current"].get("bulge") is not None:
                    row["bulge_difference"] = abs(row["current"]["bulge"] / row["baseline"]["bulge"] - 1.0)
            rows.append(row)
            print(json.dumps(row), flush=True)
        if case == "billet-quarter":
            for ranks in args.imbalance_ranks:
                with tempfile.TemporaryDirectory() as workdir:
                    result = run(trees["current"], case, ranks, workdir)
                rows.append({"case": case, "ranks": ranks, "current": median_row([result]), "once": True})
                print(json.dumps(rows[-1]), flush=True)
    startup = {} if args.no_start_up else start_up(trees["current"])
    print(json.dumps({"start_up": startup}), flush=True)

    print(f"\n| case | ranks | baseline {args.baseline} (s) | current (s) | current / baseline "
          "| Newton its (baseline, current) | linear its (current) | largest particle imbalance "
          "| constitutive + assembly share (baseline, current) | peak memory, all ranks (MB) "
          "| force, bulge difference |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        c, b = r["current"], r.get("baseline")
        if "wall_s" not in c:
            print(f"| {r['case']} | {r['ranks']} | failed: {c.get('error', '')[:60]!r} |")
            continue
        base = f"{b['wall_s']:.1f}" if b and "wall_s" in b else ""
        ratio = f"{r['ratio']:.2f}" if "ratio" in r else ""
        its = f"{b['newton']:.0f}, {c['newton']:.0f}" if b and "newton" in b else f"{c['newton']:.0f}"
        shares = f"{share(b):.0%}, {share(c):.0%}" if b and "wall_s" in b else f"{share(c):.0%}"
        memory = f"{c['peak_memory_mb']:.0f}" if c.get("peak_memory_mb") else ""
        force = (f"{r['force_difference']:.1e}, {r.get('bulge_difference', float('nan')):.1e}"
                 if "force_difference" in r else "")
        print(f"| {r['case']} | {r['ranks']}{' (once)' if r.get('once') else ''} | {base} | "
              f"{c['wall_s']:.1f} | {ratio} | {its} | {c['linear']:.0f} | {c['imbalance']:.2f} | "
              f"{shares} | {memory} | {force} |")
    if startup:
        print(f"\nstart-up (one-step billet, 1 rank): cold {startup['cold_s']:.1f} s, warm {startup['warm_s']:.1f} s")
    with open(args.json, "w") as f:
        json.dump({"baseline": args.baseline, "repeats": args.repeats,
                   "current_options": args.current_options, "rows": rows,
                   "start_up": startup}, f, indent=1)
    print(f"\nwritten: {args.json}")


if __name__ == "__main__":
    main()
