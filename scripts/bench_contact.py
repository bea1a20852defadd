#!/usr/bin/env python3
"""What a frictional platen costs: Guilkey & Weiss's billet (inputs/billet.yaml,
0.5 cm cells, 50%) with its bonded platen and with `contact: friction` at
mu = 0.1, 0.3 and 1 (the default regularization), and at mu = 0.3 with
PETSc's l2 line search at every iteration (what contact used before
pimpm.line_search), whole runs under `mpiexec -n RANKS`, the variants
alternating for --repeats rounds.

Prints a table (steps, step cuts, Newton iterations, median wall time of the
whole process, ratio to the bonded run, platen force and barrelling at 50%)
and writes JSON.

    python scripts/bench_contact.py [--ranks 2] [--repeats 3] [--cells 80 42]
                                    [--json docs/data/bench_contact.json]
"""
import argparse
import json
import os
import statistics
import tempfile

import h5py
import numpy as np

from pimpm_runs import run_pimpm

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
VARIANTS = {"bonded": [],
            "friction 0.1": ["bodies[1].contact=friction", "bodies[1].friction_coefficient=0.1"],
            "friction 0.3": ["bodies[1].contact=friction", "bodies[1].friction_coefficient=0.3"],
            "friction 1": ["bodies[1].contact=friction", "bodies[1].friction_coefficient=1.0"],
            # PETSc's l2 at every Newton iteration, the contact line search before pimpm.line_search
            "friction 0.3, l2": ["bodies[1].contact=friction", "bodies[1].friction_coefficient=0.3",
                                 "solver.petsc.snes_linesearch_type=l2"]}


def run(overrides, ranks, out):
    wall, rows = run_pimpm(os.path.join(ROOT, "inputs", "billet.yaml"), overrides, ranks, out)
    with h5py.File(os.path.join(out, "results.h5"), "r") as f:
        last = f["steps"][sorted(f["steps"].keys())[-1]]["particles"]
        x = last["position"][:][last["body"][:] == 0]
    top = float(np.max(x[:, 1]))
    barrel = float(np.max(x[x[:, 1] < 0.25 * top, 0]) - np.max(x[x[:, 1] > 0.75 * top, 0]))
    return {"wall": wall, "steps": len(rows), "cuts": sum(int(r["step_cuts"]) for r in rows),
            "newton": sum(int(r["newton_iterations"]) for r in rows),
            "newton_max": max(int(r["newton_iterations"]) for r in rows),
            "force_y": -float(rows[-1]["platen_force_y"]), "force_x": -float(rows[-1]["platen_force_x"]),
            "barrel": barrel}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--cells", type=int, nargs=2, default=[80, 42])
    ap.add_argument("--json", default=os.path.join(ROOT, "docs", "data", "bench_contact.json"))
    args = ap.parse_args()
    cells = [f"grid.cells=[{args.cells[0]}, {args.cells[1]}]"]
    runs = {name: [] for name in VARIANTS}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.repeats):
            for name, overrides in VARIANTS.items():
                runs[name].append(run(cells + overrides, args.ranks, os.path.join(tmp, name.replace(" ", "_"))))
    bonded = statistics.median(r["wall"] for r in runs["bonded"])
    table = []
    for name, results in runs.items():
        row = dict(results[-1], variant=name, wall=statistics.median(r["wall"] for r in results),
                   walls=[r["wall"] for r in results])
        row["ratio"] = row["wall"] / bonded
        table.append(row)
    print(f"billet, cells {args.cells}, {args.ranks} ranks, median of {args.repeats} alternating whole runs")
    print("| platen | steps | cuts | Newton (max) | wall s | / bonded | force kN/cm | tangential | barrel cm |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in table:
        print(f"| {r['variant']} | {r['steps']} | {r['cuts']} | {r['newton']} ({r['newton_max']}) | "
              f"{r['wall']:.1f} | {r['ratio']:.2f} | {r['force_y'] / 1e8:.4g} | {r['force_x'] / 1e8:.4g} | "
              f"{r['barrel']:.3f} |")
    os.makedirs(os.path.dirname(args.json), exist_ok=True)
    with open(args.json, "w") as f:
        json.dump({"ranks": args.ranks, "repeats": args.repeats, "cells": args.cells, "rows": table}, f, indent=1)
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
