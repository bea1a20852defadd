"""Small-strain linear elasticity and J2 plasticity with Sulsky & Kaul's
bilinear hardening / softening (eq. 2.1.13-2.1.19), radial return and its
algorithmic tangent, as pure functions of arrays: the numpy reference of
pimpm/materials/small_strain.py, whose docstring gives the accumulated
strain and the exact spatial tangent both compute."""
import numpy as np

from .base import Material, PlasticParameters
from pimpm.materials.tensors import I3, II, IDEV, as_F as _as_F


def small_strain(F):
    return 0.5 * (F + np.swapaxes(F, -1, -2)) - I3


def strain_increment(F, F_n):
    """eps increment sym(F F_n^-1) - 1 and the increment F_inc = F F_n^-1."""
    F_inc = np.matmul(F, np.linalg.inv(F_n))
    return small_strain(F_inc), F_inc


def spatial_tangent(sigma, D, F):
    """c from the small-strain tangent D (see the module docstring; F is the
    increment F_inc)."""
    c = np.einsum("pab,cd->pabcd", sigma, I3)
    c += np.einsum("pabce,pde->pabcd", D, F)
    c -= np.einsum("ac,pdb->pabcd", I3, sigma)
    c -= np.einsum("bc,pad->pabcd", I3, sigma)
    return c


def linear_yield_stress(alpha, tau0, h1, alpha_l, h2):
    """Sulsky & Kaul eq. 2.1.19: tau0 + h1 alpha up to alpha_l, then
    softening (or hardening) with slope -h2."""
    if not np.isfinite(alpha_l):
        return tau0 + h1 * alpha
    tau_l = tau0 + h1 * alpha_l
    return np.where(alpha <= alpha_l, tau0 + h1 * alpha, tau_l - h2 * (alpha - alpha_l))


def yield_stress(alpha, tau0, h1, alpha_l, h2):
    """eq. 2.1.19 floored at zero: a material that has lost its strength."""
    return np.maximum(linear_yield_stress(alpha, tau0, h1, alpha_l, h2), 0.0)


def j2_return(eps, eps_p, alpha, mu, kappa, tau0, h1, alpha_l=np.inf, h2=0.0):
    """Radial return for von Mises plasticity with piecewise-linear isotropic
    hardening. Returns sigma, D (algorithmic tangent), eps_p_new, alpha_new,
    plastic work increment density."""
    eps_e = eps - eps_p
    tr = np.trace(eps_e, axis1=1, axis2=2)
    dev = eps_e - tr[:, None, None] / 3.0 * I3
    s_trial = 2.0 * mu * dev
    norm = np.sqrt(np.sum(s_trial * s_trial, axis=(1, 2)))
    q_trial = np.sqrt(1.5) * norm
    f_trial = q_trial - yield_stress(alpha, tau0, h1, alpha_l, h2)
    plastic = f_trial > 1e-12 * max(tau0, 1e-300)
    # Delta alpha on the segment alpha_n is on, then on the softening segment if crossed
    slope = np.where(alpha < alpha_l, h1, -h2)
    d_alpha = np.where(plastic, f_trial / (3.0 * mu + slope), 0.0)
    crossed = plastic & (alpha < alpha_l) & (alpha + d_alpha > alpha_l)
    if np.any(crossed):
        tau_l = tau0 + h1 * alpha_l
        d2 = (q_trial - tau_l - 3.0 * mu * (alpha_l - alpha)) / (3.0 * mu - h2)
        d_alpha = np.where(crossed, (alpha_l - alpha) + d2, d_alpha)
        slope = np.where(crossed, -h2, slope)
    spent = plastic & ((d_alpha < 0.0) | (linear_yield_stress(alpha + d_alpha, tau0, h1, alpha_l, h2) <= 0.0))
    d_alpha = np.where(spent, q_trial / (3.0 * mu), d_alpha)       # no strength left
    slope = np.where(spent, 0.0, slope)
    safe = np.where(norm > 0, norm, 1.0)
    unit = s_trial / safe[:, None, None]
    s = s_trial - (2.0 * mu * np.sqrt(1.5) * d_alpha)[:, None, None] * unit
    sigma = kappa * tr[:, None, None] * I3 + s
    eps_p_new = eps_p + (np.sqrt(1.5) * d_alpha)[:, None, None] * unit
    alpha_new = alpha + d_alpha
    # algorithmic tangent (Simo & Hughes, Box 3.2 in terms of q)
    theta = np.where(plastic, 1.0 - 3.0 * mu * d_alpha / np.where(q_trial > 0, q_trial, 1.0), 1.0)
    theta_bar = np.where(plastic, 1.0 / (1.0 + slope / (3.0 * mu)) - (1.0 - theta), 0.0)
    D = (kappa * II + 2.0 * mu * theta[:, None, None, None, None] * IDEV
         - 2.0 * mu * theta_bar[:, None, None, None, None] * np.einsum("pab,pcd->pabcd", unit, unit))
    work = np.sum(s * (eps_p_new - eps_p), axis=(1, 2))
    return sigma, D, eps_p_new, alpha_new, work


class SmallStrainElastic(Material):
    """Linear elasticity in the accumulated small strain (Sulsky & Kaul's
    bars; the functions above). Not objective: for small rotations."""

    name = "linear_elastic"
    # measured 5% asymmetric for j2_small_strain (tests/mpi/jacobian_check.py);
    # linear_elastic shares its kinematics and is not measured: LU for both
    symmetric_tangent = False
    history = {"strain": (3, 3), "deformation_gradient": (3, 3)}

    def _hooke(self, eps):
        tr = np.trace(eps, axis1=-2, axis2=-1)[..., None, None]
        return self.bulk_modulus * tr * I3 + 2.0 * self.shear_modulus * (eps - tr / 3.0 * I3)

    def _strain(self, F, history):
        if history and "strain" in history:
            d_eps, F_inc = strain_increment(F, history["deformation_gradient"])
            return history["strain"] + d_eps, F_inc
        return small_strain(F), F      # no history: total small strain

    def update(self, F, history, tangent=True):
        F = _as_F(F)
        eps, F_inc = self._strain(F, history)
        sigma = self._hooke(eps)
        c = None
        if tangent:
            D = self.bulk_modulus * II + 2.0 * self.shear_modulus * IDEV
            c = spatial_tangent(sigma, np.broadcast_to(D, (len(F),) + D.shape), F_inc)
        return sigma, c, {"strain": eps, "deformation_gradient": F.copy()}

    def _kernel(self, F, tangent):
        sigma, c, _ = self.update(F, {}, tangent)
        return sigma, c

    def strain_energy(self, F, history=None):
        eps = history["strain"] if history else small_strain(_as_F(F))
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
        sigma, D, eps_p_new, alpha_new, work = j2_return(
            eps, eps_p, alpha, self.shear_modulus, self.bulk_modulus, self.yield_stress,
            self.hardening_modulus, self.softening_strain, self.softening_modulus)
        c = spatial_tangent(sigma, D, F_inc) if tangent else None
        return sigma, c, {"strain": eps, "deformation_gradient": F.copy(),
                          "plastic_strain": eps_p_new, "eq_plastic_strain": alpha_new,
                          "plastic_work": work0 + work}
