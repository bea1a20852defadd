#!/usr/bin/env python3
"""Velocity against momentum formulation (Sulsky & Kaul 3.2.1) with pimpm's
step control, 1 rank: the 1 cm dynamic billet of tests/helpers.py
(coarse_billet, dt 0.01 s = 26x the explicit step) with Newmark and with
backward Euler, and inputs/upsetting.yaml (1 mm cells) with backward Euler
at the input's dt 5e-4 s and up to 8 step cuts. Prints steps, cuts, Newton
iterations, and the platen force, bulge or load and radius at the end.

    python scripts/formulation_comparison.py
"""
import os
import sys

import petsc4py
petsc4py.init([])
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tests"))
sys.path.insert(0, os.path.join(ROOT, "scripts"))
from helpers import coarse_billet                       # noqa: E402
from shape_comparison import bulge, run                 # noqa: E402


def upsetting(integrator, formulation):
    with open(os.path.join(ROOT, "inputs", "upsetting.yaml")) as f:
        raw = yaml.safe_load(f)
    raw["time"].update(integrator=integrator, formulation=formulation, max_cuts=8)
    return raw


def main():
    print("| problem | formulation | steps (cuts) | Newton its | end time | result |")
    print("|---|---|---|---|---|---|")
    for integrator in ("newmark", "backward_euler"):
        for formulation in ("velocity", "momentum"):
            raw = coarse_billet(integrator)
            raw["time"]["formulation"] = formulation
            sim, r = run(raw)
            result = f"failed: {r['failed']}" if r["failed"] else (
                f"bulge {bulge(sim):.3f} cm, platen force {r['forces']['platen'][1]:.4g}")
            print(f"| billet (1 cm), {integrator} | {formulation} | {r['steps']} ({r['cuts']}) | "
                  f"{r['newton']} | {sim.time:.4g} | {result} |", flush=True)
    for formulation in ("velocity", "momentum"):
        sim, r = run(upsetting("backward_euler", formulation))
        p = sim.particles
        cylinder = p["body"] == 0
        radius = float(p["x"][cylinder & (p["x"][:, 1] < 1.0), 0].max())
        result = f"failed: {r['failed']}" if r["failed"] else (
            f"load {-r['forces']['platen'][1] / 1000:.0f} kN, radius at mid-height {radius:.2f} mm")
        print(f"| upsetting (1 mm), backward_euler | {formulation} | {r['steps']} ({r['cuts']}) | "
              f"{r['newton']} | {sim.time:.4g} | {result} |", flush=True)


if __name__ == "__main__":
    main()
