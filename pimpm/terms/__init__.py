"""Nodal terms: what a step adds beside the particles' own contribution
(:mod:`.base` says where the steps call them). One module per term:

* :mod:`.bonded`: a rigid body bonded to the material (it prescribes the
  nodes its particles touch).

:func:`make_terms` builds a run's terms from its input."""
from .base import NodalTerm, StepContext
from .bonded import BondedRigidBody


def make_terms(config, functions):
    """The terms of a run: a bonded rigid body for every rigid body of the input."""
    dim = config["dim"]
    return [BondedRigidBody.from_config(i, body, dim, functions)
            for i, body in enumerate(config["bodies"]) if body.get("rigid", False)]


__all__ = ["NodalTerm", "StepContext", "BondedRigidBody", "make_terms"]
