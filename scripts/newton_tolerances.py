#!/usr/bin/env python3
"""How tight must Newton converge? Runs whole problems with each pair of
SNES tolerances (-snes_rtol, -snes_atol on pimpm's dimensionless residual)
and compares the answers with a run converged far tighter (rtol 1e-13,
atol 1e-15), so that the defaults can be the loosest pair whose answers
agree to 1e-8 relative. Prints a table and writes JSON.

Problems (each the shipped input, its answer at the end):
  billet     inputs/billet.yaml (GIMP, quasi-static, 0.5 cm): bulge and platen force
  disks      inputs/colliding_disks.yaml (Newmark): kinetic and strain energy
  upsetting  inputs/upsetting.yaml at 1 mm cells (finite-strain J2): radius and platen force

(The dynamic billet is no use here: its steps are cut where the platen
crushes the corner, and which steps are cut changes with round-off, so
its answer moves by percents whatever the tolerance.)

    mpiexec -n 2 python scripts/newton_tolerances.py [--problems billet disks upsetting]
        [--json docs/data/newton_tolerances.json]
"""
import argparse
import json
import os
import sys

import petsc4py

petsc4py.init(sys.argv[:1])
import numpy as np  # noqa: E402
import yaml  # noqa: E402
from mpi4py import MPI  # noqa: E402
from petsc4py import PETSc  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
from pimpm import measures  # noqa: E402
from pimpm.analysis import Analysis  # noqa: E402
from pimpm.config import validate  # noqa: E402
from pimpm.simulation import Simulation  # noqa: E402

REFERENCE = ("1e-13", "1e-15")
CANDIDATES = [("1e-10", "1e-12"), ("1e-8", "1e-12"), ("1e-8", "1e-10"), ("1e-7", "1e-12"),
              ("1e-7", "1e-10"), ("1e-6", "1e-12"), ("1e-6", "1e-10"), ("1e-5", "1e-12"),
              ("1e-4", "1e-12")]


def problem(name):
    with open(os.path.join(ROOT, "inputs", {"billet": "billet.yaml", "disks": "colliding_disks.yaml",
                                            "upsetting": "upsetting.yaml"}[name])) as f:
        raw = yaml.safe_load(f)
    if name == "upsetting":               # linear shape functions, as documented
        raw["grid"]["shape_functions"] = "linear"
    if name == "upsetting":               # 1 mm cells
        raw["grid"]["cells"] = [c // 2 for c in raw["grid"]["cells"]]
    raw.pop("output", None)
    return raw


def answer(name, sim):
    if name == "disks":
        return {"kinetic_energy": sim.kinetic_energy(), "strain_energy": sim.strain_energy()}
    force = float(np.linalg.norm(sim.work.last_forces[sim.rigid_bodies[0].name]))
    if name == "upsetting":
        h = float(sim.grid.spacing[1])
        return {"radius": measures.midplane_radius(sim.particles["x"], sim.particles["body"], h,
                                                   comm=sim.comm), "force": force}
    return {"bulge": measures.bulge(sim), "force": force}


def run(name, rtol, atol):
    db = PETSc.Options()
    db.setValue("snes_rtol", rtol)
    db.setValue("snes_atol", atol)
    try:
        sim = Simulation(validate(problem(name)), MPI.COMM_WORLD)
        iterations = []

        class Count:
            def step(self, analysis, info):
                iterations.append(info["newton_iterations"])

            def __getattr__(self, _):
                return lambda *args: None

        status = Analysis(sim, [Count()]).run()
        result = {"status": status, "steps": len(iterations), "newton_iterations": int(sum(iterations))}
        result.update(answer(name, sim))
        sim.solver.destroy()
        return result
    finally:
        db.delValue("snes_rtol")
        db.delValue("snes_atol")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--problems", nargs="+", default=["billet", "disks", "upsetting"])
    parser.add_argument("--json", default=os.path.join(ROOT, "docs", "data", "newton_tolerances.json"))
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    out = {"reference": {"snes_rtol": REFERENCE[0], "snes_atol": REFERENCE[1]}, "ranks": comm.size,
           "problems": {}}
    for name in args.problems:
        reference = run(name, *REFERENCE)
        rows = []
        for rtol, atol in CANDIDATES:
            r = run(name, rtol, atol)
            r.update(snes_rtol=rtol, snes_atol=atol)
            r["max_relative_difference"] = max(
                abs(r[k] - reference[k]) / abs(reference[k]) for k in reference
                if k not in ("status", "steps", "newton_iterations"))
            rows.append(r)
        out["problems"][name] = {"reference": reference, "runs": rows}
        if comm.rank == 0:
            keys = [k for k in reference if k not in ("status", "steps", "newton_iterations")]
            print(f"\n{name}: reference (rtol {REFERENCE[0]}, atol {REFERENCE[1]}): "
                  f"{reference['newton_iterations']} Newton iterations in {reference['steps']} steps, "
                  + ", ".join(f"{k} {reference[k]:.10g}" for k in keys))
            print("| snes_rtol | snes_atol | steps | Newton iterations | largest relative difference |")
            print("|---|---|---|---|---|")
            for r in rows:
                print(f"| {r['snes_rtol']} | {r['snes_atol']} | {r['steps']} | {r['newton_iterations']} "
                      f"| {r['max_relative_difference']:.1e} |")
            sys.stdout.flush()
    if comm.rank == 0:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
