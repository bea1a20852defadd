#!/usr/bin/env python3
"""Is the self-weight column (inputs/column_gravity.yaml) a locking test?
The column several cells wide (rollers on both sides and the base), nu =
0.3, 0.49 and 0.499, with and without F-bar (``f_bar``), small strain
(E = 1e6) or large (E = 1e4), one rank. Prints, per case, the largest and
RMS error of sigma_yy against the exact -rho g (L - Y) over rho g L, and
how far the mean stress strays from a smooth (quartic) fit in the initial
height Y, over rho g L (a checkerboard would show there); writes JSON.

    python scripts/locking_column.py [--youngs 1e6] [--shape gimp] [--width 4]
        [--cells 10 20 40] [--json FILE]

About a minute at the defaults."""
import argparse
import copy
import json
import os
import sys

import numpy as np
import petsc4py
import yaml

petsc4py.init(sys.argv[:1])
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
from pimpm.analysis import run_to_end  # noqa: E402
from pimpm.config import validate  # noqa: E402


def run(base, cells, nu, f_bar, shape, width, youngs, steps=10):
    raw = copy.deepcopy(base)
    height = float(raw["bodies"][0]["geometry"]["upper"][1])
    h = height / cells
    raw["grid"].update(upper=[width * h, height + h], cells=[width, cells + 1], shape_functions=shape)
    raw["bodies"][0]["geometry"]["upper"] = [width * h, height]
    material = raw["materials"]["soil"]
    material.update(poisson_ratio=nu, youngs_modulus=youngs, f_bar=f_bar)
    raw["time"]["dt"] = raw["time"]["end_time"] / steps
    raw.pop("output", None)
    sim, stats, status = run_to_end(validate(raw))
    if status != 0:
        return {"cells": cells, "nu": nu, "f_bar": f_bar, "failed": True}
    p = sim.particles
    rho, g = material["density"], -raw["time"]["gravity"][1]
    Y = p["x0"][:, 1]
    scale = rho * g * height
    error = (p["stress"][:, 1, 1] + rho * g * (height - Y)) / scale
    mean = np.trace(p["stress"], axis1=1, axis2=2) / 3.0
    stray = (mean - np.polyval(np.polyfit(Y, mean, 4), Y)) / scale
    J = np.linalg.det(p["F"])
    return {"cells": cells, "nu": nu, "f_bar": f_bar, "max_error": float(np.max(np.abs(error))),
            "rms_error": float(np.sqrt(np.mean(error ** 2))), "mean_stress_stray": float(np.max(np.abs(stray))),
            "J_range": [float(J.min()), float(J.max())]}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--youngs", type=float, default=1.0e6)
    ap.add_argument("--shape", default="gimp", choices=["linear", "gimp", "bspline"])
    ap.add_argument("--width", type=int, default=4, help="cells across the column")
    ap.add_argument("--cells", type=int, nargs="+", default=[10, 20, 40], help="cells along its height")
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    with open(os.path.join(ROOT, "inputs", "column_gravity.yaml")) as f:
        base = yaml.safe_load(f)
    rows = []
    print(f"column {args.width} cells wide, E = {args.youngs:g}, {args.shape}")
    print("| cells | nu | F-bar | max error sigma_yy | RMS error | mean stress off a smooth fit | J range |")
    print("|---|---|---|---|---|---|---|")
    for cells in args.cells:
        for nu in (0.3, 0.49, 0.499):
            for f_bar in (False, "cells", "nodes"):
                r = run(base, cells, nu, f_bar, args.shape, args.width, args.youngs)
                rows.append(r)
                if r.get("failed"):
                    print(f"| {cells} | {nu} | {f_bar or 'off'} | failed | | | |")
                    continue
                print(f"| {cells} | {nu} | {f_bar or 'off'} | {100 * r['max_error']:.2f}% | "
                      f"{100 * r['rms_error']:.2f}% | {100 * r['mean_stress_stray']:.2f}% | "
                      f"{r['J_range'][0]:.4f}-{r['J_range'][1]:.4f} |", flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
