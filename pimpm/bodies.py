"""Boundary conditions: grid faces and rigid bodies.

A rigid body is a set of particles moving with a prescribed constant velocity;
every grid node it touches (nonzero shape-function weight) gets that velocity
for the constrained components (contact through shared nodes, as in Guilkey &
Weiss 5.1 and Sulsky & Kaul 3.1.1). Grid faces are ``fixed`` (all components
zero) or ``roller`` (normal component zero: a symmetry plane). Nodes that
carry no mass are taken out of the system (prescribed zero), so the Newton
system stays well posed.
"""
from dataclasses import dataclass

import numpy as np

from .transfer import scatter

AXES = "xyz"


@dataclass
class Constraints:
    fixed: np.ndarray          # owned dofs: prescribed?
    value: np.ndarray          # owned dofs: prescribed incremental displacement
    body_dofs: dict            # rigid body name -> owned dof mask it prescribes (for reactions)


def face_constraints(grid, boundary):
    """Owned dof indices prescribed to zero by the grid-face conditions."""
    dofs = []
    for face, kind in boundary.items():
        if kind == "fixed":
            dofs.append(grid.face_dofs(face, range(grid.dim)))
        elif kind == "roller":
            dofs.append(grid.face_dofs(face, [AXES.index(face[0])]))
    return np.unique(np.concatenate(dofs)) if dofs else np.zeros(0, dtype=np.int64)


def rigid_body_touch(grid, shape, positions, half_size, constrained_axes):
    """Owned dof mask of the nodes a rigid body's particles touch, for its
    constrained components (collective: sums touches over ranks)."""
    dim = grid.dim
    counts = np.zeros((grid.n_local_nodes, dim))
    if len(positions):
        nodes, S, _ = shape.evaluate(positions, grid.lower, grid.spacing, grid.cells, half_size)
        touch = (S > 0.0).astype(float)
        local = grid.local_node_index(nodes)
        node_counts = scatter(local, touch, grid.n_local_nodes)
        for axis in constrained_axes:
            counts[:, axis] = node_counts
    return grid.sum_to_owned(counts) > 0.0


def build_constraints(grid, shape, rigid_particles, rigid_bodies, boundary, mass, dt,
                      mass_floor=0.0, stiffness_weight=None):
    """Prescribed dofs and values for one step.

    rigid_bodies: list of (body index, name, velocity, constrained axes).
    mass: owned nodal mass per dof (zero on nodes no deformable particle touches).
    mass_floor: nodes with no more mass than this count as massless (a node
    at the very edge of a GIMP particle domain gets ~1e-30 of a particle's
    mass and no stiffness to speak of).
    stiffness_weight: if given (owned dofs), a node also needs no more than
    ``mass_floor`` of it to count as massless: a particle lying exactly on a
    cell face gives the node across the face zero mass but a full
    gradient, so that node still has stiffness and must stay free (fixing
    it would strain the particle).
    Order of precedence: grid faces > rigid bodies > massless nodes.
    """
    n = len(mass)
    fixed = np.zeros(n, dtype=bool)
    value = np.zeros(n)
    body_dofs = {}
    for index, name, velocity, axes in rigid_bodies:
        mine = rigid_particles["body"] == index
        touched = rigid_body_touch(grid, shape, rigid_particles["x"][mine],
                                   rigid_particles["half_size"][mine], axes)
        u = np.tile(np.asarray(velocity, dtype=float) * dt, n // grid.dim)
        value[touched] = u[touched]
        fixed |= touched
        for mask in body_dofs.values():   # a node shared by two bodies goes to the later one
            mask[touched] = False
        body_dofs[name] = touched
    faces = face_constraints(grid, boundary)
    fixed[faces] = True
    value[faces] = 0.0
    for mask in body_dofs.values():
        mask[faces] = False
    massless = (mass <= mass_floor) & ~fixed
    if stiffness_weight is not None:
        massless &= stiffness_weight <= mass_floor
    fixed |= massless
    return Constraints(fixed=fixed, value=value, body_dofs=body_dofs)
