"""Material models. One module per family:

* :mod:`.neo_hookean`: the uncoupled neo-Hookean of Guilkey & Weiss eq. 17-21
  and the compressible one of the MPM introduction, eq. 11;
* :mod:`.small_strain`: linear elasticity and von Mises plasticity with
  Sulsky & Kaul's bilinear hardening (eq. 2.1.13-2.1.19) in the accumulated
  small strain;
* :mod:`.finite_plasticity`: finite-strain von Mises plasticity
  (multiplicative split, exact consistent tangent);
* :mod:`.tensors`: small-matrix helpers; :mod:`.base`: the interface;
  :mod:`.update`: the stress update of all particles, material by material.

:data:`MODELS` is the registry: the input schema and :func:`make_material`
both come from it and from each model's ``parameters`` table.
"""
from .base import REQUIRED, Material, Parameter, elastic_moduli, youngs_modulus
from .finite_plasticity import J2FiniteStrain
from .neo_hookean import (CompressibleNeoHookean, UncoupledNeoHookean, compressible_neo_hookean,
                          compressible_neo_hookean_energy, uncoupled_neo_hookean,
                          uncoupled_neo_hookean_energy)
from .small_strain import J2SmallStrain, SmallStrainElastic
from .tensors import von_mises

#: input name -> model class (the order is the one error messages list)
MODELS = {cls.name: cls for cls in (UncoupledNeoHookean, CompressibleNeoHookean,
                                    SmallStrainElastic, J2SmallStrain, J2FiniteStrain)}


def make_material(spec):
    """Build a Material from a spec dict such as
    ``{"model": "neo_hookean", "density": 10.0, "shear_modulus": 6e6, "bulk_modulus": 6e7}``.
    Keys that the model does not take are ignored; a parameter given as None
    takes the model's default."""
    model = spec.get("model")
    if model not in MODELS:
        raise ValueError(f"unknown material model {model!r}; known: {sorted(MODELS)}")
    if "density" not in spec:
        raise ValueError("material spec needs a density")
    cls = MODELS[model]
    mu, kappa = elastic_moduli(spec)
    extra = {k: spec[k] for k in cls.parameters if spec.get(k) is not None}
    return cls(mu, kappa, spec["density"], **extra)


__all__ = ["MODELS", "REQUIRED", "Material", "Parameter", "make_material", "elastic_moduli", "youngs_modulus",
           "von_mises", "UncoupledNeoHookean", "CompressibleNeoHookean", "SmallStrainElastic",
           "J2SmallStrain", "J2FiniteStrain", "uncoupled_neo_hookean", "uncoupled_neo_hookean_energy",
           "compressible_neo_hookean", "compressible_neo_hookean_energy"]
