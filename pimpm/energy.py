"""Energies of the particles and the work done on them, for the history
(a check of every run: total energy minus external work is what the
integrator and plasticity dissipated)."""
import numpy as np
from mpi4py import MPI

from .kernels import stress as stress_kernels


def _kinetic(particles):
    p = particles
    return 0.5 * float(np.sum(p["mass"] * np.sum(p["v"] ** 2, axis=1)))


def _stored(particles, table):
    p = particles
    if not len(p):
        return 0.0
    history = {k: p["h_" + k] for m, _ in table.groups for k in m.history}
    return stress_kernels.strain_energy(table.only_model, table.models, table.params, table.material_of, p["F"],
                                        table.pack(history), p["volume0"])


def kinetic_energy(particles, comm):
    """Kinetic energy of the particles. Collective."""
    return float(comm.allreduce(_kinetic(particles)))


def strain_energy(particles, table, comm):
    """Stored energy of every material (per reference volume, times it),
    compiled (:func:`pimpm.kernels.stress.strain_energy`); ``table``: the
    particles' :class:`pimpm.materials.table.MaterialTable`. Collective."""
    return float(comm.allreduce(_stored(particles, table)))


def energies(particles, table, comm):
    """(kinetic, stored) energy in one reduction. Collective."""
    kinetic, stored = comm.allreduce(np.array([_kinetic(particles), _stored(particles, table)]))
    return float(kinetic), float(stored)


class WorkAccount:
    """External work done on the material so far: each rigid body's force
    (trapezoidal in time) times its displacement over the step, and the
    particle external forces (gravity and loads, trapezoidal in time) times
    the particles' displacements. Also each rigid body's total displacement
    (for the history and the force-displacement plots)."""

    def __init__(self, comm):
        self.comm = comm
        self.total = 0.0
        self.last_forces = {}          # body name -> force of the last step
        self.displacements = {}        # body name -> displacement since the start

    def state(self):
        """What a checkpoint keeps (JSON-able)."""
        as_lists = lambda d: {k: [float(x) for x in v] for k, v in d.items()}
        return {"total": self.total, "last_forces": as_lists(self.last_forces),
                "displacements": as_lists(self.displacements)}

    def restore(self, state):
        self.total = float(state["total"])
        self.last_forces = {k: np.array(v, dtype=float) for k, v in state["last_forces"].items()}
        self.displacements = {k: np.array(v, dtype=float)
                              for k, v in state.get("displacements", {}).items()}

    def add(self, forces, increments, displacement, external_start, external_end):
        """Add one step's work: ``forces`` and ``increments`` (rigid body name
        -> force, displacement over the step), the particles' displacements
        and their external forces at the start and the end of the step (None:
        there are none). Collective."""
        work = 0.0
        for name, step in increments.items():
            previous = self.last_forces.get(name, np.zeros(len(step)))
            work += 0.5 * float(np.dot(previous + forces[name], step))
            self.displacements[name] = self.displacements.get(name, np.zeros(len(step))) + step
        local = 0.0
        if len(displacement) and external_start is not None:
            local = 0.5 * float(np.sum((external_start + external_end) * displacement))
        self.total += work + self.comm.allreduce(local, op=MPI.SUM)
        self.last_forces = {name: np.array(f) for name, f in forces.items()}
