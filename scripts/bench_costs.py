#!/usr/bin/env python3
"""Implicit against explicit MPM, measured in one run on one machine (cf.
Sulsky & Kaul 2004, Tables 1-2, and Guilkey & Weiss 5.1.2).

For each problem the explicit step dt_e = cfl * h / (c + |v|) (cfl 0.5) is
computed, the explicit run is timed, and the implicit (trapezoidal) run is
timed at 1x, 10x, 100x (and 1000x) dt_e, ramping up from dt_e by 20% per
step as Sulsky & Kaul do; failing steps are cut and retried by pimpm, so
the table also gives the largest step actually taken. Upsetting (Sulsky &
Kaul 3.2.7) is also run quasi-static at its input's step. Prints a table (dt, steps, Newton and linear
iterations, wall time, cost ratio = implicit wall time / explicit wall time)
and writes JSON; also draws the colliding-disk energy histories.

    python scripts/bench_costs.py [--ranks 1] [--json docs/data/bench_costs.json]
                                  [--figure docs/figures/colliding_disks_energy.png]
"""
import argparse
import copy
import json
import os
import subprocess
import sys
import tempfile

import numpy as np
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# Sulsky & Kaul's cost ratios (operation counts, Newton-CG) for reference
PAPER = {"bar": {1: "1.7", 10: "0.34", 100: "0.10"},
         "disks": {1: "> 3", 10: "~1", 100: "< 1"}}


def load(name):
    with open(os.path.join(ROOT, "inputs", name)) as f:
        return yaml.safe_load(f)


def problems(shape="linear"):
    """The problems; the billet and the upsetting with ``shape`` functions
    (linear, as in docs/PERFORMANCE.md, unless --shape says otherwise)."""
    bar = load("bar_tension.yaml")
    bar["title"] = "elastic bar in tension, dynamic"
    disks = load("colliding_disks.yaml")
    billet = load("billet_dynamic.yaml")
    # the cost comparison uses the 1 cm billet (half the paper's resolution)
    billet["grid"].update(upper=[36.0, 22.0], cells=[36, 22])
    billet["bodies"][1]["geometry"].update(upper=[35.0, 21.0])
    upsetting = load("upsetting.yaml")      # axisymmetric, finite-strain J2, 1 mm cells
    for config in (billet, upsetting):
        config["grid"]["shape_functions"] = shape
    # implicit runs: (integrator, multiple of the explicit step); upsetting is
    # also run quasi-static at the input's step (inertia is negligible at 1 m/s)
    newmark = lambda factors: [("newmark", k) for k in factors]
    return {"bar": (bar, newmark([1, 10, 100, 1000])), "disks": (disks, newmark([1, 10, 100])),
            "billet": (billet, newmark([10, 52])),
            "upsetting": (upsetting, newmark([100, 1000]) + [("quasi_static", None)])}


def wave_step(config):
    """The explicit step pimpm would take at t = 0 (cfl 0.5)."""
    code = ("import petsc4py; petsc4py.init([]); import sys, yaml; from mpi4py import MPI;"
            "from pimpm.config import validate; from pimpm.simulation import Simulation;"
            "cfg = validate(yaml.safe_load(sys.stdin)); cfg['time']['dt'] = None;"
            "print(Simulation(cfg, MPI.COMM_WORLD).stable_time_step())")
    explicit = copy.deepcopy(config)
    explicit["time"] = {"integrator": "explicit", "end_time": config["time"]["end_time"]}
    out = subprocess.run([sys.executable, "-c", code], input=yaml.safe_dump(explicit), text=True,
                         capture_output=True, check=True, env=env()).stdout
    return float(out.strip().splitlines()[-1])


def env():
    return dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")


def run(config, ranks, workdir, name):
    config = copy.deepcopy(config)
    config["output"] = {"directory": name, "every": 1000000}
    path = os.path.join(workdir, name + ".yaml")
    with open(path, "w") as f:
        yaml.safe_dump(config, f)
    cmd = ["mpiexec", "-n", str(ranks), sys.executable, "-m", "pimpm", path, "--overwrite"]
    proc = subprocess.run(cmd, cwd=workdir, env=env(), capture_output=True, text=True)
    if proc.returncode != 0:
        return {"ok": False, "error": (proc.stdout + proc.stderr)[-500:]}
    h = np.atleast_1d(np.genfromtxt(os.path.join(workdir, name, "history.csv"), delimiter=",",
                                    names=True))
    return {"ok": True, "steps": int(len(h)), "newton": int(h["newton_iterations"].sum()),
            "linear": int(h["linear_iterations"].sum()), "cuts": int(h["step_cuts"].sum()),
            "wall_s": float(h["wall_time"].sum()), "dt_max": float(h["dt"].max()),
            "time": h["time"].tolist(), "kinetic": h["kinetic_energy"].tolist(),
            "strain": h["strain_energy"].tolist()}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ranks", type=int, default=1)
    ap.add_argument("--json", default=os.path.join(ROOT, "docs", "data", "bench_costs.json"))
    ap.add_argument("--figure", default=os.path.join(ROOT, "docs", "figures", "colliding_disks_energy.png"))
    ap.add_argument("--problems", nargs="+", default=["bar", "disks", "billet", "upsetting"])
    ap.add_argument("--shape", choices=["linear", "gimp", "bspline"], default="linear",
                    help="shape functions of the billet and the upsetting (default: linear, as documented)")
    args = ap.parse_args()
    rows, curves = [], {}
    with tempfile.TemporaryDirectory() as workdir:
        for name, (config, factors) in problems(args.shape).items():
            if name not in args.problems:
                continue
            dt_e = wave_step(config)
            explicit = copy.deepcopy(config)
            explicit["time"] = {"integrator": "explicit", "end_time": config["time"]["end_time"]}
            ex = run(explicit, args.ranks, workdir, f"{name}_explicit")
            rows.append(dict(problem=name, method="explicit", factor=1, dt=dt_e, **_short(ex)))
            curves[(name, "explicit")] = ex
            print(json.dumps(rows[-1]), flush=True)
            for integrator, k in factors:
                implicit = copy.deepcopy(config)
                if k is None:                 # the input's own step
                    k = config["time"]["dt"] / dt_e
                    implicit["time"] = dict(config["time"], integrator=integrator)
                else:
                    implicit["time"] = {"integrator": integrator, "end_time": config["time"]["end_time"],
                                        "dt": k * dt_e, "dt_initial": dt_e, "ramp_factor": 1.2,
                                        "easy_newton_iterations": 30}
                    if name == "billet":       # G&W: the platen crosses half a cell per step from the start
                        implicit["time"].pop("dt_initial")
                label = f"{name}_{integrator}_{k:.0f}"
                im = run(implicit, args.ranks, workdir, label)
                ratio = im["wall_s"] / ex["wall_s"] if im.get("ok") and ex.get("ok") else None
                rows.append(dict(problem=name, method=integrator, factor=round(k), dt=k * dt_e,
                                 cost_ratio=ratio, **_short(im)))
                curves[(name, f"implicit {k:.0f}x")] = im
                print(json.dumps(rows[-1]), flush=True)
    if os.path.exists(args.json):     # keep the rows of problems not run this time
        with open(args.json) as f:
            kept = [r for r in json.load(f) if r["problem"] not in args.problems]
        rows = kept + rows
    with open(args.json, "w") as f:
        json.dump(rows, f, indent=1)
    print_table(rows)
    plot_disks(curves, args.figure)


def _short(result):
    return {k: v for k, v in result.items() if k not in ("time", "kinetic", "strain")}


def print_table(rows):
    print("\n| problem | method | dt / dt_explicit | dt | steps | Newton its | linear its | "
          "wall time (s) | cost ratio vs explicit | Sulsky & Kaul's ratio |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        if not r.get("ok"):
            print(f"| {r['problem']} | {r['method']} | {r['factor']} | {r['dt']:.3g} | failed | | | | | |")
            continue
        ratio = "1" if r["method"] == "explicit" else f"{r['cost_ratio']:.3f}"
        paper = PAPER.get(r["problem"], {}).get(r["factor"], "") if r["method"] != "explicit" else ""
        print(f"| {r['problem']} | {r['method']} | {r['factor']} | {r['dt']:.3g} | {r['steps']} | "
              f"{r['newton']} | {r['linear']} | {r['wall_s']:.2f} | {ratio} | {paper} |")
    print("\n| problem | largest implicit step run to the end (x explicit) | largest step taken "
          "(x explicit) | step cuts | cost ratio there |")
    print("|---|---|---|---|---|")
    for problem in dict.fromkeys(r["problem"] for r in rows):
        done = [r for r in rows if r["problem"] == problem and r["method"] != "explicit" and r.get("ok")]
        explicit = [r for r in rows if r["problem"] == problem and r["method"] == "explicit"]
        if not done or not explicit:
            continue
        best = max(done, key=lambda r: r["factor"])
        dt_e = explicit[0]["dt"]
        print(f"| {problem} | {best['factor']} ({best['method']}) | {best['dt_max'] / dt_e:.0f} | "
              f"{best['cuts']} | {best['cost_ratio']:.3f} |")


def plot_disks(curves, path):
    keys = [k for k in curves if k[0] == "disks" and curves[k].get("ok")]
    if len(keys) < 2:                 # the disks were not run: keep the existing figure
        return
    if not keys:
        return
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(keys), figsize=(4.2 * len(keys), 3.6), sharey=True)
    for ax, key in zip(np.atleast_1d(axes), keys):
        c = curves[key]
        t, ke, se = np.array(c["time"]), np.array(c["kinetic"]), np.array(c["strain"])
        ax.plot(t, ke, label="kinetic")
        ax.plot(t, se, "--", label="strain")
        ax.plot(t, ke + se, "k", label="total")
        ax.set_title(key[1])
        ax.set_xlabel("time")
    np.atleast_1d(axes)[0].set_ylabel("energy")
    np.atleast_1d(axes)[0].legend()
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    print("figure:", path)


if __name__ == "__main__":
    main()
