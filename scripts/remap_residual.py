#!/usr/bin/env python3
"""What the grid reset does to a converged step: inputs/upsetting_3d.yaml
(2 mm cells, quarter cylinder, finite-strain J2, quasi-static) run with
pimpm's loop; after every step the same state takes a step of 1e-9 s (no
platen travel) on the grid reset at the new particle positions. Prints the
reaction each step reported, the reaction of that zero-travel step, and the
zero-travel step's initial dimensionless residual (the out-of-balance force
the remap leaves), for each shape function. The reaction a step reports is
evaluated on the grid of its start; a step that moves nothing re-balances
the same particles on the new grid.

    mpiexec -n 2 python scripts/remap_residual.py [--shapes linear gimp bspline] [--end 6e-3]
"""
import argparse

import petsc4py
petsc4py.init([])
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
from pimpm.analysis import Analysis, Observer              # noqa: E402
from pimpm.config import load_config                       # noqa: E402
from pimpm.simulation import Simulation                    # noqa: E402


class ZeroTravelStep(Observer):
    """After each step, a step of 1e-9 s from the same state, then the state restored."""

    def __init__(self):
        self.rows = []

    def step(self, analysis, info):
        sim = analysis.sim
        saved = ({k: v.copy() for k, v in sim.particles.fields.items()},
                 {k: v.copy() for k, v in sim.rigid.fields.items()}, sim.time, sim.step_index,
                 sim.work.total, dict(sim.work.last_forces), sim.last_grid)
        zero = sim.advance(1e-9)
        sim.particles.fields, sim.rigid.fields, sim.time, sim.step_index = saved[:4]
        sim.work.total, sim.work.last_forces, sim.last_grid = saved[4:]
        self.rows.append((info["step"], info["time"], -4e-3 * info["forces"]["platen"][2],
                          -4e-3 * zero["forces"]["platen"][2], zero["residual_initial"]))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--shapes", nargs="+", default=["linear", "gimp", "bspline"])
    ap.add_argument("--end", type=float, default=6e-3)
    args = ap.parse_args()
    results = {}
    for shape in args.shapes:
        cfg = load_config(os.path.join(ROOT, "inputs", "upsetting_3d.yaml"))
        cfg["grid"]["shape_functions"] = shape
        cfg["time"]["end_time"] = args.end
        sim = Simulation(cfg)
        observer = ZeroTravelStep()
        Analysis(sim, [observer]).run()
        sim.solver.destroy()
        results[shape] = observer.rows
    if petsc4py.PETSc.COMM_WORLD.rank == 0:
        print("| shape functions | step | platen travel (mm) | reported load (kN) | zero-travel step load (kN) | "
              "difference | zero-travel step initial residual |")
        print("|---|---|---|---|---|---|---|")
        for shape, rows in results.items():
            for step, time, reported, zero, residual in rows:
                print(f"| {shape} | {step} | {1000 * time:.3f} | {reported:.1f} | {zero:.1f} | "
                      f"{zero / reported - 1:+.1%} | {residual:.2e} |")


if __name__ == "__main__":
    main()
