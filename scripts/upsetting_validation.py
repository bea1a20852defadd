#!/usr/bin/env python3
"""Sulsky & Kaul (2004) 3.2.7 upsetting: inputs/upsetting.yaml (axisymmetric,
finite-strain J2, quasi-static) at 2, 1 and 0.5 mm cells (default) on 2 ranks, the
platen moving half a cell per step to 60% reduction. Prints load-deflection
data, the radius at mid-height and Newton iterations per step; writes
docs/data/validation_upsetting.json and docs/figures/upsetting.png.

    python scripts/upsetting_validation.py [--ranks 2] [--sizes 2 1 0.5]
        [--shape linear|gimp|bspline] [--contact bonded|frictionless|friction|tied --mu MU] [--no-docs]

A run that fails (pimpm exits 1 after its step cuts) is reported with the
reduction it reached. --no-docs prints the table only (docs/ untouched).
"""
import argparse
import copy
import json
import os
import subprocess
import sys
import tempfile

import h5py
import numpy as np
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
from pimpm.measures import midplane_radius               # noqa: E402


def case(h, shape=None, f_bar=None, contact=None, mu=None):
    with open(os.path.join(ROOT, "inputs", "upsetting.yaml")) as f:
        cfg = yaml.safe_load(f)
    cfg = copy.deepcopy(cfg)
    cfg["grid"]["cells"] = [int(round(24 / h)), int(round(17 / h))]
    cfg["bodies"][1]["geometry"] = {"type": "box", "lower": [0.0, 15.0], "upper": [23.0, 15.0 + h]}
    cfg["time"]["dt"] = 5.0e-4 * h          # half a cell per step at 1 m/s
    if shape is not None:                  # else the input's own
        cfg["grid"]["shape_functions"] = shape
    if f_bar is not None:                  # else the input's own
        cfg["materials"]["steel"]["f_bar"] = f_bar
    if contact is not None:                # else the input's tied platen
        cfg["bodies"][1]["contact"] = contact
        cfg["bodies"][1].pop("constrain", None)
        if contact == "friction":
            cfg["bodies"][1]["friction_coefficient"] = mu
    cfg["output"] = {"directory": "out", "every": 1}
    return cfg


def run(h, ranks, workdir, shape=None, f_bar=None, contact=None, mu=None):
    path = os.path.join(workdir, f"upsetting_{h}.yaml")
    with open(path, "w") as f:
        yaml.safe_dump(case(h, shape, f_bar, contact, mu), f)
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    sub = os.path.join(workdir, f"h{h}")
    os.makedirs(sub, exist_ok=True)
    cmd = ["mpiexec", "-n", str(ranks), sys.executable, "-m", "pimpm", path, "--overwrite"]
    print("$", " ".join(cmd), flush=True)
    proc = subprocess.run(cmd, cwd=sub, env=env, capture_output=True)
    hist = np.atleast_1d(np.genfromtxt(os.path.join(sub, "out", "history.csv"), delimiter=",", names=True))
    if proc.returncode != 0:                 # numerical failure: the reduction it reached
        return {"h": h, "failed": True, "steps": int(len(hist)),
                "reduction_reached": float(1000.0 * hist["time"][-1] / 15.0)}
    with h5py.File(os.path.join(sub, "out", "results.h5"), "r") as f:
        last = f["steps"][sorted(f["steps"])[-1]]["particles"]
        x, body = last["position"][:, :2], last["body"][...]
        eps_p = last["eq_plastic_strain"][...]
        J = last["J"][...]
    cyl = body == 0
    travel = 1000.0 * hist["time"]
    reduction, force = travel / 15.0, -hist["platen_force_y"] / 1000.0
    late = reduction >= 0.3 - 1e-9                        # the last half of the travel
    fit = np.polyval(np.polyfit(reduction[late], force[late], 2), reduction[late])
    return {"h": h, "steps": int(len(hist)), "newton_per_step": float(hist["newton_iterations"].mean()),
            "step_cuts": int(hist["step_cuts"].sum()), "wall_s": float(hist["wall_time"].sum()),
            "radius_mid_height_mm": midplane_radius(x, body, h), "final_half_height_mm": float(x[cyl, 1].max()),
            "max_eq_plastic_strain": float(eps_p[cyl].max()),
            "J_range": [float(J[cyl].min()), float(J[cyl].max())],
            # the smooth trend at 60% (a quadratic through the loads from 30% on) and
            # how far the loads of single steps scatter about it (RMS, relative)
            "force_trend_60_kN": float(np.polyval(np.polyfit(reduction[late], force[late], 2), 0.6)),
            "force_scatter": float(np.sqrt(np.mean((force[late] - fit) ** 2)) / np.mean(fit)),
            "J_off_by_1_percent": float(np.mean(np.abs(J[cyl] - np.median(J[cyl])) > 0.01)),
            "reduction": (travel / 15.0).tolist(), "force_kN": (-hist["platen_force_y"] / 1000.0).tolist(),
            "x": x[cyl].tolist(), "eps_p": eps_p[cyl].tolist()}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--sizes", type=float, nargs="+", default=[2.0, 1.0, 0.5])
    ap.add_argument("--shape", default=None, choices=["linear", "gimp", "bspline"],
                    help="shape functions (default: the input's, GIMP)")
    ap.add_argument("--f-bar", choices=["on", "off", "cells", "nodes"], default=None,
                    help="F-bar on the steel: on (= cells), off, or what it averages over (default: the input's)")
    ap.add_argument("--contact", choices=["bonded", "frictionless", "friction", "tied"], default=None,
                    help="the platen's contact law (default: the input's, tied)")
    ap.add_argument("--mu", type=float, default=None, help="the friction coefficient of --contact friction")
    ap.add_argument("--no-docs", action="store_true")
    args = ap.parse_args()
    if (args.contact == "friction") != (args.mu is not None):
        ap.error("--mu goes with --contact friction, and only with it")
    results = []
    with tempfile.TemporaryDirectory() as workdir:
        for h in args.sizes:
            f_bar = {None: None, "on": True, "off": False}.get(args.f_bar, args.f_bar)
            results.append(run(h, args.ranks, workdir, args.shape, f_bar, args.contact, args.mu))
    failed = [r for r in results if r.get("failed")]
    results = [r for r in results if not r.get("failed")]
    for r in failed:
        print(f"h = {r['h']:g} mm ({args.shape or 'as in the input'}): failed after {r['steps']} steps at "
              f"{100 * r['reduction_reached']:.1f}% reduction")
    if not results:
        return
    print("\n| cell size (mm) | steps | Newton its per step | radius at mid-height (mm) | "
          "final half height (mm) | force at 60% (kN) | trend at 60% (kN) | step scatter | "
          "max eq. plastic strain | particle J | "
          "J off its median by > 1% | step cuts | time in steps (s) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in results:
        print(f"| {r['h']:g} | {r['steps']} | {r['newton_per_step']:.1f} | {r['radius_mid_height_mm']:.2f} | "
              f"{r['final_half_height_mm']:.2f} | {r['force_kN'][-1]:.0f} | {r['force_trend_60_kN']:.0f} | "
              f"{100 * r['force_scatter']:.1f}% | {r['max_eq_plastic_strain']:.2f} | "
              f"{r['J_range'][0]:.3f}-{r['J_range'][1]:.3f} | {100 * r['J_off_by_1_percent']:.0f}% | "
              f"{r['step_cuts']} | {r['wall_s']:.1f} |")
    if args.no_docs or not results:
        return
    with open(os.path.join(ROOT, "docs", "data", "validation_upsetting.json"), "w") as f:
        json.dump([{k: v for k, v in r.items() if k not in ("x", "eps_p")} for r in results], f, indent=1)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.5))
    for r in results:
        a.plot(100 * np.array(r["reduction"]), r["force_kN"], label=f"h = {r['h']:g} mm")
    a.axhline(1050, color="k", ls=":", lw=0.8)
    a.axhline(800, color="k", ls="--", lw=0.8)
    a.text(2, 1060, "paper, coarse mesh ~1050 kN", fontsize=8)
    a.text(2, 810, "paper, converging to ~800 kN", fontsize=8)
    a.set_xlabel("height reduction (%)")
    a.set_ylabel("platen force (kN)")
    a.legend()
    fine = results[-1]
    xy = np.array(fine["x"])
    sc = b.scatter(xy[:, 0], xy[:, 1], c=fine["eps_p"], s=2, cmap="inferno")
    b.set_aspect("equal")
    b.set_xlabel("r (mm)")
    b.set_ylabel("z (mm)")
    b.set_title(f"equivalent plastic strain at 60% (h = {fine['h']:g} mm)")
    fig.colorbar(sc, ax=b)
    fig.tight_layout()
    fig.savefig(os.path.join(ROOT, "docs", "figures", "upsetting.png"), dpi=80)
    print("figure: docs/figures/upsetting.png")


if __name__ == "__main__":
    main()
