"""The uncoupled neo-Hookean model of Guilkey & Weiss (2003), eq. 17-21:

    W     = mu/2 (tr C~ - 3) + kappa/2 (ln J)^2,      C~ = J^(-2/3) C     (eq. 17, 20)
    tau   = J sigma = kappa ln J I + mu dev(b~)                           (eq. 18)
    J c   = kappa I(x)I - 2 kappa ln J I_s + 2 mu_bar (I_s - 1/3 I(x)I)
            - 2/3 (dev tau (x) I + I (x) dev tau),   mu_bar = mu tr(b~)/3  (eq. 21)

Eq. 21 as printed is J c (its terms are the Kirchhoff-based ones) and its
"2 mu" is the effective 2 mu_bar, which equals 2 mu only at tr(b~) = 3.
"""
import math

from ..kernels.jit import jit
from ..kernels.small import det3
from .common import fill_nan, isotropic_tangent, trace_right_cauchy_green
from .model import Model


@jit
def point(prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane):
    mu, kappa = prm[0], prm[1]
    J = det3(F)
    if not (J > 0.0):
        fill_nan(sigma, c, want_c)
        return
    lnJ = math.log(J)
    inv_J = 1.0 / J
    # bbar in w[0], dev tau in w[1], indexed in place: a view such as w[0]
    # costs numba a reference-count pair per call
    f = math.exp(-2.0 / 3.0 * lnJ)          # J^(-2/3)
    for i in range(3):
        for j in range(3):
            s = 0.0
            for k in range(3):
                s += F[i, k] * F[j, k]
            w[0, i, j] = s * f
    trb = w[0, 0, 0] + w[0, 1, 1] + w[0, 2, 2]
    for i in range(3):
        for j in range(3):
            w[1, i, j] = mu * (w[0, i, j] - (trb / 3.0 if i == j else 0.0))
            sigma[i, j] = ((kappa * lnJ if i == j else 0.0) + w[1, i, j]) * inv_J
    if want_c:
        mu_bar = mu * trb / 3.0
        a, b, f = (kappa - 2.0 / 3.0 * mu_bar) * inv_J, 2.0 * (mu_bar - kappa * lnJ) * inv_J, -2.0 / 3.0 * inv_J
        # the axes as a tuple: its length is known when compiling, so the
        # loops have fixed lengths (a run-time bound stops numba unrolling them)
        if in_plane:
            _uncoupled_tangent(c, a, b, f, w, (0, 1))
        else:
            _uncoupled_tangent(c, a, b, f, w, (0, 1, 2))


@jit
def _uncoupled_tangent(c, a, b, f, w, axes):
    """c = a I(x)I + b I_s + f (dev tau (x) I + I (x) dev tau), dev tau in
    w[1], for the indices in ``axes``."""
    isotropic_tangent(c, a, b, axes)
    n = len(axes)
    for i in range(n):
        for j in range(n):
            t = f * w[1, i, j]
            for k in range(n):
                c[i, j, k, k] += t
                c[k, k, i, j] += t


@jit
def energy(prm, F, h):
    """W = mu/2 (J^(-2/3) tr C - 3) + kappa/2 (ln J)^2 (eq. 17, 20)."""
    J = det3(F)
    if not (J > 0.0):
        return math.nan
    trC = trace_right_cauchy_green(F)
    lnJ = math.log(J)
    return 0.5 * prm[0] * (J ** (-2.0 / 3.0) * trC - 3.0) + 0.5 * prm[1] * lnJ * lnJ


MODEL = Model("neo_hookean", point, energy)
