"""Hyperelastic material models for pimpm.

All kernels are vectorised over particles: ``F`` has shape ``(..., 3, 3)``
(normally ``(n, 3, 3)``); plane-strain problems pass 3x3 tensors with
``F[2, 2] = 1`` and zero off-plane entries.  Outputs:

* Cauchy stress ``sigma``           shape ``(..., 3, 3)``
* spatial elasticity tensor ``c``   shape ``(..., 3, 3, 3, 3)``
* strain energy ``W``               shape ``(...)``, per unit *reference* volume

Tangent convention.  ``c`` is the spatial elasticity tensor
``c_ijkl = J^-1 F_iI F_jJ F_kK F_lL 4 d2W/dC_IJ dC_KL``, i.e. the tangent of
the Truesdell (Lie) rate of the Kirchhoff stress ``tau = J sigma`` divided by J:

    L_v tau = tau_dot - l tau - tau l^T = J c : d,      d = sym(l).

Hence, for ``F_eps = (I + eps H) F``,
``d tau / d eps |_0 = J c : H + H tau + tau H^T``.  ``c`` has major and minor
symmetries.  The spatial tangent stiffness used by the implicit solver is
``c_ijkl + delta_ik sigma_jl`` (material + geometric part).

Inverted particles (``det F <= 0`` or non-finite) give NaN in all outputs for
those particles, without raising or warning; the caller detects them.

References
----------
Guilkey & Weiss (2003), IJNME, section 4, eq. 17-21 (uncoupled neo-Hookean).
Guilkey, "An Introduction to the Material Point Method", appendix A, eq. 11
(compressible neo-Hookean).
"""
from __future__ import annotations

import numpy as np

from . import finite_plasticity, small_strain, smallmat

__all__ = [
    "uncoupled_neo_hookean",
    "uncoupled_neo_hookean_energy",
    "compressible_neo_hookean",
    "compressible_neo_hookean_energy",
    "von_mises",
    "Material",
    "UncoupledNeoHookean",
    "CompressibleNeoHookean",
    "MODELS",
    "elastic_moduli",
    "make_material",
]

# Constant tensors.
_I = np.eye(3)
_II = np.einsum("ij,kl->ijkl", _I, _I)  # I (x) I
# Symmetric fourth-order identity: 1/2 (d_ik d_jl + d_il d_jk).
_IS = 0.5 * (np.einsum("ik,jl->ijkl", _I, _I) + np.einsum("il,jk->ijkl", _I, _I))


# ---------------------------------------------------------------------------
# Kinematic helpers
# ---------------------------------------------------------------------------
def _as_F(F):
    F = np.asarray(F, dtype=float)
    if F.ndim < 2 or F.shape[-2:] != (3, 3):
        raise ValueError(f"deformation gradient must have shape (..., 3, 3), got {F.shape}")
    return F


def _safe_J(F):
    """det F, with NaN where det F <= 0 (or non-finite) so that everything
    computed from it is NaN for inverted particles."""
    with np.errstate(invalid="ignore", over="ignore"):
        J = _det3(F)
    return np.where(J > 0.0, J, np.nan)


def _det3(F):
    """det of (..., 3, 3) by the closed form (LAPACK per matrix is ~20x slower)."""
    return (F[..., 0, 0] * (F[..., 1, 1] * F[..., 2, 2] - F[..., 1, 2] * F[..., 2, 1])
            - F[..., 0, 1] * (F[..., 1, 0] * F[..., 2, 2] - F[..., 1, 2] * F[..., 2, 0])
            + F[..., 0, 2] * (F[..., 1, 0] * F[..., 2, 1] - F[..., 1, 1] * F[..., 2, 0]))


def _left_cauchy_green(F):
    """b = F F^T."""
    return np.matmul(F, np.swapaxes(F, -1, -2))


def _trace(A):
    return A[..., 0, 0] + A[..., 1, 1] + A[..., 2, 2]


def _outer(A, B):
    return A[..., :, :, None, None] * B[..., None, None, :, :]


# ---------------------------------------------------------------------------
# Uncoupled neo-Hookean (Guilkey & Weiss 2003, eq. 17-21)
# ---------------------------------------------------------------------------
def uncoupled_neo_hookean_energy(F, mu, kappa):
    """W = mu/2 (tr C~ - 3) + kappa/2 (ln J)^2, C~ = J^(-2/3) C  (G&W eq. 17, 20).

    Per unit reference volume; NaN where det F <= 0.
    """
    F = _as_F(F)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        J = _safe_J(F)
        trC = np.sum(F * F, axis=(-2, -1))
        lnJ = np.log(J)
        return 0.5 * mu * (J ** (-2.0 / 3.0) * trC - 3.0) + 0.5 * kappa * lnJ**2


def uncoupled_neo_hookean(F, mu, kappa, tangent=True):
    """Cauchy stress and spatial elasticity tensor of the uncoupled neo-Hookean
    model (G&W eq. 18, 20, 21).

    With U(J) = kappa/2 (ln J)^2 (so J U' = kappa ln J) and b~ = J^(-2/3) F F^T:

        tau   = J sigma = kappa ln J I + mu dev(b~)                        (eq. 18)
        J c   = kappa I(x)I - 2 kappa ln J  I_s
                + 2 mu_bar (I_s - 1/3 I(x)I)
                - 2/3 (dev tau (x) I + I (x) dev tau)                      (eq. 21)

    where I_s is the symmetric fourth-order identity and
    mu_bar = mu tr(b~)/3.  Note eq. 21 as printed is J c (its terms are the
    Kirchhoff-based ones, with (JU')'J = kappa, J s = dev tau) and its "2 mu"
    is the effective 2 mu_bar, which equals 2 mu only at tr(b~) = 3.  Checked
    against finite differences in tests/test_materials.py.

    Returns ``(sigma, c)``; ``c`` is None if ``tangent`` is False.
    """
    F = _as_F(F)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        J = _safe_J(F)
        Jx = J[..., None, None]
        lnJ = np.log(J)[..., None, None]
        bbar = J[..., None, None] ** (-2.0 / 3.0) * _left_cauchy_green(F)
        trb = _trace(bbar)[..., None, None]
        dev_tau = mu * (bbar - trb / 3.0 * _I)
        tau = kappa * lnJ * _I + dev_tau
        sigma = tau / Jx
        if not tangent:
            return sigma, None
        e = (Ellipsis,) + (None,) * 4  # broadcast scalars over ijkl
        mu_bar = mu * _trace(bbar) / 3.0
        Jc = (
            kappa * _II
            - 2.0 * kappa * np.log(J)[e] * _IS
            + 2.0 * mu_bar[e] * (_IS - _II / 3.0)
            - (2.0 / 3.0) * (_outer(dev_tau, _I) + _outer(_I, dev_tau))
        )
        c = Jc / J[e]
    return sigma, c


# ---------------------------------------------------------------------------
# Compressible neo-Hookean (Guilkey MPM intro, appendix A, eq. 11)
# ---------------------------------------------------------------------------
def compressible_neo_hookean_energy(F, lam, mu):
    """W = lam/4 (J^2 - 1) - (lam/2 + mu) ln J + mu/2 (tr(F^T F) - 3)  (eq. 11).

    Per unit reference volume; NaN where det F <= 0.
    """
    F = _as_F(F)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        J = _safe_J(F)
        trC = np.sum(F * F, axis=(-2, -1))
        return 0.25 * lam * (J**2 - 1.0) - (0.5 * lam + mu) * np.log(J) + 0.5 * mu * (trC - 3.0)


def compressible_neo_hookean(F, lam, mu, tangent=True):
    """Cauchy stress and spatial elasticity tensor of the compressible
    neo-Hookean model of eq. 11.

    Derived here from eq. 11 (tau = J dW/dJ I + mu F F^T):

        sigma = lam/2 (J - 1/J) I + mu/J (F F^T - I)

    The printed eq. 12 of the source, "mu (F F^T) - I", drops the 1/J factor
    and misplaces the parenthesis; the form above is the correct derivative
    (verified by finite differences in tests/test_materials.py).  Tangent:

        c = lam J I(x)I + (2 mu - lam (J^2 - 1)) / J  I_s
          = lam J d_ij d_kl + (mu - lam/2 (J^2 - 1)) / J (d_ik d_jl + d_il d_jk)

    Returns ``(sigma, c)``; ``c`` is None if ``tangent`` is False.
    """
    F = _as_F(F)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        J = _safe_J(F)
        Jx = J[..., None, None]
        tau = 0.5 * lam * (Jx**2 - 1.0) * _I + mu * (_left_cauchy_green(F) - _I)
        sigma = tau / Jx
        if not tangent:
            return sigma, None
        e = (Ellipsis,) + (None,) * 4
        Je = J[e]
        c = lam * Je * _II + (2.0 * mu - lam * (Je**2 - 1.0)) / Je * _IS
    return sigma, c


# ---------------------------------------------------------------------------
# Post-processing
# ---------------------------------------------------------------------------
def von_mises(sigma):
    """Von Mises equivalent stress sqrt(3/2 s:s), s = dev(sigma); shape (...)."""
    sigma = np.asarray(sigma, dtype=float)
    s = sigma - _trace(sigma)[..., None, None] / 3.0 * _I
    return np.sqrt(1.5 * np.sum(s * s, axis=(-2, -1)))


# ---------------------------------------------------------------------------
# Material classes: thin parameter holders with a common interface
# ---------------------------------------------------------------------------
class Material:
    """Common interface.  Subclasses set ``name`` and implement ``_kernel``
    and ``_energy``."""

    name = "material"
    #: history variables carried by particles: name -> per-particle shape
    history = {}

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


class UncoupledNeoHookean(Material):
    """Uncoupled neo-Hookean of Guilkey & Weiss (2003), eq. 17-21."""

    name = "neo_hookean"

    def _kernel(self, F, tangent):
        return uncoupled_neo_hookean(F, self.shear_modulus, self.bulk_modulus, tangent=tangent)

    def _energy(self, F):
        return uncoupled_neo_hookean_energy(F, self.shear_modulus, self.bulk_modulus)


class CompressibleNeoHookean(Material):
    """Compressible neo-Hookean of the MPM introduction, eq. 11;
    lambda = kappa - 2/3 mu."""

    name = "neo_hookean_compressible"

    def _kernel(self, F, tangent):
        return compressible_neo_hookean(F, self.lame_lambda, self.shear_modulus, tangent=tangent)

    def _energy(self, F):
        return compressible_neo_hookean_energy(F, self.lame_lambda, self.shear_modulus)


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


class SmallStrainElastic(Material):
    """Linear elasticity in the accumulated small strain (Sulsky & Kaul's
    bars; ``pimpm/small_strain.py``). Not objective: for small rotations."""

    name = "linear_elastic"
    history = {"strain": (3, 3), "deformation_gradient": (3, 3)}

    def _hooke(self, eps):
        tr = np.trace(eps, axis1=-2, axis2=-1)[..., None, None]
        return self.bulk_modulus * tr * _I + 2.0 * self.shear_modulus * (eps - tr / 3.0 * _I)

    def _strain(self, F, history):
        if history and "strain" in history:
            d_eps, F_inc = small_strain.strain_increment(F, history["deformation_gradient"])
            return history["strain"] + d_eps, F_inc
        return small_strain.small_strain(F), F      # no history: total small strain

    def update(self, F, history, tangent=True):
        F = _as_F(F)
        eps, F_inc = self._strain(F, history)
        sigma = self._hooke(eps)
        c = None
        if tangent:
            D = self.bulk_modulus * small_strain.II + 2.0 * self.shear_modulus * small_strain.IDEV
            c = small_strain.spatial_tangent(sigma, np.broadcast_to(D, (len(F),) + D.shape), F_inc)
        return sigma, c, {"strain": eps, "deformation_gradient": F.copy()}

    def _kernel(self, F, tangent):
        sigma, c, _ = self.update(F, {}, tangent)
        return sigma, c

    def strain_energy(self, F, history=None):
        eps = history["strain"] if history else small_strain.small_strain(_as_F(F))
        eps_p = history.get("plastic_strain", 0.0) if history else 0.0
        return 0.5 * np.sum(self._hooke(eps - eps_p) * (eps - eps_p), axis=(-2, -1))

    def _energy(self, F):
        return self.strain_energy(F)


class J2SmallStrain(PlasticParameters, SmallStrainElastic):
    """Small-strain von Mises plasticity with the bilinear hardening /
    softening of Sulsky & Kaul eq. 2.1.19 and radial return; history:
    accumulated strain, plastic strain, equivalent plastic strain, plastic
    work density."""

    name = "j2_small_strain"
    history = {"strain": (3, 3), "deformation_gradient": (3, 3), "plastic_strain": (3, 3),
               "eq_plastic_strain": (), "plastic_work": ()}

    def update(self, F, history, tangent=True):
        F = _as_F(F)
        eps, F_inc = self._strain(F, history)
        n = len(F)
        eps_p = history.get("plastic_strain", np.zeros((n, 3, 3))) if history else np.zeros((n, 3, 3))
        alpha = history.get("eq_plastic_strain", np.zeros(n)) if history else np.zeros(n)
        work0 = history.get("plastic_work", np.zeros(n)) if history else np.zeros(n)
        sigma, D, eps_p_new, alpha_new, work = small_strain.j2_return(
            eps, eps_p, alpha, self.shear_modulus, self.bulk_modulus, self.yield_stress,
            self.hardening_modulus, self.softening_strain, self.softening_modulus)
        c = small_strain.spatial_tangent(sigma, D, F_inc) if tangent else None
        return sigma, c, {"strain": eps, "deformation_gradient": F.copy(),
                          "plastic_strain": eps_p_new, "eq_plastic_strain": alpha_new,
                          "plastic_work": work0 + work}


class J2FiniteStrain(PlasticParameters, Material):
    """Finite-strain von Mises plasticity: multiplicative split with the
    uncoupled neo-Hookean elastic part, isochoric radial return and its
    consistent tangent (``pimpm/finite_plasticity.py``); Sulsky & Kaul's
    bilinear hardening / softening."""

    name = "j2_finite_strain"
    history = {"deformation_gradient": (3, 3), "elastic_left_cauchy_green": (3, 3),
               "eq_plastic_strain": (), "plastic_work": ()}

    def update(self, F, history, tangent=True):
        F = _as_F(F)
        n = len(F)
        eye = np.broadcast_to(np.eye(3), (n, 3, 3))
        F_n = history.get("deformation_gradient", eye) if history else eye
        bbar_n = history.get("elastic_left_cauchy_green", eye) if history else eye
        alpha_n = history.get("eq_plastic_strain", np.zeros(n)) if history else np.zeros(n)
        work_n = history.get("plastic_work", np.zeros(n)) if history else np.zeros(n)
        sigma, c, bbar, alpha, work = finite_plasticity.j2_finite(
            F, F_n, bbar_n, alpha_n, self.shear_modulus, self.bulk_modulus, self.yield_stress,
            self.hardening_modulus, self.softening_strain, self.softening_modulus, tangent)
        return sigma, c, {"deformation_gradient": F.copy(), "elastic_left_cauchy_green": bbar,
                          "eq_plastic_strain": alpha, "plastic_work": work_n + work}

    def _kernel(self, F, tangent):
        sigma, c, _ = self.update(F, {}, tangent)
        return sigma, c

    def strain_energy(self, F, history=None):
        """Stored energy of the elastic part: kappa/2 (ln J)^2 + mu/2 (tr bbar_e - 3),
        with bbar_e made unimodular first: the return map (Simo & Hughes Box
        9.1) keeps tr bbar_e and lets det bbar_e drift below 1 under plastic
        flow, which would leave plastic work counted as stored energy."""
        F = _as_F(F)
        J = np.linalg.det(F)
        bbar = history["elastic_left_cauchy_green"] if history else \
            J[:, None, None] ** (-2.0 / 3.0) * np.matmul(F, np.swapaxes(F, 1, 2))
        bbar = bbar * smallmat.det(bbar)[:, None, None] ** (-1.0 / 3.0)
        return 0.5 * self.bulk_modulus * np.log(J) ** 2 + 0.5 * self.shear_modulus * (
            np.trace(bbar, axis1=1, axis2=2) - 3.0)

    def _energy(self, F):
        return self.strain_energy(F)


MODELS = {
    "neo_hookean": UncoupledNeoHookean,
    "neo_hookean_compressible": CompressibleNeoHookean,
    "linear_elastic": SmallStrainElastic,
    "j2_small_strain": J2SmallStrain,
    "j2_finite_strain": J2FiniteStrain,
}


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


def make_material(spec):
    """Build a Material from a spec dict such as
    ``{"model": "neo_hookean", "density": 10.0, "shear_modulus": 6e6, "bulk_modulus": 6e7}``.
    Other keys are ignored."""
    model = spec.get("model")
    if model not in MODELS:
        raise ValueError(f"unknown material model {model!r}; known: {sorted(MODELS)}")
    if "density" not in spec:
        raise ValueError("material spec needs a density")
    mu, kappa = elastic_moduli(spec)
    if model in ("j2_small_strain", "j2_finite_strain"):
        extra = {k: spec[k] for k in ("yield_stress", "hardening_modulus", "softening_strain",
                                      "softening_modulus") if spec.get(k) is not None}
        return MODELS[model](mu, kappa, spec["density"], **extra)
    return MODELS[model](mu, kappa, spec["density"])
