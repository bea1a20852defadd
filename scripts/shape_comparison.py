#!/usr/bin/env python3
"""Shape functions against cell-crossing trouble: the coarse billet of
tests/helpers.py (Guilkey & Weiss 5.1 at 1 cm cells, 50% compression,
dynamic and quasi-static) and the colliding disks (Sulsky & Kaul 3.1.1,
Newmark at dt = 0.4) with linear, GIMP and quadratic B-spline shape
functions, with pimpm's step control. Prints Newton iterations, step cuts,
the bulge (pimpm.measures: the edge particle of the symmetry plane) and,
for the disks, the largest departure of the total energy from its initial
value.

    python scripts/shape_comparison.py [--shapes linear gimp bspline]
"""
import argparse
import copy
import os
import sys

import petsc4py
petsc4py.init([])
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tests"))
from helpers import coarse_billet                       # noqa: E402
from pimpm.analysis import run_to_end                   # noqa: E402
from pimpm.config import validate                       # noqa: E402
from pimpm.measures import bulge                        # noqa: E402


def run(raw):
    """Run to end_time with pimpm's own loop and step control (failed steps
    halved and retried, dt grown back after easy steps). Returns the
    simulation and its StepStatistics (steps, cuts, Newton iterations, the
    largest relative departure of the total energy from its start, the last
    step's forces, and ``failure``: the message, or None)."""
    sim, stats, _ = run_to_end(validate(raw))
    if stats.failure:
        stats.failure = stats.failure[:80]
    return sim, stats


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--shapes", nargs="+", default=["linear", "gimp", "bspline"])
    args = ap.parse_args()
    with open(os.path.join(ROOT, "inputs", "colliding_disks.yaml")) as f:
        disks = yaml.safe_load(f)
    print("| problem | shape functions | steps (cuts) | Newton its | Newton its per step | result |")
    print("|---|---|---|---|---|---|")
    for integrator in ("quasi_static", "newmark"):
        for shape in args.shapes:
            raw = coarse_billet(integrator)
            raw["grid"]["shape_functions"] = shape
            sim, r = run(raw)
            name = f"billet, {integrator}"
            if r.failure:
                print(f"| {name} | {shape} | {r.steps} | | | failed: {r.failure} |", flush=True)
                continue
            print(f"| {name} | {shape} | {r.steps} ({r.cuts}) | {r.newton} | "
                  f"{r.newton / r.steps:.1f} | "
                  f"bulge at 50% {bulge(sim):.3f} cm |", flush=True)
    for shape in args.shapes:
        raw = copy.deepcopy(disks)
        raw["grid"]["shape_functions"] = shape
        _, r = run(raw)
        if r.failure:
            print(f"| colliding disks | {shape} | {r.steps} | | | failed: {r.failure} |", flush=True)
            continue
        print(f"| colliding disks, Newmark dt 0.4 | {shape} | {r.steps} ({r.cuts}) | {r.newton} | "
              f"{r.newton / r.steps:.1f} | total energy within {100 * r.energy:.2f}% |", flush=True)


if __name__ == "__main__":
    main()
