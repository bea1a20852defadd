"""Where the implicit head-on disks lose their energy (issue 30,
docs/VALIDATION.md "Two disks colliding head-on"): the total energy over
the start's when contact engages, when it ends, 0.7 time units after it
ended (no contact: the integrator alone) and at t = 8, for the trapezoidal
rule at 20 cells (dt 0.1 and 0.02) and 40 cells (dt 0.05); the same for
the mirror image of the impact, one disk against a rigid frictionless
wall on the symmetry plane (an independent contact: the rigid tools'), and
the energy of the explicit runs of both at the end.

    python scripts/disk_energy_history.py [--json FILE]

One rank, a few minutes."""
import argparse
import json
import os
import sys

import petsc4py

petsc4py.init(sys.argv[:1])
from mpi4py import MPI  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from body_contact_validation import disks_config, march, mirror_config  # noqa: E402
from pimpm.simulation import Simulation  # noqa: E402

CASES = ((20, 0.1), (20, 0.02), (40, 0.05))


def energy_history(config, end_time=8.0):
    """(t, E/E0) when contact engages, at its last step in contact, 0.7
    after that, and at the end; E the kinetic plus strain energy."""
    sim = Simulation(config, MPI.COMM_SELF)
    start = sim.kinetic_energy() + sim.strain_energy()
    rows, first, last = [], None, None
    for info, _ in march(sim, end_time):
        energy = (info["kinetic_energy"] + info["strain_energy"]) / start
        if any(values["contact_points"] for values in info["contact"].values()):
            first = first or (sim.time, energy)
            last = (sim.time, energy)
        rows.append((sim.time, energy))
    after = [r for r in rows if r[0] <= last[0] + 0.7 + 1e-9][-1]
    return {"engages": first, "ends": last, "after": after, "end": rows[-1]}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", help="write the numbers here")
    args = parser.parse_args()
    results = []
    print("| cells | dt | contact | contact engages (t, energy) | contact ends (t, energy) | 0.7 later | t = 8 |")
    print("|---|---|---|---|---|---|---|")
    for cells, dt in CASES + ((20, None), (40, None)):
        integrator = "newmark" if dt else "explicit"
        for contact, make in (("pair", disks_config), ("wall", mirror_config)):
            row = energy_history(make(cells, integrator=integrator, dt=dt))
            results.append(dict(row, cells=cells, dt=dt, contact=contact))
            print(f"| {cells} | {dt or 'explicit'} | {contact} | "
                  + " | ".join(f"{row[k][0]:.2f}, {row[k][1]:.4f}" for k in ("engages", "ends", "after", "end"))
                  + " |", flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1)


if __name__ == "__main__":
    main()
