"""Material models: one module per model (or per family), each declaring
its name, parameters, history fields and compiled point and energy
functions (:mod:`.model`):

* :mod:`.neo_hookean`: the uncoupled neo-Hookean of Guilkey & Weiss eq. 17-21;
* :mod:`.neo_hookean_compressible`: the compressible neo-Hookean of the MPM
  introduction, eq. 11;
* :mod:`.small_strain`: linear elasticity and von Mises plasticity with
  Sulsky & Kaul's bilinear hardening (eq. 2.1.13-2.1.19) in the accumulated
  small strain;
* :mod:`.j2_finite_strain`: finite-strain von Mises plasticity
  (multiplicative split, exact consistent tangent);
* :mod:`.hencky`: Hencky's logarithmic-strain hyperelasticity.

:data:`MODELS` is the registry: a new model is one module and one line
here. Its position is the model's code in the compiled kernels; the input
schema reads each model's ``parameters``. :mod:`.table` packs the materials
of a run for the kernels; :mod:`.tensors` has numpy helpers for output.
"""
from . import hencky, j2_finite_strain, neo_hookean, neo_hookean_compressible, small_strain
from .model import REQUIRED, Material, Model, Parameter, elastic_moduli, youngs_modulus
from .tensors import von_mises


def _register(*models):
    for code, model in enumerate(models):
        model.code = code
    return {model.name: model for model in models}


#: input name -> Model (the order is the one error messages list, and the kernels' codes)
MODELS = _register(neo_hookean.MODEL, neo_hookean_compressible.MODEL, small_strain.LINEAR_ELASTIC,
                   small_strain.J2_SMALL_STRAIN, j2_finite_strain.MODEL, hencky.MODEL)


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
    mu, kappa = elastic_moduli(spec)
    values = {k: spec[k] for k in MODELS[model].parameters if spec.get(k) is not None}
    material = Material(MODELS[model], mu, kappa, spec["density"], **values)
    f_bar = spec.get("f_bar", False)        # False, or what it averages over ("cells", "nodes")
    material.f_bar = ("cells" if f_bar is True else f_bar) if f_bar else False
    if material.f_bar:
        material.f_bar_blend = float(spec.get("f_bar_blend", 0.0))
    return material


__all__ = ["MODELS", "REQUIRED", "Material", "Model", "Parameter", "make_material", "elastic_moduli",
           "youngs_modulus", "von_mises"]
