"""Conservation of mass and momentum by P2G and G2P, and particle migration
(run under mpiexec with any number of ranks; some ranks own no particles).

Prints rank-independent global sums so the pytest wrapper can compare runs on
1, 2 and 3 ranks; exits 1 if a conservation check fails.
"""
import sys

import petsc4py
petsc4py.init(sys.argv[:1])
import numpy as np
from mpi4py import MPI

from pimpm.config import validate
from pimpm.simulation import Simulation
from petsc4py import PETSc
# PETSc's even split of the nodes, so that ranks 1 and 2 of 3 start without
# particles (what this check is about); pimpm balances the ranks otherwise
PETSc.Options().setValue("pimpm_balance", "0")
from pimpm.transfer import grid_to_particle

comm = MPI.COMM_WORLD
raw = {
    "grid": {"lower": [0.0, 0.0], "upper": [9.0, 3.0], "cells": [18, 6]},
    "materials": {"m": {"model": "neo_hookean", "shear_modulus": 1.0, "bulk_modulus": 2.0,
                        "density": 3.0}},
    # Only the left third of the grid holds particles: with 3 ranks split
    # along x, ranks 1 and 2 start with none.
    "bodies": [{"name": "a", "material": "m", "particles_per_cell": 3,
                "geometry": {"type": "ball", "center": [1.4, 1.5], "radius": 1.2}}],
    "time": {"integrator": "newmark", "dt": 1.0, "end_time": 1.0},
}
sim = Simulation(validate(raw), comm)
p = sim.particles
counts_at_start = comm.allgather(len(p))
rng = np.random.default_rng(7)
# rank-independent random velocities: a function of the particle id
ids = p["id"]
p["v"] = np.stack([np.sin(1.3 * ids), np.cos(0.7 * ids)], axis=1)
p["a"] = np.stack([np.cos(0.3 * ids), np.sin(0.9 * ids)], axis=1)
failures = []


def check(name, a, b, tol=1e-12):
    a, b = np.asarray(a, float), np.asarray(b, float)
    rel = float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))
    if rel > tol:
        failures.append(f"{name}: {a} vs {b} (relative {rel:.2e})")
    return rel


def gsum(x):
    return comm.allreduce(np.asarray(x, float), op=MPI.SUM)


node_index, S, G = sim.footprint()
mass, velocity, acceleration, _ = sim.nodal_state(node_index, S)
dim = sim.dim
M = mass.reshape(-1, dim)[:, 0]
particle_mass = gsum(np.sum(p["mass"]))
particle_momentum = gsum(np.sum(p["mass"][:, None] * p["v"], axis=0))
grid_mass = gsum(np.sum(M))
grid_momentum = gsum(np.sum(mass.reshape(-1, dim) * velocity.reshape(-1, dim), axis=0))
check("P2G mass", grid_mass, particle_mass)
check("P2G momentum", grid_momentum, particle_momentum)
check("P2G mass-weighted acceleration",
      gsum(np.sum(mass.reshape(-1, dim) * acceleration.reshape(-1, dim), axis=0)),
      gsum(np.sum(p["mass"][:, None] * p["a"], axis=0)))
# first moment of the nodal mass equals that of the particles (linear shapes)
x_nodes = sim.grid.node_coordinates_owned()
check("P2G first moment", gsum(np.sum(M[:, None] * x_nodes, axis=0)),
      gsum(np.sum(p["mass"][:, None] * p["x"], axis=0)))

# G2P: particles pick up a nodal velocity change dv; momentum change matches.
dv_nodes = np.stack([np.sin(x_nodes[:, 0]) + x_nodes[:, 1], np.cos(x_nodes[:, 1])], axis=1)
dv_local = sim.grid.owned_to_local(dv_nodes.reshape(-1))
dv_p = grid_to_particle(node_index, S, dv_local)
check("G2P momentum", gsum(np.sum(p["mass"][:, None] * dv_p, axis=0)),
      gsum(np.sum(M[:, None] * dv_nodes, axis=0)))

count0 = comm.allreduce(len(p))
id_sum0 = comm.allreduce(int(np.sum(p["id"])))
# Migration: move every particle 5 cells to the right (across rank boundaries)
p["x"] = p["x"] + np.array([2.5, 0.0])
sim.migrate()                    # raises if count or mass changed
p = sim.particles
count1 = comm.allreduce(len(p))
id_sum1 = comm.allreduce(int(np.sum(p["id"])))
owner_ok = comm.allreduce(bool(np.all(sim.grid.owner_of_cells(sim.grid.cell_of(p["x"])) == comm.rank)),
                          op=MPI.LAND)
if count1 != count0 or id_sum1 != id_sum0 or not owner_ok:
    failures.append(f"migration: count {count0}->{count1}, id sum {id_sum0}->{id_sum1}, owners ok {owner_ok}")
local_counts = comm.allgather(len(p))

# Lazy migration (the explicit step): a move of 0.3 cells takes some particles
# into a neighbour's cells but keeps every footprint in its rank's ghosted
# nodes, so nothing moves; a full migration then sends them to their owners.
held = sorted(p["id"].tolist())
p["x"] = p["x"] + np.array([0.3, 0.0]) * sim.grid.spacing
sim.migrate(lazy=True)
p = sim.particles
strays = comm.allreduce(int(np.count_nonzero(sim.grid.owner_of_cells(sim.grid.cell_of(p["x"])) != comm.rank)))
if sorted(p["id"].tolist()) != held:
    failures.append("lazy migration moved particles whose footprints stayed in the ghosted nodes")
if comm.size > 1 and strays == 0:
    failures.append("the lazy-migration check moved no particle into a neighbour's cells")
sim.migrate()
p = sim.particles
if not comm.allreduce(bool(np.all(sim.grid.owner_of_cells(sim.grid.cell_of(p["x"])) == comm.rank)), op=MPI.LAND):
    failures.append("after the lazy step, a full migration left particles off their owners")

if comm.rank == 0:
    print(f"transfer_check ranks={comm.size} particles={count0} local_counts={counts_at_start} "
          f"after_move={local_counts}")
    print(f"mass={float(grid_mass)!r} momentum={[float(v) for v in grid_momentum]!r}")
    for f in failures:
        print("FAIL", f)
sys.exit(1 if failures else 0)
