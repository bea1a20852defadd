"""The interface every material model implements, the elastic constants and
the plasticity parameters shared by the J2 models.

Every model declares the parameters it takes beyond the elastic constants
and the density (``parameters``: name -> :data:`Parameter`);
the input schema (``pimpm/config/``) and the factory
(:func:`pimpm.materials.make_material`) both read that table.

Tangent convention. ``c`` is the spatial elasticity tensor
``c_ijkl = J^-1 F_iI F_jJ F_kK F_lL 4 d2W/dC_IJ dC_KL``, i.e. the tangent of
the Truesdell (Lie) rate of the Kirchhoff stress ``tau = J sigma`` divided by J:

    L_v tau = tau_dot - l tau - tau l^T = J c : d,      d = sym(l).

Hence, for ``F_eps = (I + eps H) F``,
``d tau / d eps |_0 = J c : H + H tau + tau H^T``. The spatial tangent
stiffness used by the implicit solver is ``c_ijkl + delta_ik sigma_jl``
(material + geometric part).
"""
import numpy as np

from collections import namedtuple

#: marks a parameter without a default
REQUIRED = object()

#: a model parameter: its default (or REQUIRED; None: the model's own, e.g.
#: no softening) and whether it must be positive (else any finite number)
Parameter = namedtuple("Parameter", "default positive")


def elastic_moduli(spec):
    """(shear_modulus, bulk_modulus) from a material spec.

    Uses ``shear_modulus`` and ``bulk_modulus`` if both are given, otherwise
    ``youngs_modulus`` E and ``poisson_ratio`` nu:
    mu = E / (2 (1 + nu)),  kappa = E / (3 (1 - 2 nu)).
    """
    if "shear_modulus" in spec and "bulk_modulus" in spec:
        return float(spec["shear_modulus"]), float(spec["bulk_modulus"])
    if "youngs_modulus" in spec and "poisson_ratio" in spec:
        E = float(spec["youngs_modulus"])
        nu = float(spec["poisson_ratio"])
        if not (E > 0 and -1.0 < nu < 0.5):
            raise ValueError(f"need youngs_modulus > 0 and -1 < poisson_ratio < 0.5, got E={E}, nu={nu}")
        return E / (2.0 * (1.0 + nu)), E / (3.0 * (1.0 - 2.0 * nu))
    raise ValueError(
        "material spec needs either shear_modulus and bulk_modulus, "
        "or youngs_modulus and poisson_ratio"
    )


def youngs_modulus(shear_modulus, bulk_modulus):
    """E = 9 kappa mu / (3 kappa + mu)."""
    return 9.0 * bulk_modulus * shear_modulus / (3.0 * bulk_modulus + shear_modulus)


class Material:
    """Common interface. Subclasses set ``name`` and implement ``_kernel``
    and ``_energy`` (or override :meth:`update` and :meth:`strain_energy`)."""

    name = "material"
    #: history variables carried by particles: name -> per-particle shape
    history = {}
    #: parameters beyond the elastic constants and density: name -> Parameter
    parameters = {}
    #: is the consistent tangent symmetric? (measured by tests/mpi/jacobian_check.py)
    symmetric_tangent = True
    #: the model's code in the compiled kernels (pimpm.kernels.material_point)
    kernel_model = None

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
    def lame_lambda(self):
        """First Lame parameter lambda = kappa - 2/3 mu."""
        return self.bulk_modulus - 2.0 / 3.0 * self.shear_modulus

    @property
    def youngs_modulus(self):
        return youngs_modulus(self.shear_modulus, self.bulk_modulus)

    @property
    def p_wave_modulus(self):
        """kappa + 4/3 mu (uniaxial-strain stiffness)."""
        return self.bulk_modulus + 4.0 / 3.0 * self.shear_modulus

    def packed_parameters(self):
        """The parameters as the compiled kernels take them: [mu, kappa, yield
        stress, hardening modulus, softening strain, softening modulus]."""
        return np.array([self.shear_modulus, self.bulk_modulus, 0.0, 0.0, np.inf, 0.0])

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

    def wave_speed(self):
        """Small-strain dilatational wave speed sqrt((kappa + 4/3 mu) / rho)."""
        return float(np.sqrt((self.bulk_modulus + 4.0 / 3.0 * self.shear_modulus) / self.density))

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

    parameters = {"yield_stress": Parameter(REQUIRED, True),
                  "hardening_modulus": Parameter(0.0, False),
                  "softening_strain": Parameter(None, True),
                  "softening_modulus": Parameter(0.0, False)}

    def __init__(self, shear_modulus, bulk_modulus, density, yield_stress, hardening_modulus=0.0,
                 softening_strain=np.inf, softening_modulus=0.0):
        super().__init__(shear_modulus, bulk_modulus, density)
        self.yield_stress = float(yield_stress)
        self.hardening_modulus = float(hardening_modulus)
        self.softening_strain = float(softening_strain)
        self.softening_modulus = float(softening_modulus)

    def packed_parameters(self):
        return np.array([self.shear_modulus, self.bulk_modulus, self.yield_stress,
                         self.hardening_modulus, self.softening_strain, self.softening_modulus])
