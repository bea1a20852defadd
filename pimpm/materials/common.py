"""Compiled pieces the material models share: fourth-order identities and
isotropic tangents, Sulsky & Kaul's bilinear yield stress, the relative
deformation of a step, and NaN for an inverted particle."""
import math

import numpy as np

from ..kernels.jit import jit
from ..kernels.small import inv3, matmul3

SQ23 = math.sqrt(2.0 / 3.0)
SQ32 = math.sqrt(1.5)


@jit
def fill_nan(sigma, c, want_c):
    """NaN stress (and tangent): the particle is inverted (det F <= 0)."""
    for i in range(3):
        for j in range(3):
            sigma[i, j] = np.nan
            if want_c:
                for k in range(3):
                    for m in range(3):
                        c[i, j, k, m] = np.nan


@jit
def sym_identity(i, j, k, m):
    """Symmetric fourth-order identity 1/2 (d_ik d_jm + d_im d_jk)."""
    return 0.5 * ((1.0 if (i == k and j == m) else 0.0) + (1.0 if (i == m and j == k) else 0.0))


@jit
def identity_dyad(i, j, k, m):
    """I (x) I."""
    return 1.0 if (i == j and k == m) else 0.0


@jit
def linear_yield_stress(alpha, tau0, h1, alpha_l, h2):
    """Sulsky & Kaul eq. 2.1.19: tau0 + h1 alpha up to alpha_l, then slope -h2."""
    if not math.isfinite(alpha_l) or alpha <= alpha_l:
        return tau0 + h1 * alpha
    return tau0 + h1 * alpha_l - h2 * (alpha - alpha_l)


@jit
def yield_stress(alpha, tau0, h1, alpha_l, h2):
    """eq. 2.1.19, never below zero: softening (or a negative hardening
    modulus) ends in a material without strength, not a negative yield
    stress (issue 32: the plastic strain then ran backwards)."""
    return max(linear_yield_stress(alpha, tau0, h1, alpha_l, h2), 0.0)


@jit
def isotropic_tangent(c, a, b, axes):
    """c = a I(x)I + b I_s (I_s the symmetric fourth-order identity), for
    the indices in ``axes`` ((0, 1): the in-plane entries only; a tuple, so
    that the loops have lengths known when compiling)."""
    n = len(axes)
    for i in range(n):
        for j in range(n):
            for k in range(n):
                for m in range(n):
                    c[i, j, k, m] = 0.0
    for i in range(n):
        for k in range(n):
            c[i, i, k, k] += a
            c[i, k, i, k] += 0.5 * b
            c[i, k, k, i] += 0.5 * b


@jit
def strain_increment(F, h_in, fn_offset, w):
    """F_inc = F F_n^-1 (F_n in the history at ``fn_offset``) in w[2]."""
    Fn = w[0]
    for i in range(3):
        for j in range(3):
            Fn[i, j] = h_in[fn_offset + 3 * i + j]
    Fn_inv = w[1]
    inv3(Fn, Fn_inv)
    F_inc = w[2]
    matmul3(F, Fn_inv, F_inc)
    return F_inc


@jit
def trace_right_cauchy_green(F):
    """tr C = tr(F^T F) = sum of the squares of F's entries."""
    s = 0.0
    for i in range(3):
        for j in range(3):
            s += F[i, j] * F[i, j]
    return s
