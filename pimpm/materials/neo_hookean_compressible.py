"""The compressible neo-Hookean model of the MPM introduction, eq. 11:

    W     = lam/4 (J^2 - 1) - (lam/2 + mu) ln J + mu/2 (tr C - 3)
    sigma = lam/2 (J - 1/J) I + mu/J (b - I)     (the printed eq. 12 misses the 1/J)
    c     = lam J I(x)I + (2 mu - lam (J^2 - 1)) / J I_s

with lam = kappa - 2/3 mu.
"""
import math

from ..kernels.jit import jit
from ..kernels.small import det3, matmul3_bt
from .common import fill_nan, isotropic_tangent, trace_right_cauchy_green
from .model import Model


@jit
def point(prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane):
    mu = prm[0]
    lam = prm[1] - 2.0 / 3.0 * mu
    J = det3(F)
    if not (J > 0.0):
        fill_nan(sigma, c, want_c)
        return
    b = w[0]
    matmul3_bt(F, F, b)
    for i in range(3):
        for j in range(3):
            d = 1.0 if i == j else 0.0
            sigma[i, j] = (0.5 * lam * (J * J - 1.0) * d + mu * (b[i, j] - d)) / J
    if want_c:
        a, b = lam * J, (2.0 * mu - lam * (J * J - 1.0)) / J
        if in_plane:
            isotropic_tangent(c, a, b, (0, 1))
        else:
            isotropic_tangent(c, a, b, (0, 1, 2))


@jit
def energy(prm, F, h):
    mu = prm[0]
    lam = prm[1] - 2.0 / 3.0 * mu
    J = det3(F)
    if not (J > 0.0):
        return math.nan
    trC = trace_right_cauchy_green(F)
    return 0.25 * lam * (J * J - 1.0) - (0.5 * lam + mu) * math.log(J) + 0.5 * mu * (trC - 3.0)


MODEL = Model("neo_hookean_compressible", point, energy)
