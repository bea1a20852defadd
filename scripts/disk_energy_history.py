"""Where the implicit head-on disks lose their energy (issue 30,
docs/VALIDATION.md "Two disks colliding head-on"): the total energy over
the start's when contact engages, when it ends, 0.7 time units after it
ended (no contact: the integrator alone) and at t = 8, for the trapezoidal
rule at 20 cells (dt 0.1 and 0.02) and 40 cells (dt 0.05).

    python scripts/disk_energy_history.py

One rank, about a minute."""
import os
import sys

import petsc4py

petsc4py.init(sys.argv[:1])
from mpi4py import MPI  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from body_contact_validation import disks_config, march  # noqa: E402
from pimpm.simulation import Simulation  # noqa: E402


def energy_history(cells, dt, end_time=8.0):
    sim = Simulation(disks_config(cells, integrator="newmark", dt=dt), MPI.COMM_SELF)
    pair = sim.fields.names[0]
    start = sim.kinetic_energy() + sim.strain_energy()
    rows, first, last = [], None, None
    for info, _ in march(sim, end_time):
        energy = (info["kinetic_energy"] + info["strain_energy"]) / start
        if info["contact"][pair]["contact_points"]:
            first = first or (sim.time, energy)
            last = (sim.time, energy)
        rows.append((sim.time, energy))
    after = [r for r in rows if r[0] <= last[0] + 0.7 + 1e-9][-1]
    return first, last, after, rows[-1]


def main():
    print("| cells | dt | contact engages (t, energy) | contact ends (t, energy) | 0.7 later | t = 8 |")
    print("|---|---|---|---|---|---|")
    for cells, dt in ((20, 0.1), (20, 0.02), (40, 0.05)):
        first, last, after, end = energy_history(cells, dt)
        print(f"| {cells} | {dt} | {first[0]:.2f}, {first[1]:.4f} | {last[0]:.2f}, {last[1]:.4f} | "
              f"{after[1]:.4f} | {end[1]:.4f} |", flush=True)


if __name__ == "__main__":
    main()
