"""Rigid bodies: sets of particles moving with a prescribed velocity; every
grid node a body's particles touch (nonzero shape-function weight) gets
that velocity for the constrained components (contact through shared
nodes, as in Guilkey & Weiss 5.1 and Sulsky & Kaul 3.1.1)."""
from dataclasses import dataclass

import numpy as np

from ..transfer import scatter


@dataclass
class RigidBody:
    index: int                 # position in the input's body list (the particles' body id)
    name: str
    velocity: np.ndarray       # (dim,)
    axes: list                 # constrained components

    @classmethod
    def from_config(cls, index, body, dim):
        axes = ["xyz".index(a) for a in body.get("constrain", "xyz"[:dim])]
        return cls(index, body["name"], np.asarray(body["velocity"], float), axes)

    def touched_dofs(self, grid, shape, rigid_particles):
        """Owned dof mask of the nodes this body's particles touch, for its
        constrained components (collective: sums touches over ranks)."""
        mine = rigid_particles["body"] == self.index
        positions, half_size = rigid_particles["x"][mine], rigid_particles["half_size"][mine]
        counts = np.zeros((grid.n_local_nodes, grid.dim))
        if len(positions):
            nodes, S, _ = shape.evaluate(positions, grid.lower, grid.spacing, grid.cells, half_size)
            touch = (S > 0.0).astype(float)
            local = grid.local_node_index(nodes)
            node_counts = scatter(local, touch, grid.n_local_nodes)
            for axis in self.axes:
                counts[:, axis] = node_counts
        return grid.sum_to_owned(counts) > 0.0

    def increment(self, dt):
        """Displacement of the body over a step."""
        return self.velocity * dt
