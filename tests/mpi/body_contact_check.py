"""Deformable bodies in contact on any number of ranks (tests/test_body_contact.py):
two disks through their impact and Nairn's frictional block, explicit, and
with the trapezoidal rule the disks (a frictionless pair inside Newton) and
the block, the stack of three blocks and the disk sliding down its slope
(Coulomb's stick and slip inside Newton). Saves
every particle's position and velocity (in id order) and the pairs' forces
to the .npz file named on the command line (rank 0)."""
import os
import sys

import petsc4py

petsc4py.init(sys.argv[:1])
import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))),
                                "scripts"))
from body_contact_validation import (block_on_plane_config, disk_on_slope_config, disks_config,  # noqa: E402
                                     march, stacked_blocks_config)
from pimpm.simulation import Simulation  # noqa: E402

comm = MPI.COMM_WORLD
out = {}
for name, config, end in (("disks", disks_config(20), 3.2),
                          ("block", block_on_plane_config(5e-3, "friction", 0.5), 0.15e-3),
                          ("implicit_disks", disks_config(20, integrator="newmark", dt=0.1), 3.2),
                          ("implicit_block", block_on_plane_config(5e-3, "friction", 0.5, integrator="newmark",
                                                                   dt=1.3e-5), 0.15e-3),
                          ("implicit_stack", stacked_blocks_config(0.01, (0.5, 0.1, 0.8), integrator="newmark",
                                                                   dt=1.4e-3), 0.04),
                          ("implicit_slope", disk_on_slope_config(0.02, 0.1, integrator="newmark", dt=8.6e-3), 0.1)):
    sim = Simulation(dict(config, time=dict(config["time"], end_time=end)), comm)
    forces = []
    for info, _ in march(sim, end):
        pair = info["contact"][sim.fields.names[0]]
        # (not the count of nodes in contact: a node whose approach is round-off may flip)
        forces.append([pair["normal_force"], pair["tangential_force"]])
    p = sim.particles
    parts = comm.gather((p["id"], p["x"], p["v"]), root=0)
    if comm.rank == 0:
        ids = np.concatenate([a for a, _, _ in parts])
        order = np.argsort(ids)
        out[name + "_x"] = np.concatenate([b for _, b, _ in parts])[order]
        out[name + "_v"] = np.concatenate([c for _, _, c in parts])[order]
        out[name + "_forces"] = np.array(forces)
if comm.rank == 0:
    np.savez(sys.argv[1], **out)
