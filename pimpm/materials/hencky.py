"""Hencky's hyperelastic model (logarithmic strain): with the left stretch
V = sqrt(b), b = F F^T = sum_A lambda_A^2 n_A (x) n_A, and eps = ln V,

    W   = lam/2 (tr eps)^2 + mu eps : eps
    tau = J sigma = lam tr(eps) 1 + 2 mu eps,   tau_A = lam sum_B x_B + 2 mu x_A,  x_A = ln lambda_A

Its exact spatial tangent, in the principal directions m_A = n_A (x) n_A,
m_AB = n_A (x) n_B (Simo & Hughes 1998, section 7.1; Miehe 1998):

    J c = sum_AB (D_AB - 2 tau_A d_AB) m_A (x) m_B
          + sum_(A != B) k_AB (m_AB (x) m_AB + m_AB (x) m_BA),
    D_AB = lam + 2 mu d_AB,
    k_AB = (tau_A lambda_B^2 - tau_B lambda_A^2) / (lambda_A^2 - lambda_B^2)
         = mu 2 d / (exp(2 d) - 1) - tau_B,   d = x_A - x_B,

the last form exact for tau_A - tau_B = 2 mu d and free of the 0/0 of
equal stretches (its limit is mu - tau_B). The principal stretches and
directions come from the Jacobi eigensolver of :mod:`pimpm.kernels.small`.
In uniaxial strain with nu = 0: sigma = E ln(lambda) / lambda.
"""
import math

import numpy as np

from ..kernels.jit import jit
from ..kernels.small import det3, matmul3_bt, symmetric_eigen3
from .common import fill_nan
from .model import Model


@jit
def _principal(F, w):
    """Principal logarithmic stretches x (3,) and directions (columns of w[1])
    of b = F F^T: b in w[0], the eigenvalues of b in w[2, 0], x in w[2, 1]."""
    b = w[0]
    matmul3_bt(F, F, b)
    values = w[2, 0]
    symmetric_eigen3(b, values, w[1])
    x = w[2, 1]
    for a in range(3):
        x[a] = 0.5 * math.log(values[a])
    return x


@jit
def point(prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane):
    mu, kappa = prm[0], prm[1]
    lam = kappa - 2.0 / 3.0 * mu
    J = det3(F)
    if not (J > 0.0):
        fill_nan(sigma, c, want_c)
        return
    x = _principal(F, w)
    n = w[1]
    tr = x[0] + x[1] + x[2]
    tau = w[2, 2]
    for a in range(3):
        tau[a] = lam * tr + 2.0 * mu * x[a]
    for i in range(3):
        for j in range(3):
            s = 0.0
            for a in range(3):
                s += tau[a] * n[i, a] * n[j, a]
            sigma[i, j] = s / J
    if not want_c:
        return
    for i in range(3):
        for j in range(3):
            for k in range(3):
                for m in range(3):
                    c[i, j, k, m] = 0.0
    for a in range(3):
        for b in range(3):
            coefficient = (lam + (2.0 * mu - 2.0 * tau[a] if a == b else 0.0)) / J
            for i in range(3):
                for j in range(3):
                    mij = coefficient * n[i, a] * n[j, a]
                    for k in range(3):
                        for m in range(3):
                            c[i, j, k, m] += mij * n[k, b] * n[m, b]
            if a == b:
                continue
            d = x[a] - x[b]
            ratio = 1.0 if d == 0.0 else 2.0 * d / math.expm1(2.0 * d)
            kab = (mu * ratio - tau[b]) / J
            for i in range(3):
                for j in range(3):
                    mab_ij = kab * n[i, a] * n[j, b]
                    for k in range(3):
                        for m in range(3):
                            c[i, j, k, m] += mab_ij * (n[k, a] * n[m, b] + n[k, b] * n[m, a])


@jit
def energy(prm, F, h):
    """lam/2 (tr eps)^2 + mu eps : eps = lam/2 (sum x_A)^2 + mu sum x_A^2."""
    mu, kappa = prm[0], prm[1]
    if not (det3(F) > 0.0):
        return math.nan
    w = np.empty((3, 3, 3))
    x = _principal(F, w)
    tr = x[0] + x[1] + x[2]
    return 0.5 * (kappa - 2.0 / 3.0 * mu) * tr * tr + mu * (x[0] * x[0] + x[1] * x[1] + x[2] * x[2])


MODEL = Model("hencky", point, energy)
