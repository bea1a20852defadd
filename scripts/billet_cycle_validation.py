#!/usr/bin/env python3
"""The load cycle of inputs/billet_cycle.yaml (docs/VALIDATION.md, "Billet
load cycle"): the elastic billet compressed to 20% and brought back, at
several step sizes (and, with --cells, another grid). For each run:

* the residual displacement: max and RMS over the billet's particles of
  |x - x0| at the end, over the platen travel (4 cm);
* the force left at the end and the loop's gap: the largest difference of
  the platen's vertical force at the same platen position on the way down
  and on the way up (interpolated), both over the peak force;
* the net work of the cycle (history.csv external_work at the end) over the
  work done at the deepest point, and the strain energy left at the end.

    python scripts/billet_cycle_validation.py [--dts 0.01 0.005 0.0025]
        [--cells 80 42] [--ranks 2] [--json docs/data/billet_cycle_validation.json]
"""
import argparse
import json
import os
import sys
import tempfile

import h5py
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tests"))
from helpers import run_pimpm  # noqa: E402

INPUT = os.path.join(ROOT, "inputs", "billet_cycle.yaml")
TRAVEL = 4.0           # cm: 20% of the 20 cm half height


def run(dt, ranks, workdir, cells=None):
    out = os.path.join(workdir, f"dt{dt}-{ranks}-{cells}")
    args = [INPUT, "--overwrite", "--output", out, "--set", f"time.dt={dt}"]
    if cells:
        args += ["--set", f"grid.cells=[{cells[0]},{cells[1]}]"]
    proc = run_pimpm(ranks, args)
    if proc.returncode != 0:
        raise RuntimeError(proc.stdout[-2000:] + proc.stderr[-2000:])
    return measure(out, dt, cells)


def measure(out, dt, cells=None):
    h = np.atleast_1d(np.genfromtxt(os.path.join(out, "history.csv"), delimiter=",", names=True))
    force, position = h["platen_force_y"], -h["platen_displacement_y"]
    deepest = int(np.argmax(position))
    peak = float(np.max(np.abs(force)))
    down_u, down_f = np.r_[0.0, position[:deepest + 1]], np.r_[0.0, force[:deepest + 1]]
    up_u, up_f = position[deepest:][::-1], force[deepest:][::-1]
    gap = float(np.max(np.abs(np.interp(up_u, down_u, down_f) - up_f))) / peak
    with h5py.File(os.path.join(out, "results.h5"), "r") as f:
        last = max(f["steps"], key=lambda s: int(f["steps"][s].attrs["step"]))
        p = f["steps"][last]["particles"]
        billet = p["body"][...] == 0
        residual = np.linalg.norm(p["displacement"][...][billet], axis=1)
    return {"dt": dt, "cells": cells, "steps": int(len(h)), "newton": int(h["newton_iterations"].sum()),
            "final_platen_position": float(position[-1]),
            "residual_max": float(residual.max()) / TRAVEL, "residual_rms": float(np.sqrt(np.mean(residual ** 2))) / TRAVEL,
            "final_force": float(abs(force[-1])) / peak, "loop_gap": gap, "peak_force": peak,
            "net_work": float(h["external_work"][-1] / h["external_work"][deepest]),
            "final_strain_energy": float(h["strain_energy"][-1] / h["strain_energy"][deepest])}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dts", type=float, nargs="+", default=[0.01, 0.005, 0.0025])
    ap.add_argument("--cells", type=int, nargs=2, default=None)
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--json", default=os.path.join(ROOT, "docs", "data", "billet_cycle_validation.json"))
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as workdir:
        for dt in args.dts:
            rows.append(run(dt, args.ranks, workdir, args.cells))
            print(json.dumps(rows[-1]), flush=True)
    print("\n| dt | steps | Newton its | residual displacement max, RMS (/ travel) | force at the end (/ peak) "
          "| loop gap (/ peak) | net work of the cycle (/ work at 20%) | strain energy left |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['dt']} | {r['steps']} | {r['newton']} | {r['residual_max']:.2e}, {r['residual_rms']:.2e} | "
              f"{r['final_force']:.2e} | {r['loop_gap']:.2e} | {r['net_work']:+.2e} | {r['final_strain_energy']:.2e} |")
    with open(args.json, "w") as f:
        json.dump({"cells": args.cells, "ranks": args.ranks, "rows": rows}, f, indent=1)
    print(f"\nwritten: {args.json}")


if __name__ == "__main__":
    main()
