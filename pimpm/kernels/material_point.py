"""One material point of every material model, compiled: the Cauchy stress,
the spatial tangent ``c`` (convention of :mod:`pimpm.materials.base`) and
the history after the deformation ``F``, from the history committed at t.

These are the formulas of the numpy models, written per particle on
scalars (the numpy versions are the references the tests compare with):

* ``NEO_HOOKEAN``: Guilkey & Weiss eq. 17-21 (:mod:`pimpm.materials.neo_hookean`);
* ``NEO_HOOKEAN_COMPRESSIBLE``: MPM introduction eq. 11 (with the 1/J that
  the printed eq. 12 misses);
* ``LINEAR_ELASTIC`` and ``J2_SMALL_STRAIN``: accumulated small strain,
  radial return with Sulsky & Kaul's bilinear hardening (eq. 2.1.13-2.1.19)
  and its algorithmic tangent (:mod:`pimpm.materials.small_strain`);
* ``J2_FINITE_STRAIN``: multiplicative split, isochoric radial return on
  bbar_e and its exact consistent tangent (Simo & Hughes Box 9.1-9.2,
  :mod:`pimpm.materials.finite_plasticity`).

A model's parameters are packed as ``[mu, kappa, yield stress, hardening
modulus, softening strain, softening modulus]`` and its history as the
concatenation of its ``history`` fields in declaration order
(:meth:`pimpm.materials.base.Material.packed_parameters`).
"""
import math

import numpy as np

from numba.extending import overload

from .jit import JIT_OPTIONS, jit
from .small import det3, inv3, matmul3, matmul3_bt, trace3

NEO_HOOKEAN, NEO_HOOKEAN_COMPRESSIBLE, LINEAR_ELASTIC, J2_SMALL_STRAIN, J2_FINITE_STRAIN = range(5)
#: a kernel's ``only`` argument when the particles' materials use several models
MIXED = -1
#: number of scratch 3x3 matrices :func:`material_point` needs
WORKSPACE = 8
SQ23 = math.sqrt(2.0 / 3.0)
SQ32 = math.sqrt(1.5)


@jit
def _fill_nan(sigma, c, want_c):
    for i in range(3):
        for j in range(3):
            sigma[i, j] = np.nan
            if want_c:
                for k in range(3):
                    for m in range(3):
                        c[i, j, k, m] = np.nan


@jit
def _is(i, j, k, m):
    """Symmetric fourth-order identity 1/2 (d_ik d_jm + d_im d_jk)."""
    return 0.5 * ((1.0 if (i == k and j == m) else 0.0) + (1.0 if (i == m and j == k) else 0.0))


@jit
def _ii(i, j, k, m):
    return 1.0 if (i == j and k == m) else 0.0


@jit
def yield_stress(alpha, tau0, h1, alpha_l, h2):
    """Sulsky & Kaul eq. 2.1.19: tau0 + h1 alpha up to alpha_l, then slope -h2."""
    if not math.isfinite(alpha_l) or alpha <= alpha_l:
        return tau0 + h1 * alpha
    return tau0 + h1 * alpha_l - h2 * (alpha - alpha_l)


@jit
def neo_hookean(F, mu, kappa, sigma, c, want_c, w, in_plane):
    """Uncoupled neo-Hookean, G&W eq. 18 and 21 (eq. 21 as J c, with the
    effective 2 mu tr(bbar)/3). ``in_plane``: write only the entries of c
    whose four indices are 0 or 1 (all that plane strain uses)."""
    J = det3(F)
    if not (J > 0.0):
        _fill_nan(sigma, c, want_c)
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
        # J c = (kappa - 2/3 mu_bar) I(x)I + 2 (mu_bar - kappa ln J) I_s
        #       - 2/3 (dev tau (x) I + I (x) dev tau),   mu_bar = mu tr(bbar)/3
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
    _isotropic_tangent(c, a, b, axes)
    n = len(axes)
    for i in range(n):
        for j in range(n):
            t = f * w[1, i, j]
            for k in range(n):
                c[i, j, k, k] += t
                c[k, k, i, j] += t


@jit
def _isotropic_tangent(c, a, b, axes):
    """c = a I(x)I + b I_s (I_s the symmetric fourth-order identity), for
    the indices in ``axes`` ((0, 1): the in-plane entries only)."""
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
def neo_hookean_compressible(F, lam, mu, sigma, c, want_c, w, in_plane):
    """sigma = lam/2 (J - 1/J) I + mu/J (F F^T - I) and
    c = lam J I(x)I + (2 mu - lam (J^2 - 1)) / J I_s (``in_plane``: as
    :func:`neo_hookean`)."""
    J = det3(F)
    if not (J > 0.0):
        _fill_nan(sigma, c, want_c)
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
            _isotropic_tangent(c, a, b, (0, 1))
        else:
            _isotropic_tangent(c, a, b, (0, 1, 2))


@jit
def _strain_increment(F, h_in, fn_offset, w):
    """F_inc = F F_n^-1 (F_n in the history at ``fn_offset``) in w[2];
    its symmetric part minus 1 is the strain increment."""
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
def _small_strain_tangent(sigma, D, F_inc, c):
    """c_abcd = sigma_ab d_cd + D_abce F_inc_de - d_ac sigma_db - d_bc sigma_ad
    (the exact derivative of the small-strain stress under the solver's
    convention, :mod:`pimpm.materials.small_strain`)."""
    for a in range(3):
        for b in range(3):
            for cc in range(3):
                for d in range(3):
                    s = sigma[a, b] * (1.0 if cc == d else 0.0)
                    for e in range(3):
                        s += D[a, b, cc, e] * F_inc[d, e]
                    if a == cc:
                        s -= sigma[d, b]
                    if b == cc:
                        s -= sigma[a, d]
                    c[a, b, cc, d] = s


@jit
def j2_small_strain(F, prm, h_in, h_out, plastic_model, sigma, c, want_c, w, D):
    """Accumulated small strain eps = eps_n + sym(F F_n^-1) - 1, Hooke's law
    (``plastic_model`` False) or radial return (Sulsky & Kaul 2.1.13-2.1.19,
    Simo & Hughes Box 3.2). History: strain, F, [plastic strain, alpha, work]."""
    mu, kappa, tau0, h1, alpha_l, h2 = prm[0], prm[1], prm[2], prm[3], prm[4], prm[5]
    F_inc = _strain_increment(F, h_in, 9, w)
    eps = w[3]
    for i in range(3):
        for j in range(3):
            eps[i, j] = h_in[3 * i + j] + 0.5 * (F_inc[i, j] + F_inc[j, i]) - (1.0 if i == j else 0.0)
            h_out[3 * i + j] = eps[i, j]
            h_out[9 + 3 * i + j] = F[i, j]
    eps_e = w[4]
    for i in range(3):
        for j in range(3):
            eps_e[i, j] = eps[i, j] - (h_in[18 + 3 * i + j] if plastic_model else 0.0)
    tr = trace3(eps_e)
    s_trial = w[5]
    norm2 = 0.0
    for i in range(3):
        for j in range(3):
            s_trial[i, j] = 2.0 * mu * (eps_e[i, j] - (tr / 3.0 if i == j else 0.0))
            norm2 += s_trial[i, j] * s_trial[i, j]
    norm = math.sqrt(norm2)
    d_alpha = 0.0
    theta = 1.0
    theta_bar = 0.0
    plastic = False
    if plastic_model:
        alpha = h_in[27]
        q_trial = SQ32 * norm
        f_trial = q_trial - yield_stress(alpha, tau0, h1, alpha_l, h2)
        plastic = f_trial > 1e-12 * max(tau0, 1e-300)
        if plastic:
            slope = h1 if alpha < alpha_l else -h2
            d_alpha = f_trial / (3.0 * mu + slope)
            if alpha < alpha_l and alpha + d_alpha > alpha_l:      # crosses into softening
                tau_l = tau0 + h1 * alpha_l
                d2 = (q_trial - tau_l - 3.0 * mu * (alpha_l - alpha)) / (3.0 * mu - h2)
                d_alpha = (alpha_l - alpha) + d2
                slope = -h2
            theta = 1.0 - 3.0 * mu * d_alpha / (q_trial if q_trial > 0 else 1.0)
            theta_bar = 1.0 / (1.0 + slope / (3.0 * mu)) - (1.0 - theta)
    safe = norm if norm > 0 else 1.0
    unit = w[6]
    work = 0.0
    for i in range(3):
        for j in range(3):
            unit[i, j] = s_trial[i, j] / safe
            s = s_trial[i, j] - 2.0 * mu * SQ32 * d_alpha * unit[i, j]
            sigma[i, j] = (kappa * tr if i == j else 0.0) + s
            if plastic_model:
                dp = SQ32 * d_alpha * unit[i, j]
                h_out[18 + 3 * i + j] = h_in[18 + 3 * i + j] + dp
                work += s * dp
    if plastic_model:
        h_out[27] = h_in[27] + d_alpha
        h_out[28] = h_in[28] + work
    if want_c:
        for i in range(3):
            for j in range(3):
                for k in range(3):
                    for m in range(3):
                        ii = _ii(i, j, k, m)
                        D[i, j, k, m] = (kappa * ii + 2.0 * mu * theta * (_is(i, j, k, m) - ii / 3.0)
                                         - 2.0 * mu * theta_bar * unit[i, j] * unit[k, m])
        _small_strain_tangent(sigma, D, F_inc, c)


@jit
def j2_finite_strain(F, prm, h_in, h_out, sigma, c, want_c, w):
    """Finite-strain J2 (module docstring). History: F, bbar_e, alpha, work."""
    mu, kappa, tau0, h1, alpha_l, h2 = prm[0], prm[1], prm[2], prm[3], prm[4], prm[5]
    J = det3(F)
    f = _strain_increment(F, h_in, 0, w)          # relative deformation F F_n^-1 in w[2]
    fbar = w[3]
    s3 = det3(f) ** (-1.0 / 3.0)
    for i in range(3):
        for j in range(3):
            fbar[i, j] = s3 * f[i, j]
    bn = w[4]
    for i in range(3):
        for j in range(3):
            bn[i, j] = h_in[9 + 3 * i + j]
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
    alpha_n = h_in[18]
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
    safe = norm if norm > 0 else 1.0
    unit = w[0]                                    # (F_n, F_n^-1 no longer needed)
    s = w[1]
    lnJ = math.log(J) if J > 0 else np.nan
    s_norm2 = 0.0
    for i in range(3):
        for j in range(3):
            unit[i, j] = s_trial[i, j] / safe
            s[i, j] = s_trial[i, j] - 2.0 * mu_bar * d_gamma * unit[i, j]
            s_norm2 += s[i, j] * s[i, j]
            h_out[3 * i + j] = F[i, j]
            h_out[9 + 3 * i + j] = s[i, j] / mu + (Ie if i == j else 0.0)
            sigma[i, j] = ((kappa * lnJ if i == j else 0.0) + s[i, j]) / J
    h_out[18] = alpha_n + SQ23 * d_gamma
    h_out[19] = h_in[19] + d_gamma * math.sqrt(s_norm2)
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
                    ii = _ii(i, j, k, m)
                    sym = _is(i, j, k, m)
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
def _neo_hookean_point(prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane):
    neo_hookean(F, prm[0], prm[1], sigma, c, want_c, w, in_plane)


@jit
def _neo_hookean_compressible_point(prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane):
    neo_hookean_compressible(F, prm[1] - 2.0 / 3.0 * prm[0], prm[0], sigma, c, want_c, w, in_plane)


@jit
def _linear_elastic_point(prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane):
    j2_small_strain(F, prm, h_in, h_out, False, sigma, c, want_c, w, D)


@jit
def _j2_small_strain_point(prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane):
    j2_small_strain(F, prm, h_in, h_out, True, sigma, c, want_c, w, D)


@jit
def _j2_finite_strain_point(prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane):
    j2_finite_strain(F, prm, h_in, h_out, sigma, c, want_c, w)


#: each model's material point, by code
POINTS = {NEO_HOOKEAN: _neo_hookean_point,
          NEO_HOOKEAN_COMPRESSIBLE: _neo_hookean_compressible_point,
          LINEAR_ELASTIC: _linear_elastic_point, J2_SMALL_STRAIN: _j2_small_strain_point,
          J2_FINITE_STRAIN: _j2_finite_strain_point}


@jit
def material_point(model, prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane):
    """Stress ``sigma`` (3, 3), tangent ``c`` (3, 3, 3, 3; written only if
    ``want_c``; with ``in_plane``, the neo-Hookean models write only the
    entries whose indices are all 0 or 1, which is all plane strain uses)
    and history ``h_out`` after the deformation gradient ``F`` for the
    model ``model`` with packed parameters ``prm`` and history ``h_in``
    committed at t. ``w``: (WORKSPACE, 3, 3) scratch; ``D``: (3, 3,
    3, 3) scratch. (Callers pass flags as values, not constants: numba would
    compile every model again for each constant.) Every model is compiled
    in; :func:`model_point` compiles one."""
    if model == NEO_HOOKEAN:
        _neo_hookean_point(prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane)
    elif model == NEO_HOOKEAN_COMPRESSIBLE:
        _neo_hookean_compressible_point(prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane)
    elif model == LINEAR_ELASTIC:
        _linear_elastic_point(prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane)
    elif model == J2_SMALL_STRAIN:
        _j2_small_strain_point(prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane)
    else:
        _j2_finite_strain_point(prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane)


def model_tag(code):
    """A value whose numba type says which model a kernel compiles: a tuple
    of ``code + 1`` zeros for one model shared by every particle, ``()`` for
    MIXED. (A tuple's length is part of its type, as with ``axes``; a
    literal int from Python would make numba re-type the kernel at every
    call.)"""
    return () if code == MIXED else (0,) * (code + 1)


def model_point(only, model, prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane):
    """:func:`material_point` for kernels that know their model when they
    are compiled: ``only`` is :func:`model_tag` of the model every particle
    shares (``model`` is then ignored, and only that model's code is
    compiled), or of MIXED (each particle's ``model`` is dispatched at run
    time, every model compiled in). Compiled code only: the implementation
    is chosen by :func:`_model_point` from the type of ``only``."""
    raise NotImplementedError("model_point runs only in compiled kernels")


@overload(model_point, jit_options=JIT_OPTIONS)
def _model_point(only, model, prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane):
    point = POINTS.get(len(only.types) - 1)
    if point is None:
        def dispatched(only, model, prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane):
            material_point(model, prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane)
        return dispatched

    def single(only, model, prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane):
        point(prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane)
    return single


@jit
def update_points(models, params, material_of, F, h_in, h_out, sigma, c, want_c, plane_stress, F_inc):
    """The stress update of every particle (G&W step 5): ``material_of[p]``
    indexes ``models`` and ``params``; in plane stress the thickness stretch
    F33 is solved first (:func:`solve_thickness`, writing F and F_inc).
    ``F_inc`` may have zero rows when not in plane stress."""
    w = np.empty((WORKSPACE, 3, 3))
    D = np.empty((3, 3, 3, 3))
    c_scratch = np.empty((3, 3, 3, 3))
    for p in range(F.shape[0]):
        m = material_of[p]
        cp = c[p] if want_c else c_scratch
        if plane_stress:
            solve_thickness((), models[m], params[m], F[p], F_inc[p], h_in[p], h_out[p], sigma[p],
                            cp, want_c, w, D)
        else:
            # every entry of c (False as a value, not a constant: see material_point)
            material_point(models[m], params[m], F[p], h_in[p], h_out[p], sigma[p], cp, want_c, w, D,
                           plane_stress)


@jit
def solve_thickness(only, model, prm, F, F_inc, h_in, h_out, sigma, c, want_c, w, D):
    """Plane stress: a local Newton for F33 so that sigma33 = 0 (d sigma33 /
    d ln F33 = c3333 + sigma33), F and F_inc updated in place; the in-plane
    tangent is condensed, c_abcd - c_ab33 c_33cd / c_3333 (as
    :class:`pimpm.kinematics.PlaneStress`). ``only``, ``model``: as
    :func:`model_point`."""
    # every iteration needs c_3333; a flag that is not a constant, so that numba
    # does not compile the material point once more for a literal True
    need_c = want_c or not want_c
    in_plane = not need_c        # every entry of c: the condensation needs c_ab33, c_33cd
    for _ in range(50):
        model_point(only, model, prm, F, h_in, h_out, sigma, c, need_c, w, D, in_plane)
        s33 = sigma[2, 2]
        big = 0.0
        for i in range(3):
            for j in range(3):
                big = max(big, abs(sigma[i, j]))
        if abs(s33) <= 1e-13 * (abs(c[2, 2, 2, 2]) + big):
            break
        step = math.exp(-s33 / (c[2, 2, 2, 2] + s33))
        F[2, 2] *= step
        F_inc[2, 2] *= step
    if want_c:
        c2222 = c[2, 2, 2, 2]
        for a in range(2):
            for b in range(2):
                for cc in range(2):
                    for d in range(2):
                        c[a, b, cc, d] -= c[a, b, 2, 2] * c[2, 2, cc, d] / c2222


@jit
def _neo_hookean_energy(prm, F, h):
    """G&W eq. 17, 20: W = mu/2 (J^(-2/3) tr C - 3) + kappa/2 (ln J)^2."""
    J = det3(F)
    if not (J > 0.0):
        return np.nan
    trC = 0.0
    for i in range(3):
        for j in range(3):
            trC += F[i, j] * F[i, j]
    lnJ = math.log(J)
    return 0.5 * prm[0] * (J ** (-2.0 / 3.0) * trC - 3.0) + 0.5 * prm[1] * lnJ * lnJ


@jit
def _neo_hookean_compressible_energy(prm, F, h):
    """MPM intro eq. 11: W = lam/4 (J^2 - 1) - (lam/2 + mu) ln J + mu/2 (tr C - 3)."""
    mu = prm[0]
    lam = prm[1] - 2.0 / 3.0 * mu
    J = det3(F)
    if not (J > 0.0):
        return np.nan
    trC = 0.0
    for i in range(3):
        for j in range(3):
            trC += F[i, j] * F[i, j]
    return 0.25 * lam * (J * J - 1.0) - (0.5 * lam + mu) * math.log(J) + 0.5 * mu * (trC - 3.0)


@jit
def _small_strain_energy(prm, h, plastic_model):
    """1/2 eps_e : C : eps_e with eps_e = strain - plastic strain (history)."""
    mu, kappa = prm[0], prm[1]
    tr = 0.0
    for i in range(3):
        tr += h[4 * i] - (h[18 + 4 * i] if plastic_model else 0.0)
    w = 0.0
    for i in range(3):
        for j in range(3):
            e = h[3 * i + j] - (h[18 + 3 * i + j] if plastic_model else 0.0)
            s = (kappa * tr if i == j else 0.0) + 2.0 * mu * (e - (tr / 3.0 if i == j else 0.0))
            w += s * e
    return 0.5 * w


@jit
def _linear_elastic_energy(prm, F, h):
    return _small_strain_energy(prm, h, False)


@jit
def _j2_small_strain_energy(prm, F, h):
    return _small_strain_energy(prm, h, True)


@jit
def _j2_finite_strain_energy(prm, F, h):
    """kappa/2 (ln J)^2 + mu/2 (tr bbar_e - 3), bbar_e (history) made
    unimodular first (the return map lets det bbar_e drift below 1)."""
    J = det3(F)
    b = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            b[i, j] = h[9 + 3 * i + j]
    s = det3(b) ** (-1.0 / 3.0)
    lnJ = math.log(J) if J > 0.0 else np.nan
    return 0.5 * prm[1] * lnJ * lnJ + 0.5 * prm[0] * (s * trace3(b) - 3.0)


@jit
def model_energy(model, prm, F, h):
    """Stored energy per unit reference volume of one particle of model
    ``model`` (packed parameters ``prm``, committed history ``h``)."""
    if model == NEO_HOOKEAN:
        return _neo_hookean_energy(prm, F, h)
    elif model == NEO_HOOKEAN_COMPRESSIBLE:
        return _neo_hookean_compressible_energy(prm, F, h)
    elif model == LINEAR_ELASTIC:
        return _linear_elastic_energy(prm, F, h)
    elif model == J2_SMALL_STRAIN:
        return _j2_small_strain_energy(prm, F, h)
    return _j2_finite_strain_energy(prm, F, h)
