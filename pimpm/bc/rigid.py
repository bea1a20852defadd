"""Rigid bodies: sets of particles moving with a prescribed velocity, times
a function of time (approach, hold, retract, cycle); every grid node a
body's particles touch (nonzero shape-function weight) gets the body's
displacement over the step for the constrained components (contact through
shared nodes, as in Guilkey & Weiss 5.1 and Sulsky & Kaul 3.1.1). The
displacement over a step is the velocity times the exact integral of the
function over it."""
from dataclasses import dataclass

import numpy as np

from ..functions import ONE, lookup
from ..transfer import particle_to_grid


@dataclass
class RigidBody:
    index: int                 # position in the input's body list (the particles' body id)
    name: str
    velocity: np.ndarray       # (dim,)
    axes: list                 # constrained components
    function: object = ONE     # the velocity's scale, a function of time (pimpm.functions)

    @classmethod
    def from_config(cls, index, body, dim, functions=None):
        axes = ["xyz".index(a) for a in body.get("constrain", "xyz"[:dim])]
        return cls(index, body["name"], np.asarray(body["velocity"], float), axes,
                   lookup(functions or {}, body.get("function")))

    def touched_dofs(self, grid, shape, rigid_particles):
        """Owned dof mask of the nodes this body's particles touch, for its
        constrained components (collective: sums touches over ranks)."""
        mine = rigid_particles["body"] == self.index
        positions, half_size = rigid_particles["x"][mine], rigid_particles["half_size"][mine]
        counts = np.zeros((grid.n_local_nodes, grid.dim))
        if len(positions):
            local, S, _ = shape.footprint(positions, grid, half_size)
            # how many of the body's particles touch each node (weight > 0)
            node_counts = particle_to_grid(local, (S > 0.0).astype(float), np.ones(len(S)), grid.n_local_nodes)
            for axis in self.axes:
                counts[:, axis] = node_counts
        return grid.sum_to_owned(counts) > 0.0

    def increment(self, time, dt):
        """Displacement of the body over the step from ``time`` to ``time + dt``."""
        return self.velocity * self.function.integral(time, time + dt)
