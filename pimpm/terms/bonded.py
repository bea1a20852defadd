"""A rigid body bonded to the material (Guilkey & Weiss 5.1, Sulsky & Kaul
3.1.1): a set of particles moving with a prescribed velocity, times a
function of time (approach, hold, retract, cycle); every grid node the
body's particles touch (nonzero shape-function weight) gets the body's
displacement over the step in the constrained components, so the material
there moves with it: it can neither let go nor slide. The displacement over
a step is the velocity times the exact integral of the function over it."""
import numpy as np

from ..functions import ONE, lookup
from ..transfer import particle_to_grid
from .base import NodalTerm


class BondedRigidBody(NodalTerm):
    def __init__(self, index, name, velocity, axes, function=ONE):
        self.index = index                     # position in the input's body list (the particles' body id)
        self.name = name
        self.velocity = np.asarray(velocity, dtype=float)
        self.axes = list(axes)                 # constrained components
        self.function = function               # the velocity's scale, a function of time
        self._touched = None
        self._increment = np.zeros(len(self.velocity))

    @classmethod
    def from_config(cls, index, body, dim, functions=None):
        axes = ["xyz".index(a) for a in body.get("constrain", "xyz"[:dim])]
        return cls(index, body["name"], body["velocity"], axes, lookup(functions or {}, body.get("function")))

    def begin_step(self, context):
        self._increment = self.displacement(context.time, context.dt)
        self._touched = self.touched_dofs(context.grid, context.shape, context.rigid)

    def prescribed(self):
        n = len(self._touched)
        return self._touched, np.where(self._touched, np.tile(self._increment, n // len(self._increment)), 0.0)

    def increment(self):
        return self._increment

    def particle_displacement(self, rigid):
        return np.where((rigid["body"] == self.index)[:, None], self._increment, 0.0)

    def displacement(self, time, dt):
        """The body's displacement over the step from ``time`` to ``time + dt``."""
        return self.velocity * self.function.integral(time, time + dt)

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
