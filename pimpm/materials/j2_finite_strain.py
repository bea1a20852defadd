"""Finite-strain J2 plasticity: multiplicative split F = Fe Fp, the
uncoupled neo-Hookean elastic part of Guilkey & Weiss (eq. 20), von Mises
yield on the Kirchhoff stress with the bilinear hardening / softening of
Sulsky & Kaul eq. 2.1.19, the isochoric radial return on the elastic left
Cauchy-Green tensor and its exact consistent spatial tangent (Simo & Hughes
1998, Boxes 9.1 and 9.2, without their symmetrization of the last term: the
tangent is not symmetric).

History: F at t, bbar_e (isochoric elastic left Cauchy-Green tensor, 1
initially), the equivalent plastic strain alpha and the plastic work
density. The return starts from the values at t and the relative
deformation f = F F_n^-1 of the step.
"""
import math

import numpy as np

from ..kernels.jit import jit
from ..kernels.small import det3, matmul3, matmul3_bt, trace3
from .common import SQ23, identity_dyad, linear_yield_stress, strain_increment, sym_identity, yield_stress
from .model import PLASTICITY, Model, history_offsets, parameter_offsets

HISTORY = {"deformation_gradient": (3, 3), "elastic_left_cauchy_green": (3, 3),
           "eq_plastic_strain": (), "plastic_work": ()}
_H = history_offsets(HISTORY)
DEFORMATION_GRADIENT, BBAR = _H["deformation_gradient"], _H["elastic_left_cauchy_green"]
EQ_PLASTIC_STRAIN, PLASTIC_WORK = _H["eq_plastic_strain"], _H["plastic_work"]
_P = parameter_offsets(PLASTICITY)
YIELD_STRESS, HARDENING, SOFTENING_STRAIN, SOFTENING = (_P["yield_stress"], _P["hardening_modulus"],
                                                         _P["softening_strain"], _P["softening_modulus"])


@jit
def point(prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane):
    mu, kappa = prm[0], prm[1]
    tau0, h1, alpha_l, h2 = prm[YIELD_STRESS], prm[HARDENING], prm[SOFTENING_STRAIN], prm[SOFTENING]
    J = det3(F)
    f = strain_increment(F, h_in, DEFORMATION_GRADIENT, w)     # relative deformation F F_n^-1 in w[2]
    fbar = w[3]
    s3 = det3(f) ** (-1.0 / 3.0)
    for i in range(3):
        for j in range(3):
            fbar[i, j] = s3 * f[i, j]
    bn = w[4]
    for i in range(3):
        for j in range(3):
            bn[i, j] = h_in[BBAR + 3 * i + j]
    tmp = w[5]
    matmul3(fbar, bn, tmp)
    b_trial = w[6]
    matmul3_bt(tmp, fbar, b_trial)
    Ie = trace3(b_trial) / 3.0
    s_trial = w[7]
    norm2 = 0.0
    for i in range(3):
        for j in range(3):
            s_trial[i, j] = mu * (b_trial[i, j] - (Ie if i == j else 0.0))
            norm2 += s_trial[i, j] * s_trial[i, j]
    norm = math.sqrt(norm2)
    mu_bar = mu * Ie
    alpha_n = h_in[EQ_PLASTIC_STRAIN]
    f_trial = norm - SQ23 * yield_stress(alpha_n, tau0, h1, alpha_l, h2)
    plastic = f_trial > 1e-12 * tau0
    slope = h1 if alpha_n < alpha_l else -h2
    d_gamma = 0.0
    if plastic:
        d_gamma = f_trial / (2.0 * mu_bar * (1.0 + slope / (3.0 * mu_bar)))
        if alpha_n < alpha_l and alpha_n + SQ23 * d_gamma > alpha_l:
            tau_l = tau0 + h1 * alpha_l
            g1 = (alpha_l - alpha_n) / SQ23
            rest = norm - 2.0 * mu_bar * g1 - SQ23 * tau_l
            d_gamma = g1 + rest / (2.0 * mu_bar * (1.0 - h2 / (3.0 * mu_bar)))
            slope = -h2
        if d_gamma < 0.0 or linear_yield_stress(alpha_n + SQ23 * d_gamma, tau0, h1, alpha_l, h2) <= 0.0:
            # no strength left, or softening faster than the elastic stiffness (snap-back:
            # the return had no solution of growing plastic strain): the deviator returns to zero
            d_gamma = norm / (2.0 * mu_bar)
            slope = 0.0
    safe = norm if norm > 0 else 1.0
    unit = w[0]                                    # (F_n, F_n^-1 no longer needed)
    s = w[1]
    lnJ = math.log(J) if J > 0 else math.nan
    s_norm2 = 0.0
    for i in range(3):
        for j in range(3):
            unit[i, j] = s_trial[i, j] / safe
            s[i, j] = s_trial[i, j] - 2.0 * mu_bar * d_gamma * unit[i, j]
            s_norm2 += s[i, j] * s[i, j]
            h_out[DEFORMATION_GRADIENT + 3 * i + j] = F[i, j]
            h_out[BBAR + 3 * i + j] = s[i, j] / mu + (Ie if i == j else 0.0)
            sigma[i, j] = ((kappa * lnJ if i == j else 0.0) + s[i, j]) / J
    h_out[EQ_PLASTIC_STRAIN] = alpha_n + SQ23 * d_gamma
    h_out[PLASTIC_WORK] = h_in[PLASTIC_WORK] + d_gamma * math.sqrt(s_norm2)
    if not want_c:
        return
    beta1 = beta3 = beta4 = 0.0
    dev_n2 = w[2]
    if plastic:
        beta0 = 1.0 + slope / (3.0 * mu_bar)
        beta1 = 2.0 * mu_bar * d_gamma / safe
        beta2 = (1.0 - 1.0 / beta0) * (2.0 / 3.0) * norm / mu_bar * d_gamma
        beta3 = 1.0 / beta0 - beta1 + beta2
        beta4 = (1.0 / beta0 - beta1) * norm / mu_bar
        matmul3(unit, unit, tmp)
        tr_n2 = trace3(tmp)
        for i in range(3):
            for j in range(3):
                dev_n2[i, j] = tmp[i, j] - (tr_n2 / 3.0 if i == j else 0.0)
    for i in range(3):
        for j in range(3):
            for k in range(3):
                for m in range(3):
                    ii = identity_dyad(i, j, k, m)
                    sym = sym_identity(i, j, k, m)
                    cbar = (2.0 * mu_bar * (sym - ii / 3.0)
                            - (2.0 / 3.0) * norm * (unit[i, j] * (1.0 if k == m else 0.0)
                                                    + (1.0 if i == j else 0.0) * unit[k, m]))
                    jc = kappa * ii - 2.0 * kappa * lnJ * sym + cbar
                    if plastic:
                        # the exact derivative of the return map: n (x) dev(n^2), not symmetrized
                        jc -= (beta1 * cbar + 2.0 * mu_bar * beta3 * unit[i, j] * unit[k, m]
                               + 2.0 * mu_bar * beta4 * unit[i, j] * dev_n2[k, m])
                    c[i, j, k, m] = jc / J


@jit
def energy(prm, F, h):
    """kappa/2 (ln J)^2 + mu/2 (tr bbar_e - 3), bbar_e made unimodular first:
    the return map (Simo & Hughes Box 9.1) keeps tr bbar_e and lets det
    bbar_e drift below 1 under plastic flow, which would leave plastic work
    counted as stored energy."""
    J = det3(F)
    b = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            b[i, j] = h[BBAR + 3 * i + j]
    s = det3(b) ** (-1.0 / 3.0)
    lnJ = math.log(J) if J > 0.0 else math.nan
    return 0.5 * prm[1] * lnJ * lnJ + 0.5 * prm[0] * (s * trace3(b) - 3.0)


MODEL = Model("j2_finite_strain", point, energy, parameters=PLASTICITY, history=HISTORY,
              symmetric_tangent=False, identity_history=("deformation_gradient", "elastic_left_cauchy_green"),
              output=("eq_plastic_strain", "plastic_work"))
