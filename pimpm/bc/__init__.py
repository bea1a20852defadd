"""Boundary conditions: grid faces (:mod:`.faces`), and the prescribed dofs
of a step built from the faces and the nodal terms (:mod:`.constraints`;
rigid bodies are terms: :mod:`pimpm.terms`)."""
from .constraints import Constraints, build_constraints
from .faces import face_constraints

__all__ = ["Constraints", "build_constraints", "face_constraints"]
