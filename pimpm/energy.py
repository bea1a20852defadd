"""Energies of the particles and the work done on them, for the history
(a check of every run: total energy minus external work is what the
integrator and plasticity dissipated)."""
import numpy as np
from mpi4py import MPI


def kinetic_energy(particles, comm):
    p = particles
    return float(comm.allreduce(0.5 * np.sum(p["mass"] * np.sum(p["v"] ** 2, axis=1))))


def strain_energy(particles, material_groups, comm):
    """Stored energy of every material (per reference volume, times it). Collective."""
    p = particles
    total = 0.0
    for material, index in material_groups:
        if len(index):
            history = {k: p["h_" + k][index] for k in material.history}
            total += float(np.sum(p["volume0"][index] * material.strain_energy(p["F"][index], history)))
    return float(comm.allreduce(total))


class WorkAccount:
    """External work done on the material so far: rigid bodies, force
    (trapezoidal in time) times their prescribed velocity, and gravity,
    sum_p m_p g . du_p."""

    def __init__(self, comm):
        self.comm = comm
        self.total = 0.0
        self.last_forces = {}          # body name -> force of the last step

    def state(self):
        """What a checkpoint keeps (JSON-able)."""
        return {"total": self.total, "last_forces": {k: [float(x) for x in v]
                                                     for k, v in self.last_forces.items()}}

    def restore(self, state):
        self.total = float(state["total"])
        self.last_forces = {k: np.array(v, dtype=float) for k, v in state["last_forces"].items()}

    def add(self, forces, rigid_bodies, particles, displacement, gravity, dt):
        """Add one step's work. Collective."""
        work = 0.0
        for body in rigid_bodies:
            previous = self.last_forces.get(body.name, np.zeros(len(body.velocity)))
            work += 0.5 * float(np.dot(previous + forces[body.name], body.velocity)) * dt
        if len(displacement) and np.any(gravity):
            local = float(np.sum(particles["mass"] * (displacement @ gravity)))
        else:
            local = 0.0
        self.total += work + self.comm.allreduce(local, op=MPI.SUM)
        self.last_forces = {name: np.array(f) for name, f in forces.items()}
