"""Finite-strain J2 plasticity: multiplicative split F = Fe Fp, the
uncoupled neo-Hookean elastic part of Guilkey & Weiss (eq. 20), von Mises
yield on the Kirchhoff stress with the bilinear hardening / softening of
Sulsky & Kaul eq. 2.1.19, the isochoric radial return on the elastic left
Cauchy-Green tensor and its consistent spatial tangent (Simo & Hughes 1998,
Boxes 9.1 and 9.2, without their symmetrization of the last term). Pure functions of arrays.

History: bbar_e (isochoric elastic left Cauchy-Green tensor, 1 initially),
the equivalent plastic strain alpha and the plastic work density. The
return starts from the values at t and the relative deformation
f = F F_n^-1 of the step.
"""
import numpy as np

from pimpm.materials import tensors
from .base import Material, PlasticParameters
from .small_strain import linear_yield_stress, yield_stress
from pimpm.materials.tensors import I3, II, IS, as_F as _as_F, outer as _outer

SQ23 = np.sqrt(2.0 / 3.0)


def j2_finite(F, F_n, bbar_n, alpha_n, mu, kappa, tau0, h1, alpha_l=np.inf, h2=0.0, tangent=True):
    """Returns sigma (Cauchy), c (spatial tangent per current volume, the
    solver's convention) or None, bbar_e, alpha, plastic work increment."""
    n = len(F)
    J = np.linalg.det(F)
    f = np.matmul(F, np.linalg.inv(F_n))
    fbar = np.linalg.det(f)[:, None, None] ** (-1.0 / 3.0) * f
    b_trial = np.matmul(np.matmul(fbar, bbar_n), np.swapaxes(fbar, 1, 2))
    Ie = np.trace(b_trial, axis1=1, axis2=2) / 3.0
    s_trial = mu * (b_trial - Ie[:, None, None] * I3)
    norm = np.sqrt(np.sum(s_trial * s_trial, axis=(1, 2)))
    mu_bar = mu * Ie
    f_trial = norm - SQ23 * yield_stress(alpha_n, tau0, h1, alpha_l, h2)
    plastic = f_trial > 1e-12 * tau0
    slope = np.where(alpha_n < alpha_l, h1, -h2)
    d_gamma = np.where(plastic, f_trial / (2.0 * mu_bar * (1.0 + slope / (3.0 * mu_bar))), 0.0)
    crossed = plastic & (alpha_n < alpha_l) & (alpha_n + SQ23 * d_gamma > alpha_l)
    if np.any(crossed):
        # first up to alpha_l on the hardening line, the rest on the softening line
        tau_l = tau0 + h1 * alpha_l
        g1 = (alpha_l - alpha_n) / SQ23
        rest = norm - 2.0 * mu_bar * g1 - SQ23 * tau_l
        d_gamma = np.where(crossed, g1 + rest / (2.0 * mu_bar * (1.0 - h2 / (3.0 * mu_bar))), d_gamma)
        slope = np.where(crossed, -h2, slope)
    spent = plastic & ((d_gamma < 0.0) | (linear_yield_stress(alpha_n + SQ23 * d_gamma, tau0, h1, alpha_l, h2) <= 0.0))
    d_gamma = np.where(spent, norm / (2.0 * mu_bar), d_gamma)      # no strength left
    slope = np.where(spent, 0.0, slope)
    safe = np.where(norm > 0, norm, 1.0)
    unit = s_trial / safe[:, None, None]
    s = s_trial - (2.0 * mu_bar * d_gamma)[:, None, None] * unit
    bbar = s / mu + Ie[:, None, None] * I3
    alpha = alpha_n + SQ23 * d_gamma
    lnJ = np.log(J)
    tau = (kappa * lnJ)[:, None, None] * I3 + s
    sigma = tau / J[:, None, None]
    work = d_gamma * np.sqrt(np.sum(s * s, axis=(1, 2)))
    if not tangent:
        return sigma, None, bbar, alpha, work
    e = (slice(None),) + (None,) * 4
    # elastic trial tangent (Kirchhoff based): volumetric + isochoric parts
    cbar_trial = 2.0 * mu_bar[e] * (IS - II / 3.0) - (2.0 / 3.0) * norm[e] * (
        _outer(unit, np.broadcast_to(I3, (n, 3, 3))) + _outer(np.broadcast_to(I3, (n, 3, 3)), unit))
    Jc = kappa * II - 2.0 * (kappa * lnJ)[e] * IS + cbar_trial
    if np.any(plastic):
        beta0 = 1.0 + slope / (3.0 * mu_bar)
        beta1 = 2.0 * mu_bar * d_gamma / safe
        beta2 = (1.0 - 1.0 / beta0) * (2.0 / 3.0) * norm / mu_bar * d_gamma
        beta3 = 1.0 / beta0 - beta1 + beta2
        beta4 = (1.0 / beta0 - beta1) * norm / mu_bar
        n2 = np.matmul(unit, unit)
        dev_n2 = n2 - (np.trace(n2, axis1=1, axis2=2) / 3.0)[:, None, None] * I3
        # Simo & Hughes symmetrize this last term; the exact derivative of the
        # return map is n (x) dev(n^2) (checked by finite differences in
        # tests/test_plasticity.py), so the tangent is not symmetric: use a
        # non-symmetric Krylov solver (gmres-gamg) or the direct solver.
        plastic_part = (beta1[e] * cbar_trial + 2.0 * (mu_bar * beta3)[e] * _outer(unit, unit)
                        + 2.0 * (mu_bar * beta4)[e] * _outer(unit, dev_n2))
        Jc = Jc - np.where(plastic[e], plastic_part, 0.0)
    return sigma, Jc / J[e], bbar, alpha, work


class J2FiniteStrain(PlasticParameters, Material):
    """Finite-strain von Mises plasticity: multiplicative split with the
    uncoupled neo-Hookean elastic part, isochoric radial return and its
    consistent tangent (:func:`j2_finite`); Sulsky & Kaul's
    bilinear hardening / softening."""

    name = "j2_finite_strain"
    symmetric_tangent = False        # the exact return-map derivative (see tangent above)
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
        sigma, c, bbar, alpha, work = j2_finite(
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
        bbar = bbar * tensors.det(bbar)[:, None, None] ** (-1.0 / 3.0)
        return 0.5 * self.bulk_modulus * np.log(J) ** 2 + 0.5 * self.shear_modulus * (
            np.trace(bbar, axis1=1, axis2=2) - 3.0)

    def _energy(self, F):
        return self.strain_energy(F)
