"""The numpy reference of every material model (vectorised over particles;
the interface of :mod:`.base`), under the names the tests use, and
:func:`reference_of` (the reference of a pimpm material)."""
from pimpm.materials import elastic_moduli, von_mises  # noqa: F401

from .base import Material, PlasticParameters  # noqa: F401
from .finite_plasticity import J2FiniteStrain, j2_finite  # noqa: F401
from .hencky import Hencky
from .neo_hookean import (CompressibleNeoHookean, UncoupledNeoHookean, compressible_neo_hookean,  # noqa: F401
                          compressible_neo_hookean_energy, uncoupled_neo_hookean,
                          uncoupled_neo_hookean_energy)
from .small_strain import J2SmallStrain, SmallStrainElastic, j2_return, yield_stress  # noqa: F401

#: model name -> reference class
REFERENCES = {cls.name: cls for cls in (UncoupledNeoHookean, CompressibleNeoHookean, SmallStrainElastic,
                                        J2SmallStrain, J2FiniteStrain, Hencky)}


def reference_of(material):
    """The numpy reference of a :class:`pimpm.materials.Material`."""
    cls = REFERENCES[material.name]
    return cls(material.shear_modulus, material.bulk_modulus, material.density, **material.values)


def make_reference(spec):
    """The numpy reference of the material an input's ``materials`` entry makes."""
    from pimpm.materials import make_material
    return reference_of(make_material(spec))
