#!/usr/bin/env python3
"""Convergence under refinement, for each shape function.

Column (inputs/column_gravity.yaml, 1 rank): the maximum and RMS error of
sigma_yy against the exact -rho g (L - Y) at 10, 20, 40, 80 cells along the
height, small strain (E = 1e6) and large strain (E = 1e4), with the observed
order log2(e_n / e_2n).

Billet (Guilkey & Weiss 5.1, quasi-static, the coarse_billet of
tests/helpers.py scaled to the cell size h; 4 x 4 particles per cell): at
each h the platen moves half a cell per step, then a quarter cell (dt
halved). Prints the bulge (pimpm.measures) and the platen force at 10-50%
compression, the differences between successive refinements, the observed
(Richardson) order p = log2(|f_h - f_h/2| / |f_h/2 - f_h/4|) where three
levels exist, and the drift of the stored J = det F from the J of the
particle lattice per step (pimpm.measures.lattice_j_drift).

Writes docs/data/convergence_study.json (or --json PATH), merged with what the
file already holds (entries for other shape functions or studies are kept).

    mpiexec -n 2 python scripts/convergence_study.py [--column] [--billet]
        [--shapes linear gimp bspline] [--sizes 1 0.5 0.25] [--f-bar [cells|nodes]]
"""
import argparse
import json
import os
import sys

import petsc4py
petsc4py.init([])
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tests"))
sys.path.insert(0, ROOT)
from helpers import coarse_billet, column                    # noqa: E402
from pimpm.analysis import Observer, run_to_end              # noqa: E402
from pimpm.config import validate                            # noqa: E402
from pimpm.measures import bulge, column_stress_error, lattice_j_drift   # noqa: E402

MARKS = (0.1, 0.2, 0.3, 0.4, 0.5)          # compression
HALF_HEIGHT, PLATEN_SPEED = 20.0, 50.0


def say(*args):
    from mpi4py import MPI
    if MPI.COMM_WORLD.rank == 0:
        print(*args, flush=True)


def column_study(shapes, cells=(10, 20, 40, 80)):
    out = {}
    say("\n| shape functions | E | " + " | ".join(f"{n} cells: max (RMS)" for n in cells)
        + " | observed order of the max (last pair) |")
    say("|---|---|" + "---|" * len(cells) + "---|")
    for shape in shapes:
        for E in (1.0e6, 1.0e4):
            rows = []
            for n in cells:
                raw, (rho, g, height) = column(n, shape, E)
                sim, stats, status = run_to_end(validate(raw))
                worst, rms = column_stress_error(sim.particles, rho, g, height, sim.comm) \
                    if status == 0 else (np.nan, np.nan)
                rows.append({"cells": n, "max": worst, "rms": rms, "failed": stats.failure})
            order = np.log2(rows[-2]["max"] / rows[-1]["max"])
            say(f"| {shape} | {E:g} | " + " | ".join(f"{r['max']:.2%} ({r['rms']:.2%})" for r in rows)
                + f" | {order:.2f} |")
            out[f"{shape}, E={E:g}"] = rows
    return out


def billet(h, travel_per_step, shape, f_bar=False):
    """coarse_billet at cell size h (cm): the grid and bodies keep their
    size in cm, cells scale; the platen moves ``travel_per_step`` cells per step;
    ``f_bar``: every material with F-bar (pimpm/fbar.py), False or what
    it averages over ("cells", "nodes")."""
    raw = coarse_billet("quasi_static")
    for material in raw["materials"].values():
        material["f_bar"] = f_bar
    scale = int(round(1.0 / h))
    raw["grid"]["cells"] = [36 * scale, 22 * scale]
    raw["grid"]["shape_functions"] = shape
    raw["bodies"][1]["geometry"]["lower"][1] = 20.0
    raw["bodies"][1]["geometry"]["upper"][1] = 20.0 + h
    raw["time"]["dt"] = travel_per_step * h / PLATEN_SPEED
    return raw


class AtMarks(Observer):
    """Bulge, platen force and J drift at the first step reaching each mark."""

    def __init__(self, spacing):
        self.rows = []
        self.spacing = spacing

    def step(self, analysis, info):
        sim = analysis.sim
        if len(self.rows) < len(MARKS) and sim.time >= MARKS[len(self.rows)] * HALF_HEIGHT / PLATEN_SPEED - 1e-12:
            drift = lattice_j_drift(sim.particles, self.spacing, lambda x0: np.all(x0 < 10.0, axis=1), sim.comm)
            self.rows.append({"compression": MARKS[len(self.rows)], "step": sim.step_index,
                              "bulge": bulge(sim), "force": float(-info["forces"]["platen"][1]),
                              "j_drift": drift})


def billet_study(shapes, sizes, f_bar=False):
    out = {}
    for shape in shapes:
        label = {False: shape, "cells": f"{shape}, f_bar"}.get(f_bar, f"{shape}, f_bar {f_bar}")
        runs = {}
        for h in sizes:
            for travel in (0.5, 0.25):
                raw = billet(h, travel, shape, f_bar)
                marks = AtMarks(h / 4.0)
                sim, stats, status = run_to_end(validate(raw), observers=[marks])
                runs[(h, travel)] = {"h": h, "travel_per_step": travel, "steps": sim.step_index,
                                     "newton": stats.newton, "failed": stats.failure, "marks": marks.rows}
                last = marks.rows[-1] if marks.rows else None
                say(f"billet {label} h {h:g} travel {travel:g} cell/step: {sim.step_index} steps"
                    + (f", bulge at 50% {last['bulge']:.4f} cm, force {last['force']:.5e}, "
                       f"J drift {100 * last['j_drift']:+.3f}% ({100 * last['j_drift'] / last['step']:+.4f}% per step)"
                       if last and len(marks.rows) == len(MARKS) else f", failed: {stats.failure}"))
        out[label] = [dict(r) for r in runs.values()]
        report(label, runs, sizes)
    return out


def report(shape, runs, sizes):
    for quantity in ("bulge", "force"):
        say(f"\n{shape}: {quantity} at 10-50% compression")
        say("| h (cm) | cell/step | " + " | ".join(f"{m:.0%}" for m in MARKS) + " |")
        say("|---|---|" + "---|" * len(MARKS))
        for (h, travel), r in runs.items():
            values = [m[quantity] for m in r["marks"]]
            say(f"| {h:g} | {travel:g} | " + " | ".join(f"{v:.5g}" for v in values) + " |")
        for travel in (0.5, 0.25):
            series = [np.array([m[quantity] for m in runs[(h, travel)]["marks"]]) for h in sizes
                      if len(runs[(h, travel)]["marks"]) == len(MARKS)]
            diffs = [b - a for a, b in zip(series, series[1:])]
            for k, d in enumerate(diffs):
                say(f"  refining h {sizes[k]:g} -> {sizes[k + 1]:g} at {travel:g} cell/step changes it by "
                    + ", ".join(f"{v:+.4g}" for v in d))
            if len(diffs) >= 2:
                p = np.log2(np.abs(diffs[-2]) / np.abs(diffs[-1]))
                say("  observed order in h: " + ", ".join(f"{v:.2f}" for v in p))
        for h in sizes:
            a, b = runs[(h, 0.5)]["marks"], runs[(h, 0.25)]["marks"]
            if len(a) == len(b) == len(MARKS):
                say(f"  halving dt at h {h:g} changes it by "
                    + ", ".join(f"{y[quantity] - x[quantity]:+.4g}" for x, y in zip(a, b)))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--column", action="store_true")
    ap.add_argument("--billet", action="store_true")
    ap.add_argument("--shapes", nargs="+", default=["linear", "gimp", "bspline"])
    ap.add_argument("--sizes", type=float, nargs="+", default=[1.0, 0.5, 0.25])
    ap.add_argument("--f-bar", nargs="?", const="cells", default=False, choices=["cells", "nodes"],
                    help="the billet with F-bar on the cells (entries 'SHAPE, f_bar') or the nodes "
                         "('SHAPE, f_bar nodes')")
    ap.add_argument("--json", default=os.path.join(ROOT, "docs", "data", "convergence_study.json"))
    args = ap.parse_args()
    if not (args.column or args.billet):
        args.column = args.billet = True
    result = {}
    if args.column:
        result["column"] = column_study(args.shapes)
    if args.billet:
        result["billet"] = billet_study(args.shapes, args.sizes, args.f_bar)
    from mpi4py import MPI
    if MPI.COMM_WORLD.rank == 0:
        # merge into the existing file: the shapes (and studies) not run keep their entries
        if os.path.exists(args.json):
            with open(args.json) as f:
                previous = json.load(f)
            for study, entries in result.items():
                previous.setdefault(study, {}).update(entries)
            result = previous
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1, default=float)
        say(f"\nwritten: {args.json}")


if __name__ == "__main__":
    main()
