"""The prescribed dofs of one step (G&W step 2): grid faces, nodal terms
(rigid bodies) and nodes that carry no mass (taken out of the system, prescribed zero, so
the Newton system stays well posed), and the reactions on them."""
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from .faces import face_constraints


@dataclass
class Constraints:
    fixed: np.ndarray          # owned dofs: prescribed?
    value: np.ndarray          # owned dofs: prescribed incremental displacement
    body_dofs: dict            # term name -> owned dof mask it prescribes (for reactions)

    def reactions(self, force, comm, dim):
        """The force each prescribing term (rigid body) exerts on the
        material: the sum of the unconstrained nodal ``force`` (owned dofs)
        over the dofs it prescribes, over all ranks. Collective."""
        forces = {}
        for name, mask in self.body_dofs.items():
            local = np.where(mask, force, 0.0).reshape(-1, dim).sum(axis=0)
            forces[name] = comm.allreduce(local, op=MPI.SUM)
        return forces


def build_constraints(grid, terms, boundary, mass, dt, mass_floor=0.0, stiffness_weight=None, time=0.0,
                      functions=None):
    """Prescribed dofs and values for one step.

    terms: the run's nodal terms (:mod:`pimpm.terms`), their
    ``begin_step`` already called for this step; each prescribes dofs
    (:meth:`pimpm.terms.NodalTerm.prescribed`), and a dof prescribed by
    two goes to the later one.
    mass: owned nodal mass per dof (zero on nodes no deformable particle touches).
    mass_floor: nodes with no more mass than this count as massless (a node
    at the very edge of a GIMP particle domain gets ~1e-30 of a particle's
    mass and no stiffness to speak of).
    stiffness_weight: if given (owned dofs), a node also needs no more than
    ``mass_floor`` of it to count as massless: a particle lying exactly on a
    cell face gives the node across the face zero mass but a full
    gradient, so that node still has stiffness and must stay free (fixing
    it would strain the particle).
    time: the start of the step (faces moving with a function of time move
    by its integral over the step).
    Order of precedence: grid faces > terms > massless nodes.
    """
    n = len(mass)
    fixed = np.zeros(n, dtype=bool)
    value = np.zeros(n)
    body_dofs = {}
    for term in terms:
        prescribed = term.prescribed()
        if prescribed is None:
            continue
        touched, values = prescribed
        value[touched] = values[touched]
        fixed |= touched
        for mask in body_dofs.values():   # a node shared by two terms goes to the later one
            mask[touched] = False
        body_dofs[term.name] = touched.copy()
    faces, face_values = face_constraints(grid, boundary, time, dt, functions)
    fixed[faces] = True
    value[faces] = face_values
    for mask in body_dofs.values():
        mask[faces] = False
    massless = (mass <= mass_floor) & ~fixed
    if stiffness_weight is not None:
        massless &= stiffness_weight <= mass_floor
    fixed |= massless
    return Constraints(fixed=fixed, value=value, body_dofs=body_dofs)
