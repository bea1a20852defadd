"""Hyperelastic neo-Hookean models, vectorised over particles.

``F`` has shape ``(..., 3, 3)`` (normally ``(n, 3, 3)``); plane-strain
problems pass 3x3 tensors with ``F[2, 2] = 1`` and zero off-plane entries.
Outputs: Cauchy stress ``sigma`` (..., 3, 3), spatial elasticity tensor ``c``
(..., 3, 3, 3, 3) (convention: :mod:`pimpm.materials.base`) and strain energy
``W`` (...) per unit *reference* volume.

Inverted particles (``det F <= 0`` or non-finite) give NaN in all outputs for
those particles, without raising or warning; the caller detects them.

References: Guilkey & Weiss (2003), IJNME, section 4, eq. 17-21 (uncoupled
neo-Hookean); Guilkey, "An Introduction to the Material Point Method",
appendix A, eq. 11 (compressible neo-Hookean).
"""
import numpy as np

from .base import Material
from pimpm.materials.tensors import as_F as _as_F, I3 as _I, II as _II, IS as _IS, det as _det3, outer as _outer, trace as _trace


def _safe_J(F):
    """det F, with NaN where det F <= 0 (or non-finite) so that everything
    computed from it is NaN for inverted particles."""
    with np.errstate(invalid="ignore", over="ignore"):
        J = _det3(F)
    return np.where(J > 0.0, J, np.nan)


def _jacobian_and_trace_c(F):
    """J = det F (NaN where inverted) and tr C = tr(F^T F), for the energies."""
    F = _as_F(F)
    with np.errstate(invalid="ignore", over="ignore"):
        return _safe_J(F), np.sum(F * F, axis=(-2, -1))


def _left_cauchy_green(F):
    """b = F F^T."""
    return np.matmul(F, np.swapaxes(F, -1, -2))


# ---------------------------------------------------------------------------
# Uncoupled neo-Hookean (Guilkey & Weiss 2003, eq. 17-21)
# ---------------------------------------------------------------------------
def uncoupled_neo_hookean_energy(F, mu, kappa):
    """W = mu/2 (tr C~ - 3) + kappa/2 (ln J)^2, C~ = J^(-2/3) C  (G&W eq. 17, 20).

    Per unit reference volume; NaN where det F <= 0.
    """
    J, trC = _jacobian_and_trace_c(F)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        return 0.5 * mu * (J ** (-2.0 / 3.0) * trC - 3.0) + 0.5 * kappa * np.log(J)**2


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
    J, trC = _jacobian_and_trace_c(F)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
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
