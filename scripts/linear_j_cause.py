#!/usr/bin/env python3
"""Where the linear billet's J drift comes from (docs/VALIDATION.md).

Runs the 1 cm quasi-static billet (the coarse_billet of tests/helpers.py,
half a cell per step) and, at every step, relates each interior particle's
volume change over the step, dJ = J_new / J_old, to how full its cell was
at the start of the step: fill = (sum of the current particle volumes in
the cell) / (cell volume). Prints, per shape function, the mean dJ - 1 of
the particles in the emptiest and the fullest quarter of cells, the slope
of dJ against fill (least squares over all steps), the lattice J drift
per step (pimpm.measures.lattice_j_drift) and how it changes with the
number of particles per cell.

    python scripts/linear_j_cause.py [--json PATH]
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
from helpers import coarse_billet                            # noqa: E402
from pimpm.analysis import Observer, run_to_end              # noqa: E402
from pimpm.config import validate                            # noqa: E402
from pimpm.measures import lattice_j_drift                   # noqa: E402


class FillAndVolumeChange(Observer):
    """Per step: cell fill at the start of the step and each interior
    particle's dJ over it (1 rank)."""

    def __init__(self, cell):
        self.cell = cell
        self.fill, self.dJ = [], []
        self.before = None

    def snapshot(self, sim):
        p = sim.particles
        billet = p["body"] == 0
        ij = np.floor(p["x"][billet] / self.cell).astype(np.int64)
        key = ij[:, 0] * 100000 + ij[:, 1]
        volume = p["volume0"][billet] * np.linalg.det(p["F"][billet])
        cells, where = np.unique(key, return_inverse=True)
        fill = np.bincount(where, weights=volume) / self.cell ** 2
        return {"id": p["id"][billet], "J": np.linalg.det(p["F"][billet]),
                "fill": fill[where], "x0": p["x0"][billet]}

    def start(self, analysis):
        self.before = self.snapshot(analysis.sim)

    def step(self, analysis, info):
        after = self.snapshot(analysis.sim)
        b = self.before
        order_b, order_a = np.argsort(b["id"]), np.argsort(after["id"])
        interior = np.all(b["x0"][order_b] < 10.0, axis=1)
        self.dJ.append((after["J"][order_a] / b["J"][order_b])[interior])
        self.fill.append(b["fill"][order_b][interior])
        self.before = after


def study(shape, ppc=4, steps_per_cell=2):
    raw = coarse_billet("quasi_static")
    raw["grid"]["shape_functions"] = shape
    raw["bodies"][0]["particles_per_cell"] = ppc
    raw["time"]["dt"] = 1.0 / steps_per_cell / 50.0
    observer = FillAndVolumeChange(1.0)
    sim, stats, status = run_to_end(validate(raw), observers=[observer])
    drift = lattice_j_drift(sim.particles, 1.0 / ppc, lambda x0: np.all(x0 < 10.0, axis=1), sim.comm)
    fill, dJ = np.concatenate(observer.fill), np.concatenate(observer.dJ) - 1.0
    low, high = np.quantile(fill, [0.25, 0.75])
    slope = np.polyfit(fill, dJ, 1)[0]
    return {"shape": shape, "particles_per_cell": ppc, "steps": sim.step_index, "failed": stats.failure,
            "fill_quartiles": [float(low), float(high)],
            "dJ_emptiest_quarter": float(np.mean(dJ[fill <= low])),
            "dJ_fullest_quarter": float(np.mean(dJ[fill >= high])),
            "slope_dJ_per_fill": float(slope), "j_drift": drift,
            "j_drift_per_step": drift / sim.step_index}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", default=os.path.join(ROOT, "docs", "data", "linear_j_cause.json"))
    args = ap.parse_args()
    rows = [study(s) for s in ("linear", "gimp", "bspline")] + [study("linear", ppc) for ppc in (2, 8)]
    print("| shape functions | particles per cell | fill of the cells (quartiles) | dJ - 1, emptiest quarter | "
          "dJ - 1, fullest quarter | d(dJ)/d(fill) | J drift per step |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['shape']} | {r['particles_per_cell']}x{r['particles_per_cell']} | "
              f"{r['fill_quartiles'][0]:.3f}-{r['fill_quartiles'][1]:.3f} | {r['dJ_emptiest_quarter']:+.3e} | "
              f"{r['dJ_fullest_quarter']:+.3e} | {r['slope_dJ_per_fill']:+.3e} | {100 * r['j_drift_per_step']:+.4f}% |")
    with open(args.json, "w") as f:
        json.dump(rows, f, indent=1)
    print(f"\nwritten: {args.json}")


if __name__ == "__main__":
    main()
