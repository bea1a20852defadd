#!/usr/bin/env python3
"""Guilkey & Weiss (2003) 5.1 billet validation: runs inputs/billet.yaml and
inputs/billet_dynamic.yaml (or reads existing results with --reuse), then
prints and saves the bulge (pimpm.measures: horizontal displacement of the
particle at the outer edge on the symmetry plane y = 0) and the platen force at 10-50%
compression, the Newton residual history of one step, and a figure.

    python scripts/billet_validation.py [--ranks 2] [--reuse] [--out docs]
"""
import argparse
import json
import os
import subprocess
import sys

import h5py
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
from pimpm.measures import bulge_from_fields, edge_particle_id   # noqa: E402

CASES = {"quasi-static": "billet.yaml", "dynamic": "billet_dynamic.yaml",
         "explicit": "billet_explicit.yaml"}
PLATEN_SPEED = 50.0          # cm/s (pseudo-time in the quasi-static case)
HALF_HEIGHT = 20.0           # cm
PAPER_BULGE_50 = {"quasi-static": 7.38, "dynamic": 7.44, "explicit": None}   # G&W 5.1.1 / 5.1.2, IMPM


def run_case(input_file, workdir, ranks, extra):
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    cmd = ["mpiexec", "-n", str(ranks), sys.executable, "-m", "pimpm",
           os.path.join(ROOT, "inputs", input_file), "--overwrite"] + extra
    print("$", " ".join(cmd), flush=True)
    log = open(os.path.join(workdir, input_file.replace(".yaml", ".log")), "w")
    subprocess.run(cmd, cwd=workdir, env=env, check=True, stdout=log, stderr=subprocess.STDOUT)


def analyse(directory):
    history = np.genfromtxt(os.path.join(directory, "history.csv"), delimiter=",", names=True)
    with h5py.File(os.path.join(directory, "results.h5"), "r") as f:
        steps = sorted(f["steps"])
        times = np.array([f["steps"][s].attrs["time"] for s in steps])
        first = f["steps"][steps[0]]["particles"]
        edge_id = edge_particle_id(first["id"][...], first["position"][:, :2], first["body"][...])
        rows = []

        def bulge_at(k):
            g = f["steps"][steps[k]]["particles"]
            return bulge_from_fields(g["id"][...], g["displacement"], edge_id)

        for fraction in (0.1, 0.2, 0.3, 0.4, 0.5):
            t = fraction * HALF_HEIGHT / PLATEN_SPEED
            # the implicit steps land on these times; the explicit (automatic
            # step) outputs bracket them: interpolate linearly in time
            k = min(max(int(np.searchsorted(times, t - 1e-12)), 1), len(times) - 1)
            w = float(np.clip((t - times[k - 1]) / (times[k] - times[k - 1]), 0.0, 1.0))
            bulge = (1 - w) * bulge_at(k - 1) + w * bulge_at(k)
            near = k if w > 0.5 else k - 1
            h = int(np.argmin(np.abs(history["time"] - t)))
            rows.append({"compression": fraction, "time": float(t),
                         "bulge_cm": bulge,
                         "platen_force_y": float(history["platen_force_y"][h]),
                         "max_von_mises": float(np.max(f["steps"][steps[near]]["particles"]["von_mises"][...]))})
        last = f["steps"][steps[-1]]["particles"]
        shape = {"position": last["position"][:, :2].tolist(), "von_mises": last["von_mises"][...].tolist(),
                 "body": last["body"][...].tolist()}
    newton = history["newton_iterations"]
    return rows, shape, {"steps": int(len(history)), "newton_total": int(newton.sum()),
                         "newton_mean": float(newton.mean()),
                         "wall_time_s": float(history["wall_time"].sum())}


def residual_history(input_file, workdir, step):
    """Residual norms of Newton iterations at one step (serial rerun up to it)."""
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    code = f"""
import petsc4py; petsc4py.init([])
from pimpm.analysis import Observer, run_to_end
from pimpm.config import load_config
class Last(Observer):
    def step(self, analysis, info):
        self.residuals = list(info['residual_history'])
last = Last()
run_to_end(load_config({os.path.join(ROOT, 'inputs', input_file)!r}), observers=[last], max_steps={step})
print(last.residuals)
"""
    out = subprocess.run([sys.executable, "-c", code], cwd=workdir, env=env, check=True,
                         capture_output=True, text=True).stdout
    return [float(v) for v in out.strip().splitlines()[-1].strip("[]").split(",")]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--reuse", action="store_true", help="analyse existing results in --workdir")
    ap.add_argument("--run", nargs="+", choices=list(CASES), default=list(CASES),
                    help="cases to run (the others are read from --workdir)")
    ap.add_argument("--workdir", default=os.path.join(ROOT, "runs"))
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "data"))
    args, extra = ap.parse_known_args()
    os.makedirs(args.workdir, exist_ok=True)
    summary = {}
    for name, input_file in CASES.items():
        directory = os.path.join(args.workdir, input_file.replace(".yaml", "_output"))
        if not args.reuse and name in args.run:
            run_case(input_file, args.workdir, args.ranks, extra)
        rows, shape, stats = analyse(directory)
        summary[name] = {"rows": rows, "stats": stats, "shape": shape}
    summary["quasi-static"]["residual_history_step_10"] = residual_history("billet.yaml", args.workdir, 10)

    print("\n| compression | platen travel (cm) | bulge QS (cm) | platen force QS (dyne/cm) | "
          "bulge dynamic (cm) | platen force dynamic (dyne/cm) | bulge explicit (cm) | "
          "platen force explicit (dyne/cm) |")
    print("|---|---|---|---|---|---|---|---|")
    for qs, dyn, ex in zip(*(summary[name]["rows"] for name in CASES)):
        print(f"| {qs['compression']:.0%} | {qs['compression'] * HALF_HEIGHT:.0f} | {qs['bulge_cm']:.3f} | "
              f"{-qs['platen_force_y']:.4e} | {dyn['bulge_cm']:.3f} | {-dyn['platen_force_y']:.4e} | "
              f"{ex['bulge_cm']:.3f} | {-ex['platen_force_y']:.4e} |")
    for name in CASES:
        s = summary[name]["stats"]
        print(f"{name}: {s['steps']} steps, {s['newton_total']} Newton iterations "
              f"({s['newton_mean']:.1f} per step), {s['wall_time_s']:.1f} s in steps"
              + (f"; paper's IMPM bulge at 50%: {PAPER_BULGE_50[name]} cm" if PAPER_BULGE_50[name] else ""))
    print("Newton residuals, quasi-static step 10:",
          " ".join(f"{r:.3e}" for r in summary["quasi-static"]["residual_history_step_10"]))

    os.makedirs(os.path.join(args.out, "figures"), exist_ok=True)
    slim = {k: {kk: vv for kk, vv in v.items() if kk != "shape"} for k, v in summary.items()}
    with open(os.path.join(args.out, "validation_billet.json"), "w") as f:
        json.dump(slim, f, indent=1)
    plot(summary, os.path.join(args.out, "figures", "billet.png"))


def plot(summary, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(2, 2, figsize=(13, 10))
    for ax, name in zip(axes[0], CASES):
        shape = summary[name]["shape"]
        x = np.array(shape["position"])
        vm = np.array(shape["von_mises"])
        body = np.array(shape["body"])
        m = body == 0
        sc = ax.scatter(x[m, 0], x[m, 1], c=vm[m], s=0.3, cmap="viridis")
        ax.scatter(x[~m, 0], x[~m, 1], c="k", s=0.5)
        ax.set_aspect("equal")
        ax.set_title(f"{name} billet at 50% compression (von Mises, dyne/cm$^2$)")
        fig.colorbar(sc, ax=ax, shrink=0.7)
    ax = axes[1][0]
    for name, marker in zip(CASES, ("o-", "s--", "^:")):
        rows = summary[name]["rows"]
        travel = [r["compression"] * HALF_HEIGHT for r in rows]
        ax.plot(travel, [r["bulge_cm"] for r in rows], marker, label=f"bulge, {name}")
    ax.plot([10], [PAPER_BULGE_50["quasi-static"]], "k*", ms=12, label="G&W IMPM, quasi-static (7.38)")
    ax.plot([10], [PAPER_BULGE_50["dynamic"]], "kx", ms=10, label="G&W IMPM, dynamic (7.44)")
    ax.set_xlabel("platen travel (cm)")
    ax.set_ylabel("horizontal displacement of outer edge particle at y = 0 (cm)")
    ax.legend()
    ax2 = axes[1][1]
    for name, marker in zip(CASES, ("o-", "s--", "^:")):
        rows = summary[name]["rows"]
        ax2.plot([r["compression"] * HALF_HEIGHT for r in rows], [-r["platen_force_y"] for r in rows],
                 marker, label=name)
    ax2.set_xlabel("platen travel (cm)")
    ax2.set_ylabel("platen force per unit thickness, quarter model (dyne/cm)")
    ax2.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    print("figure:", path)


if __name__ == "__main__":
    main()
