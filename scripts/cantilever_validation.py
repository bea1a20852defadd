#!/usr/bin/env python3
"""The cantilever of inputs/cantilever.yaml against beam theory, at several
resolutions (docs/VALIDATION.md, "Cantilever").

* Small load (k = P L^2 / (E I) = 0.03, two steps): the tip deflection
  against Timoshenko beam theory (bending + shear), evaluated where the tip
  particles sit (x = L - h/4).
* Large load (k from 0 to 10, the shipped input): the tip displacements at
  k = 1..10 against the inextensible elastica and Reissner's extensible,
  shear-deformable beam (pimpm/reference.py), both at the tip particles'
  arclength.

The tip displacement is the history column ``tip_displacement_*`` (the
share-weighted mean displacement of the particles the tip traction acts on);
steps do not land on integer k after step cuts, so the ratio to the
reference is interpolated in k between the steps.

    python scripts/cantilever_validation.py [--depth-cells 4 8 16] [--ranks 2]
        [--json docs/data/cantilever_validation.json]
"""
import argparse
import json
import os
import sys
import tempfile

import numpy as np
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))
from helpers import run_pimpm  # noqa: E402
from pimpm.reference import elastica_tip, reissner_tip, timoshenko_cantilever  # noqa: E402

INPUT = os.path.join(ROOT, "inputs", "cantilever.yaml")
SMALL_TRACTION = 250.0          # k = 0.03


def beam_data():
    with open(INPUT) as f:
        raw = yaml.safe_load(f)
    material = raw["materials"]["steel"]
    box = raw["bodies"][0]["geometry"]
    length = box["upper"][0] - box["lower"][0]
    depth = box["upper"][1] - box["lower"][1]
    load = -raw["loads"][0]["traction"][1] * depth
    return raw, dict(E=material["youngs_modulus"], nu=material["poisson_ratio"], L=length, d=depth, P=load)


def run(depth_cells, ranks, small, workdir, extra=()):
    """Run the input at ``depth_cells`` cells per depth (``extra``: more
    --set values); returns the history and the cell size."""
    raw, beam = beam_data()
    h = beam["d"] / depth_cells
    extent = np.subtract(raw["grid"]["upper"], raw["grid"]["lower"])
    cells = [int(round(e / h)) for e in extent]
    sets = [f"grid.cells=[{cells[0]},{cells[1]}]"]
    if small:
        sets += [f"loads[0].traction=[0,{-SMALL_TRACTION}]", "time.dt=0.5"]
    sets += list(extra)
    out = os.path.join(workdir, f"{'small' if small else 'large'}{depth_cells}-{ranks}")
    args = [INPUT, "--overwrite", "--output", out]
    for s in sets:
        args += ["--set", s]
    proc = run_pimpm(ranks, args)
    if proc.returncode != 0:
        raise RuntimeError(proc.stdout[-2000:] + proc.stderr[-2000:])
    history = np.genfromtxt(os.path.join(out, "history.csv"), delimiter=",", names=True)
    return np.atleast_1d(history), h


def small_load(depth_cells, ranks, workdir):
    history, h = run(depth_cells, ranks, True, workdir)
    _, b = beam_data()
    x = b["L"] - 0.25 * h                         # the tip particles' x (2 per cell and axis)
    reference = timoshenko_cantilever(SMALL_TRACTION * b["d"], b["L"], b["d"], b["E"], b["nu"], x=x)
    bending_only = timoshenko_cantilever(SMALL_TRACTION * b["d"], b["L"], b["d"], b["E"], b["nu"], x=x,
                                         shear_coefficient=np.inf)
    deflection = -float(history["tip_displacement_y"][-1])
    return {"depth_cells": depth_cells, "deflection": deflection, "timoshenko": reference,
            "bending_only": bending_only, "error": deflection / reference - 1.0,
            "steps": int(len(history)), "newton": int(history["newton_iterations"].sum())}


def large_load(depth_cells, ranks, workdir):
    history, h = run(depth_cells, ranks, False, workdir)
    _, b = beam_data()
    k_full = b["P"] * b["L"] ** 2 / (b["E"] * b["d"] ** 3 / 12.0)
    axial = b["P"] / (b["E"] * b["d"])                               # P / (E A) at k = k_full
    shear = b["P"] / (5.0 / 6.0 * b["E"] / (2.0 * (1.0 + b["nu"])) * b["d"])
    at = 1.0 - 0.25 * h / b["L"]
    k_steps = k_full * history["time"] / history["time"][-1]
    v = -history["tip_displacement_y"] / b["L"]
    u = -history["tip_displacement_x"] / b["L"]
    rows = []
    for k in range(1, int(round(k_full)) + 1):
        # the references at each neighbouring step's k, so only the ratio is interpolated
        i = int(np.searchsorted(k_steps, k))
        around = [j for j in (i - 1, i) if 0 <= j < len(k_steps)]
        ratio_v, ratio_u, ratio_ev, ratio_eu = [], [], [], []
        for j in around:
            rv, ru = reissner_tip(k_steps[j], axial * k_steps[j] / k_full, shear * k_steps[j] / k_full, at=at)
            ev, eu = reissner_tip(k_steps[j], 0.0, 0.0, at=at)
            ratio_v.append(v[j] / rv)
            ratio_u.append(u[j] / ru)
            ratio_ev.append(v[j] / ev)
            ratio_eu.append(u[j] / eu)
        ks = k_steps[around]

        def at_k(values):
            return float(np.interp(k, ks, values)) if len(ks) > 1 else float(values[0])

        rv, ru = reissner_tip(k, axial * k / k_full, shear * k / k_full, at=at)
        ev, eu = elastica_tip(k)
        tip = reissner_tip(k, axial * k / k_full, shear * k / k_full)
        rows.append({"k": k, "vertical": at_k(ratio_v) * rv, "horizontal": at_k(ratio_u) * ru,
                     "reissner_at_particles": [rv, ru],
                     "elastica_tip": [ev, eu], "reissner": list(tip),
                     "vertical_vs_reissner": at_k(ratio_v) - 1.0, "horizontal_vs_reissner": at_k(ratio_u) - 1.0,
                     "vertical_vs_elastica": at_k(ratio_ev) - 1.0,
                     "horizontal_vs_elastica": at_k(ratio_eu) - 1.0})
    return {"depth_cells": depth_cells, "steps": int(len(history)),
            "newton": int(history["newton_iterations"].sum()), "cuts": int(history["step_cuts"].sum()),
            "rows": rows}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--depth-cells", type=int, nargs="+", default=[4, 8, 16])
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--json", default=os.path.join(ROOT, "docs", "data", "cantilever_validation.json"))
    args = ap.parse_args()
    result = {"small": [], "large": []}
    with tempfile.TemporaryDirectory() as workdir:
        for n in args.depth_cells:
            result["small"].append(small_load(n, args.ranks, workdir))
            print(json.dumps(result["small"][-1]), flush=True)
        for n in args.depth_cells:
            result["large"].append(large_load(n, args.ranks, workdir))
            print(json.dumps({k: v for k, v in result["large"][-1].items() if k != "rows"}), flush=True)

    print("\nSmall load (k = 0.03): tip deflection against Timoshenko (bending + shear)\n")
    print("| cells per depth | tip deflection | Timoshenko | bending only | difference |")
    print("|---|---|---|---|---|")
    for r in result["small"]:
        print(f"| {r['depth_cells']} | {r['deflection']:.5e} | {r['timoshenko']:.5e} | {r['bending_only']:.5e} "
              f"| {r['error']:+.2%} |")
    print("\nLarge load: tip displacement / L against the inextensible elastica and Reissner's beam\n")
    header = " | ".join(f"MPM {r['depth_cells']} cells (v, u)" for r in result["large"])
    print(f"| k | elastica (v, u) | Reissner (v, u) | {header} |")
    print("|---|---|---|" + "---|" * len(result["large"]))
    for i, row in enumerate(result["large"][0]["rows"]):
        cells = " | ".join(f"{r['rows'][i]['vertical']:.4f}, {r['rows'][i]['horizontal']:.4f} "
                           f"({r['rows'][i]['vertical_vs_reissner']:+.2%}, "
                           f"{r['rows'][i]['horizontal_vs_reissner']:+.2%})" for r in result["large"])
        print(f"| {row['k']} | {row['elastica_tip'][0]:.4f}, {row['elastica_tip'][1]:.4f} | "
              f"{row['reissner'][0]:.4f}, {row['reissner'][1]:.4f} | {cells} |")
    print("\n(elastica and Reissner at the tip, s = L; MPM columns: v/L, u/L of the tip particles, at s = L - h/4,"
          " and in brackets the difference from Reissner's beam at that s)")
    with open(args.json, "w") as f:
        json.dump(result, f, indent=1)
    print(f"\nwritten: {args.json}")


if __name__ == "__main__":
    main()
