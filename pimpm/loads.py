"""Loads on particles (the input's ``loads:`` section, docs/INPUT.md), each
scaled by a function of time. They are dead loads: every particle's share
is fixed at the start, on the reference configuration, and needs no
tangent.

* ``traction``: force per area on the faces of a body's surface whose
  outward normal is ``normal``, within ``region``. Seeding records, for every
  particle, the area of each of its domain's faces (its sub-cell, clipped to
  the body) that lies on the body's surface, by normal (the particle field
  ``surface``); a face is on the surface when the neighbouring sub-cell along
  that normal holds no particle of the body. A particle carries the traction
  times its face area, so the resultant is the traction times the loaded
  area exactly (per unit thickness in plane strain and plane stress; faces
  of revolution, 2 pi r times their length, in axisymmetry).
* ``point``: a force shared equally by the body's particles nearest the
  point (ties within 1e-9 of the distance share it).
* ``body_force``: a force per unit mass on every particle of the body.

Each load keeps its particles' shares as a particle field (``load_<name>``),
so shares travel with the particles between ranks and into checkpoints. The
nodal external force of a step is the particle forces at t + dt scattered
with the shape functions (G&W eq. 4).
"""
import numpy as np
from mpi4py import MPI

from .functions import lookup

AXES = "xyz"


def normal_index(normal):
    """Column of the ``surface`` field for a normal such as "y+"."""
    return 2 * AXES.index(normal[0]) + (1 if normal[1] == "+" else 0)


class Load:
    def __init__(self, spec, function, body_index):
        self.name = spec["name"]
        self.kind = spec["type"]
        self.spec = spec
        self.function = function
        self.body = body_index
        self.field = "load_" + self.name
        vector = {"traction": "traction", "point": "force", "body_force": "acceleration"}[self.kind]
        #: the force per unit share at f = 1
        self.vector = np.asarray(spec[vector], dtype=float)
        self.total_share = 0.0          # sum of the shares over all particles (set by share)

    def share(self, particles, comm):
        """Each particle's share of the load (traction: loaded face area;
        point: 1 / number of nearest particles; body force: mass). Collective."""
        p = particles
        mine = p["body"] == self.body
        share = np.zeros(len(p))
        if self.kind == "traction":
            region = self.spec["region"]
            inside = np.all((p["x0"] >= np.asarray(region["lower"])) & (p["x0"] <= np.asarray(region["upper"])),
                            axis=1)
            pick = mine & inside
            share[pick] = p["surface"][pick, normal_index(self.spec["normal"])]
        elif self.kind == "point":
            distance = np.full(len(p), np.inf)
            distance[mine] = np.linalg.norm(p["x0"][mine] - np.asarray(self.spec["point"]), axis=1)
            nearest = comm.allreduce(float(distance.min()) if len(p) else np.inf, op=MPI.MIN)
            pick = distance <= nearest * (1.0 + 1e-9) + 1e-300
            count = comm.allreduce(int(pick.sum()))
            share[pick] = 1.0 / count
        else:
            share[mine] = p["mass"][mine]
        self.total_share = comm.allreduce(float(share.sum()))
        return share

    def resultant(self, time):
        """The load's total force at ``time``."""
        return self.vector * self.total_share * self.function(time)


def make_loads(config, functions, body_names):
    return [Load(spec, lookup(functions, spec["function"]), body_names.index(spec["body"]))
            for spec in config.get("loads", [])]


def particle_forces(loads, particles, time, dim):
    """The force on every particle at ``time`` from all loads, (n, dim), or None."""
    if not loads:
        return None
    force = np.zeros((len(particles), dim))
    for load in loads:
        scale = load.function(time)
        if scale != 0.0:
            force += np.outer(particles[load.field], load.vector * scale)
    return force


def displacement(load, particles, comm):
    """The share-weighted mean displacement of a load's particles (the
    displacement its force works through). Collective."""
    w = particles[load.field]
    local = np.sum(w[:, None] * (particles["x"] - particles["x0"]), axis=0) if len(w) else \
        np.zeros(particles["x"].shape[1])
    total = comm.allreduce(local)
    return total / load.total_share if load.total_share else total
