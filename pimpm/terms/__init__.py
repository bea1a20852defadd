"""Nodal terms: what a step adds beside the particles' own contribution
(:mod:`.base` says where the steps call them). One module per term:

* :mod:`.bonded`: a rigid body bonded to the material (it prescribes the
  nodes its particles touch).
* :mod:`.contact`: a rigid tool in unilateral contact with the material,
  frictionless or with Coulomb friction, or tied to it at its surface.

:func:`make_terms` builds a run's terms from its input."""
from .base import NodalTerm, StepContext
from .bonded import BondedRigidBody
from .contact import ContactTool

#: the term of each rigid body's contact law (``contact`` of the input)
RIGID_TERMS = {"bonded": lambda i, body, config, functions:
               BondedRigidBody.from_config(i, body, config["dim"], functions),
               "frictionless": ContactTool.from_config,
               "friction": ContactTool.from_config,
               "tied": ContactTool.from_config}


def make_terms(config, functions):
    """The terms of a run: one per rigid body, chosen by its contact law."""
    return [RIGID_TERMS[body.get("contact") or "bonded"](i, body, config, functions)
            for i, body in enumerate(config["bodies"]) if body.get("rigid", False)]


__all__ = ["NodalTerm", "StepContext", "BondedRigidBody", "ContactTool", "make_terms"]
