#!/usr/bin/env python3
"""Velocity against momentum formulation (Sulsky & Kaul 3.2.1), 1 rank.

First the two test cases of tests/test_formulations.py and
tests/test_explicit.py with their measured values: the stress-free disk
translating across the grid (explicit USL / MUSL, implicit Newmark in both
formulations) and the vibrating bar (Newmark at 3.7x the explicit step, 10
periods: energy and period errors, for both formulations and the three
shape functions). Then, with pimpm's step control: the 1 cm dynamic billet of tests/helpers.py
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
from shape_comparison import run                        # noqa: E402
from mpi4py import MPI                                  # noqa: E402
import numpy as np                                      # noqa: E402
from pimpm.measures import bulge, midplane_radius       # noqa: E402
from pimpm.simulation import Simulation                 # noqa: E402
from test_explicit import bar_config, vibrate           # noqa: E402
from test_formulations import E, translate, translating_disk   # noqa: E402


def upsetting(integrator, formulation):
    with open(os.path.join(ROOT, "inputs", "upsetting.yaml")) as f:
        raw = yaml.safe_load(f)
    raw["time"].update(integrator=integrator, formulation=formulation, max_cuts=8)
    raw["grid"]["shape_functions"] = "linear"       # as documented (docs/VALIDATION.md)
    return raw


def test_cases():
    print("| translating disk (15 time units) | steps | max stress / E | deviation from rigid translation | failure |")
    print("|---|---|---|---|---|")
    cases = [("explicit, velocity (usl)", {"integrator": "explicit", "stress_update": "usl"}, None),
             ("explicit, momentum (musl)", {"integrator": "explicit", "stress_update": "musl"}, None),
             ("Newmark dt 0.5, velocity", {"integrator": "newmark", "dt": 0.5, "formulation": "velocity"}, 0.5),
             ("Newmark dt 0.5, momentum", {"integrator": "newmark", "dt": 0.5, "formulation": "momentum"}, 0.5)]
    for label, time, dt in cases:
        sim = Simulation(translating_disk(time), MPI.COMM_WORLD)
        failure, stress, deviation = translate(sim, 15.0, dt)
        print(f"| {label} | {sim.step_index} | {stress / E:.2e} | {deviation:.2e} | {failure or ''} |",
              flush=True)
        if sim.solver is not None:
            sim.solver.destroy()
    print("\n| vibrating bar, Newmark dt 0.0025, 10 periods | energy drift | period error |")
    print("|---|---|---|")
    for shape, formulation in (("linear", "velocity"), ("gimp", "velocity"), ("bspline", "velocity"),
                               ("linear", "momentum")):
        sim, period, measured, energy = vibrate(bar_config("newmark", dt=0.0025, shape=shape,
                                                           formulation=formulation), 10, dt=0.0025)
        print(f"| {shape}, {formulation} | {np.max(np.abs(energy - energy[0])) / energy[0]:.2%} | "
              f"{np.max(np.abs(measured - period)) / period:.2%} |", flush=True)
        sim.solver.destroy()
    print()


def main():
    test_cases()
    print("| problem | formulation | steps (cuts) | Newton its | end time | result |")
    print("|---|---|---|---|---|---|")
    for integrator in ("newmark", "backward_euler"):
        for formulation in ("velocity", "momentum"):
            raw = coarse_billet(integrator)
            raw["time"]["formulation"] = formulation
            sim, r = run(raw)
            result = f"failed: {r.failure}" if r.failure else (
                f"bulge {bulge(sim):.3f} cm, platen force {r.forces['platen'][1]:.4g}")
            print(f"| billet (1 cm), {integrator} | {formulation} | {r.steps} ({r.cuts}) | "
                  f"{r.newton} | {sim.time:.4g} | {result} |", flush=True)
    for formulation in ("velocity", "momentum"):
        sim, r = run(upsetting("backward_euler", formulation))
        radius = midplane_radius(sim.particles["x"], sim.particles["body"], 1.0)   # 1 mm cells
        result = f"failed: {r.failure}" if r.failure else (
            f"load {-r.forces['platen'][1] / 1000:.0f} kN, radius at mid-height {radius:.2f} mm")
        print(f"| upsetting (1 mm), backward_euler | {formulation} | {r.steps} ({r.cuts}) | "
              f"{r.newton} | {sim.time:.4g} | {result} |", flush=True)


if __name__ == "__main__":
    main()
