"""The numpy reference of the material interface: what every model of
tests/reference computes, vectorised over particles (``F`` of shape (n, 3,
3)). These were pimpm's production models before the compiled ones
(pimpm.materials) replaced them; the tests compare the two to round-off and
check both against finite differences of the energies. Tangent convention:
:mod:`pimpm.materials.model`."""
import numpy as np

from pimpm.materials import MODELS
from pimpm.materials import Material as PimpmMaterial
from pimpm.materials.model import ElasticConstants


class Material(ElasticConstants):
    """Common interface. Subclasses set ``name`` and implement ``_kernel``
    and ``_energy`` (or override :meth:`update` and :meth:`strain_energy`)."""

    name = "material"
    #: history variables carried by particles: name -> per-particle shape
    history = {}
    #: parameters beyond the elastic constants and density: name -> Parameter
    parameters = {}
    #: is the consistent tangent symmetric? (measured by tests/mpi/jacobian_check.py)
    symmetric_tangent = True

    def __init__(self, shear_modulus, bulk_modulus, density):
        self.shear_modulus = float(shear_modulus)
        self.bulk_modulus = float(bulk_modulus)
        self.density = float(density)
        if not (self.shear_modulus > 0 and self.bulk_modulus > 0 and self.density > 0):
            raise ValueError(
                f"{self.name}: shear_modulus, bulk_modulus and density must be > 0 "
                f"(got {shear_modulus}, {bulk_modulus}, {density})"
            )

    @property
    def code(self):
        """The model's code in the compiled kernels (its place in the registry)."""
        return MODELS[self.name].code

    def packed_parameters(self):
        """The parameters as the compiled kernels take them (pimpm's packing
        of the same values)."""
        model = MODELS[self.name]
        values = {key: getattr(self, key) for key in model.parameters}
        return PimpmMaterial(model, self.shear_modulus, self.bulk_modulus, self.density,
                             **values).packed_parameters()

    def stress(self, F):
        """Cauchy stress, shape (n, 3, 3)."""
        return self._kernel(F, tangent=False)[0]

    def stress_and_tangent(self, F):
        """Cauchy stress (n, 3, 3) and spatial elasticity tensor (n, 3, 3, 3, 3)."""
        return self._kernel(F, tangent=True)

    def strain_energy(self, F, history=None):
        """Strain energy per unit reference volume, shape (n,)."""
        return self._energy(F)

    def update(self, F, history, tangent=True):
        """Stress, tangent (or None) and the history after this deformation,
        from the history committed at the start of the step (elastic models
        have none)."""
        sigma, c = self._kernel(F, tangent=tangent)
        return sigma, c, {}

    def _kernel(self, F, tangent):  # pragma: no cover - abstract
        raise NotImplementedError

    def _energy(self, F):  # pragma: no cover - abstract
        raise NotImplementedError

    def __repr__(self):
        return (
            f"{type(self).__name__}(shear_modulus={self.shear_modulus!r}, "
            f"bulk_modulus={self.bulk_modulus!r}, density={self.density!r})"
        )


class PlasticParameters:
    """Yield stress and the bilinear hardening / softening of Sulsky & Kaul
    eq. 2.1.19 (mixed into the J2 models before Material)."""

    def __init__(self, shear_modulus, bulk_modulus, density, yield_stress, hardening_modulus=0.0,
                 softening_strain=np.inf, softening_modulus=0.0):
        super().__init__(shear_modulus, bulk_modulus, density)
        self.yield_stress = float(yield_stress)
        self.hardening_modulus = float(hardening_modulus)
        self.softening_strain = float(softening_strain)
        self.softening_modulus = float(softening_modulus)
