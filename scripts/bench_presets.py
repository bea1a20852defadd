#!/usr/bin/env python3
"""Every solver preset on the whole 50% billet (inputs/billet.yaml: 25,600
particles, GIMP, 40 quasi-static steps), as a user runs it:
``mpiexec -n R python -m pimpm inputs/billet.yaml -pimpm_preset P -log_view``
with output only at the start and the end. For each preset: whole-process
wall time (median of --repeats, presets alternating), Newton and linear
iterations, direct fallbacks, step cuts, the share of the Solve stage, and
the final platen force against the MUMPS run's.

    python scripts/bench_presets.py [--presets mumps cg-gamg gmres-gamg gmres-hypre jfnk matrix-free]
        [--ranks 2] [--repeats 1] [--json docs/data/bench_presets.json]
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
sys.path.insert(0, os.path.join(ROOT, "tests"))
from bench_solvers import parse_log  # noqa: E402
from helpers import run_pimpm  # noqa: E402

TIMEOUT = 1800


def run(preset, ranks, workdir):
    with open(os.path.join(ROOT, "inputs", "billet.yaml")) as f:
        config = yaml.safe_load(f)
    config["output"] = {"directory": "out", "every": 1000}
    with open(os.path.join(workdir, "case.yaml"), "w") as f:
        yaml.safe_dump(config, f)
    start = time.perf_counter()
    try:
        proc = run_pimpm(ranks, ["case.yaml", "--overwrite", "-pimpm_preset", preset, "-log_view"],
                         timeout=TIMEOUT, cwd=workdir)
    except subprocess.TimeoutExpired:
        return {"preset": preset, "ok": False, "error": f"timeout after {TIMEOUT} s"}
    wall = time.perf_counter() - start
    history = np.atleast_1d(np.genfromtxt(os.path.join(workdir, "out", "history.csv"), delimiter=",", names=True))
    stages, _ = parse_log(proc.stdout)
    return {"preset": preset, "ok": proc.returncode == 0, "status": proc.returncode, "wall_s": wall,
            "steps": int(len(history)), "time": float(history["time"][-1]),
            "newton": int(history["newton_iterations"].sum()), "linear": int(history["linear_iterations"].sum()),
            "fallbacks": int(history["linear_fallbacks"].sum()), "cuts": int(history["step_cuts"].sum()),
            "force": float(history["platen_force_y"][-1]),
            "solve_share": (stages.get("Solve") or 0.0) / wall,
            "assembly_constitutive_share": ((stages.get("Assembly") or 0.0)
                                            + (stages.get("Constitutive update") or 0.0)) / wall}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--presets", nargs="+", default=["mumps", "cg-gamg", "gmres-gamg", "gmres-hypre", "jfnk", "matrix-free"])
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--json", default=os.path.join(ROOT, "docs", "data", "bench_presets.json"))
    args = ap.parse_args()
    runs = {p: [] for p in args.presets}
    for _ in range(args.repeats):
        for preset in args.presets:
            with tempfile.TemporaryDirectory() as workdir:
                runs[preset].append(run(preset, args.ranks, workdir))
            print(json.dumps(runs[preset][-1]), flush=True)
    rows = []
    for preset, results in runs.items():
        row = dict(results[0])
        if row["ok"]:
            row["wall_s"] = float(np.median([r["wall_s"] for r in results if r["ok"]]))
        rows.append(row)
    reference = next((r["force"] for r in rows if r["preset"] == "mumps" and r["ok"]), None)
    print(f"\n| preset | ranks | wall time (s) | steps | Newton its | linear its | linear its per Newton "
          "| direct fallbacks | step cuts | Solve share | constitutive + assembly share | force vs mumps |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        if not r.get("steps"):
            print(f"| {r['preset']} | {args.ranks} | {r.get('error', 'failed')} |")
            continue
        force = f"{abs(r['force'] / reference - 1.0):.1e}" if reference else ""
        print(f"| {r['preset']} | {args.ranks} | {r['wall_s']:.1f} | {r['steps']} | {r['newton']} | {r['linear']} | "
              f"{r['linear'] / max(r['newton'], 1):.1f} | {r['fallbacks']} | {r['cuts']} | {r['solve_share']:.0%} | "
              f"{r['assembly_constitutive_share']:.0%} | {force} |")
    with open(args.json, "w") as f:
        json.dump({"ranks": args.ranks, "repeats": args.repeats, "rows": rows}, f, indent=1)
    print(f"\nwritten: {args.json}")


if __name__ == "__main__":
    main()
