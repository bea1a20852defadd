#!/usr/bin/env python3
"""How the billet depends on the time step: the 1 cm billet of
tests/helpers.py (coarse_billet, Guilkey & Weiss 5.1 at half resolution),
run quasi-statically at several steps and explicitly at several CFL
factors, with pimpm's own time loop. Prints the bulge (pimpm.measures:
the edge particle of the symmetry plane) at the first step that reaches
10-50% compression.

    python scripts/billet_explicit_cfl.py [--qs-dt 0.01 0.005 0.0025]
        [--cfl 0.5 0.25 0.1] [--stress-update musl]
"""
import argparse
import os
import sys

import petsc4py
petsc4py.init([])

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tests"))
from helpers import coarse_billet                       # noqa: E402
from pimpm.analysis import Observer, run_to_end         # noqa: E402
from pimpm.config import validate                       # noqa: E402
from pimpm.measures import bulge                        # noqa: E402

MARKS = (0.04, 0.08, 0.12, 0.16, 0.2)      # 10-50% compression (platen at 50 cm/s)


class BulgeAtMarks(Observer):
    """The bulge at the first step that reaches each of MARKS."""

    def __init__(self):
        self.values = []

    def step(self, analysis, info):
        if len(self.values) < len(MARKS) and analysis.sim.time >= MARKS[len(self.values)] - 1e-12:
            self.values.append(bulge(analysis.sim))


def bulges(time_config):
    raw = coarse_billet(time_config["integrator"])
    raw["time"] = dict(time_config, end_time=0.2)
    marks = BulgeAtMarks()
    sim, stats, _ = run_to_end(validate(raw), observers=[marks])
    return marks.values, sim.step_index, stats.failure or ""


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cfl", type=float, nargs="+", default=[0.5, 0.25, 0.1])
    ap.add_argument("--qs-dt", type=float, nargs="+", default=[0.01, 0.005, 0.0025])
    ap.add_argument("--stress-update", default="musl")
    args = ap.parse_args()
    runs = [(f"quasi-static, dt {dt:g}", {"integrator": "quasi_static", "dt": dt}) for dt in args.qs_dt]
    runs += [(f"explicit {args.stress_update}, cfl {c:g}",
              {"integrator": "explicit", "cfl": c, "stress_update": args.stress_update})
             for c in args.cfl]
    print("| run | steps | " + " | ".join(f"bulge at {m / 0.4:.0%} (cm)" for m in MARKS) + " |")
    print("|---|---|" + "---|" * len(MARKS))
    for label, time_config in runs:
        values, steps, failure = bulges(time_config)
        cells = [f"{v:.3f}" for v in values] + ["failed"] * (len(MARKS) - len(values))
        print(f"| {label} | {steps} | " + " | ".join(cells) + " |" + (f" {failure}" if failure else ""),
              flush=True)


if __name__ == "__main__":
    main()
