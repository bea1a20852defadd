"""The contact benchmarks of docs/VALIDATION.md ("Rigid tools that let go
and slide"), refined in h and dt: a plate that lets go, a block on a ramp,
the same on an inclined ramp, friction onset, the frictionless upsetting
against its homogeneous answer, and the billet with a frictional platen.
Prints a table per benchmark and writes the numbers as JSON.

    python scripts/contact_validation.py [--json docs/data/validation_contact.json]

Serial (one rank; the tests check 1-4 ranks); about eight minutes."""
import argparse
import json
import os
import sys
import time

import numpy as np
import petsc4py

petsc4py.init(sys.argv[:1])
from mpi4py import MPI  # noqa: E402

from pimpm.analysis import Observer, Trace, run_to_end  # noqa: E402
from pimpm.config import load_config  # noqa: E402
from pimpm.measures import mean_displacement  # noqa: E402
from pimpm.reference import homogeneous_upsetting  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
INPUTS = os.path.join(os.path.dirname(HERE), "inputs")


class Rows(Observer):
    """Per step: time, the first rigid body's force and displacement, Newton
    iterations, the mass-weighted mean displacement and velocity in x."""

    def __init__(self):
        self.rows = []

    def step(self, analysis, info):
        sim = analysis.sim
        p = sim.particles
        tool = sim.rigid_bodies[0].name
        mass = sim.mass0
        self.rows.append({
            "time": sim.time, "force": [float(f) for f in info["forces"][tool]],
            "tool": [float(u) for u in info["displacements"][tool]],
            "newton": int(info["newton_iterations"]),
            "mean_x": sim.comm.allreduce(float(np.sum(p["mass"] * (p["x"][:, 0] - p["x0"][:, 0])))) / mass,
            "mean_v": sim.comm.allreduce(float(np.sum(p["mass"] * p["v"][:, 0]))) / mass,
            "contact": info.get("contact", {}).get(tool, {}),
            "dissipation": info.get("frictional_dissipation", 0.0),
            "energy_balance": info["kinetic_energy"] + info["strain_energy"] - info["external_work"]
            + info.get("frictional_dissipation", 0.0),
            "external_work": info["external_work"]})


def run(name, overrides):
    rows = Rows()
    start = time.perf_counter()
    sim, stats, status = run_to_end(load_config(os.path.join(INPUTS, name), overrides), observers=[rows])
    wall = time.perf_counter() - start
    newton = [r["newton"] for r in rows.rows]
    return sim, rows.rows, {"cuts": stats.cuts, "failed": stats.failure, "steps": len(rows.rows),
                            "newton_mean": float(np.mean(newton)) if newton else 0.0,
                            "newton_max": int(max(newton)) if newton else 0, "wall_s": wall}


def plate():
    out = []
    E, width, height = 1.0e6, 0.8, 0.8
    for cells, dt in (([10, 12], 1.0), ([10, 12], 0.5), ([20, 24], 1.0), ([20, 24], 0.5)):
        sim, rows, info = run("plate_release.yaml", [f"grid.cells={cells}", f"time.dt={dt}"])
        loading = [r for r in rows if r["time"] <= 20.0 + 1e-9]
        errors = []
        for r in loading:
            stretch = (height + r["tool"][1]) / height
            exact = 0.5 * E * (stretch ** 2 - 1.0) / stretch
            if abs(exact) > 0:
                errors.append(abs(r["force"][1] / width - exact) / abs(exact))
        released = [r for r in rows if r["time"] > 40.0 + 1e-9]
        out.append(dict(info, h=1.0 / cells[0], dt=dt, stress_error_max=max(errors),
                        force_after_release=max(abs(r["force"][1]) for r in released)))
    return out


def ramp():
    out = []
    g, angle = 9.80665, np.radians(30.0)
    for mu in (0.0, 0.3, 0.7):
        for cells, dt in (([24, 12], 1e-3), ([24, 12], 5e-4), ([48, 24], 1e-3), ([48, 24], 5e-4)):
            sim, rows, info = run("block_on_ramp.yaml", [f"bodies[1].friction_coefficient={mu}",
                                                         f"grid.cells={cells}", f"time.dt={dt}"])
            t = np.array([0.0] + [r["time"] for r in rows])
            x = np.array([0.0] + [r["mean_x"] for r in rows])
            a = 2.0 * np.polyfit(t, x, 2)[0]
            exact = max(g * (np.sin(angle) - mu * np.cos(angle)), 0.0)
            out.append(dict(info, mu=mu, h=0.06 / cells[0], dt=dt, acceleration=a, exact=exact,
                            error=(a - exact) / exact if exact else None, drift=float(x[-1])))
    return out


def incline():
    """Benchmark 1's other variant: the block seeded turned by 30 degrees on
    an inclined half-space under vertical gravity (inputs/block_on_incline.yaml);
    the acceleration fitted to the mean displacement along the ramp."""
    out = []
    g, angle = 9.80665, np.radians(30.0)
    down = np.array([np.cos(angle), -np.sin(angle)])
    for mu in (0.0, 0.3, 0.7):
        for cells, dt in (([32, 28], 1e-3), ([32, 28], 5e-4)):
            along = Trace(lambda sim: mean_displacement(sim, down))
            rows = Rows()
            start = time.perf_counter()
            sim, stats, status = run_to_end(load_config(os.path.join(INPUTS, "block_on_incline.yaml"),
                                                        [f"bodies[1].friction_coefficient={mu}",
                                                         f"grid.cells={cells}", f"time.dt={dt}"]),
                                            observers=[rows, along])
            t, s = np.array(along.values).T
            a = 2.0 * np.polyfit(t, s, 2)[0]
            exact = max(g * (np.sin(angle) - mu * np.cos(angle)), 0.0)
            newton = [r["newton"] for r in rows.rows]
            out.append({"mu": mu, "h": 0.08 / cells[0], "dt": dt, "steps": len(rows.rows), "cuts": stats.cuts,
                        "newton_mean": float(np.mean(newton)), "newton_max": int(max(newton)),
                        "acceleration": a, "exact": exact, "error": (a - exact) / exact if exact else None,
                        "drift": float(s[-1]), "wall_s": time.perf_counter() - start})
    return out


def onset():
    out = []
    for dt in (0.1, 0.05, 0.025):
        sim, rows, info = run("friction_onset.yaml", [f"time.dt={dt}"])
        stick = 1e-3 * 0.25
        # sticking, it moves at most its elastic slip; the first step of slip at dt = 0.1
        # takes it to 1.5 x stick (tests/test_contact.py)
        first = next(r["time"] for r in rows if r["mean_x"] > 1.2 * stick)
        last = rows[-1]
        out.append(dict(info, dt=dt, onset=first, velocity_2s=last["mean_v"], slip_2s=last["mean_x"] - stick,
                        dissipation=last["dissipation"],
                        energy_balance=last["energy_balance"] / last["external_work"]))
    return out


def upsetting():
    out = []
    exact, J = homogeneous_upsetting(6.0)
    cases = [(2.0, "linear", "frictionless", None), (1.0, "linear", "frictionless", None),
             (0.5, "linear", "frictionless", None), (1.0, "linear", "friction", 0.1),
             (1.0, "linear", "bonded", None)]
    cases += [(1.0, "gimp", contact, mu) for contact, mu in (("frictionless", None), ("friction", 0.1),
                                                              ("friction", 0.3), ("bonded", None))]
    for size, shape, contact, mu in cases:
        cells = [int(24 / size), int(17 / size)]
        overrides = [f"grid.cells={cells}", f"time.dt={5e-4 * size}", f"bodies[1].contact={contact}",
                     f"grid.shape_functions={shape}"]
        if contact == "friction":
            overrides.append(f"bodies[1].friction_coefficient={mu}")
        sim, rows, info = run("upsetting.yaml", overrides)
        p = sim.particles
        x = p["x"]
        top = float(np.max(x[:, 1]))
        J_p = np.linalg.det(p["F"])
        out.append(dict(info, size=size, shape=shape, contact=contact, mu=mu,
                        force=-rows[-1]["force"][1] / 1000.0, exact=exact / 1000.0,
                        error=(-rows[-1]["force"][1] - exact) / exact,
                        radius_mid=float(np.max(x[x[:, 1] < 0.25 * top, 0])),
                        radius_top=float(np.max(x[x[:, 1] > 0.75 * top, 0])),
                        J_min=float(J_p.min()), J_max=float(J_p.max()), J_exact=J))
    return out


def billet():
    """Benchmark 5: Guilkey & Weiss's billet with a frictional platen (mu =
    0.1, 0.3, 1) and bonded, at 1 and 0.5 cm cells, to 50%; then at 0.5 cm
    and mu = 0.3 the cost of the regularization of stick: the tangential
    stiffness cap (x M / h) against the uncapped law, each run's forces at
    10% (t = 0.04, which every variant reaches) and how far it got."""
    out, study = [], []
    for cells in ([40, 21], [80, 42]):
        for mu in (0.1, 0.3, 1.0, None):
            overrides = [f"grid.cells={cells}"]
            if mu is not None:
                overrides += ["bodies[1].contact=friction", f"bodies[1].friction_coefficient={mu}"]
            sim, rows, info = run("billet.yaml", overrides)
            x = sim.particles["x"]
            top = float(np.max(x[:, 1]))
            last = rows[-1]
            out.append(dict(info, h=40.0 / cells[0], mu=mu if mu is not None else "bonded",
                            force=-last["force"][1] / 1e8, tangential=-last["force"][0] / 1e8,
                            barrel=float(np.max(x[x[:, 1] < 0.25 * top, 0]) - np.max(x[x[:, 1] > 0.75 * top, 0])),
                            contact_length=last["contact"].get("contact_area", float("nan"))))
    for name, overrides in (("uncapped, slip_tolerance 5e-3", ["bodies[1].tangential_stiffness=1e12",
                                                                "bodies[1].slip_tolerance=5e-3"]),
                            ("uncapped (slip_tolerance 1e-3)", ["bodies[1].tangential_stiffness=1e12"]),
                            ("tangential_stiffness 1", ["bodies[1].tangential_stiffness=1"]),
                            ("tangential_stiffness 0.3 (default)", []),
                            ("tangential_stiffness 0.1", ["bodies[1].tangential_stiffness=0.1"])):
        sim, rows, info = run("billet.yaml", ["bodies[1].contact=friction", "bodies[1].friction_coefficient=0.3"]
                              + overrides)
        times = np.array([r["time"] for r in rows])
        reached = float(times[-1]) if len(rows) else 0.0

        def at_20(k):
            if reached < 0.04 - 1e-12:
                return float("nan")
            return float(np.interp(0.04, times, [-r["force"][k] / 1e8 for r in rows]))
        study.append(dict(info, law=name, reached=reached, force_20=at_20(1), tangential_20=at_20(0)))
    return out, study


def table(title, rows, columns):
    print(f"\n{title}")
    print("| " + " | ".join(columns) + " |")
    print("|" + "---|" * len(columns))
    for row in rows:
        cells = []
        for c in columns:
            v = row.get(c)
            cells.append(f"{v:.4g}" if isinstance(v, float) else str(v))
        print("| " + " | ".join(cells) + " |")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", default=os.path.join(os.path.dirname(HERE), "docs", "data",
                                                       "validation_contact.json"))
    args = parser.parse_args()
    results = {"plate": plate(), "ramp": ramp(), "onset": onset(), "upsetting": upsetting()}
    results["incline"] = incline()
    results["billet"], results["billet_regularization"] = billet()
    if MPI.COMM_WORLD.rank == 0:
        table("A rigid plate that lets go", results["plate"],
              ["h", "dt", "steps", "cuts", "newton_mean", "newton_max", "stress_error_max", "force_after_release"])
        table("Block on a ramp (floor, gravity tilted 30 degrees)", results["ramp"],
              ["mu", "h", "dt", "cuts", "newton_mean", "newton_max", "acceleration", "exact", "error", "drift"])
        table("Block on an inclined ramp (the block turned by 30 degrees, vertical gravity)", results["incline"],
              ["mu", "h", "dt", "steps", "cuts", "newton_mean", "newton_max", "acceleration", "exact", "error",
               "drift"])
        table("Friction onset", results["onset"],
              ["dt", "cuts", "newton_mean", "newton_max", "onset", "velocity_2s", "slip_2s", "dissipation",
               "energy_balance"])
        table("Upsetting at 60%", results["upsetting"],
              ["size", "shape", "contact", "mu", "steps", "cuts", "newton_mean", "force", "exact", "error", "radius_mid",
               "radius_top", "J_min", "J_max"])
        table("Billet at 50% (forces in kN per cm of thickness)", results["billet"],
              ["h", "mu", "steps", "cuts", "newton_mean", "newton_max", "force", "tangential", "barrel",
               "contact_length"])
        table("Billet, mu = 0.3, 0.5 cm: the regularization of stick (forces at 10%, t = 0.04)",
              results["billet_regularization"],
              ["law", "steps", "cuts", "newton_mean", "newton_max", "reached", "force_20", "tangential_20"])
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1, default=str)
        print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
