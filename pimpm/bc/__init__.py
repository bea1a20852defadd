"""Boundary conditions: grid faces (:mod:`.faces`), rigid bodies
(:mod:`.rigid`), and the prescribed dofs of a step built from both
(:mod:`.constraints`)."""
from .constraints import Constraints, build_constraints
from .faces import face_constraints
from .rigid import RigidBody

__all__ = ["Constraints", "RigidBody", "build_constraints", "face_constraints"]
