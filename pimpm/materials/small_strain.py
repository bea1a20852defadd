"""Small-strain models embedded in the finite-deformation solver: linear
elasticity (``linear_elastic``) and J2 (von Mises) plasticity
(``j2_small_strain``) with the bilinear hardening / softening of Sulsky &
Kaul (2004) eq. 2.1.13-2.1.19, radial return (Simo & Hughes Box 3.2) and
its algorithmic tangent.

The strain is accumulated step by step, eps = eps_n + sym(F_inc) - 1 with
F_inc = F F_n^-1 the increment since the last converged step (the rate form
of Sulsky & Kaul, sigma_dot = C : (d - d_pl), integrated with the grid's
incremental deformation; for small strains it is sym(F) - 1), and the
stress is sigma = D : (eps - eps_p). So that Newton converges
quadratically, the spatial tangent handed to the assembly is the exact
derivative of this stress under the solver's convention (d tau = J c:H +
H tau + tau H^T for F -> (1 + H) F, so d eps = sym(H F_inc)):

    c_abcd = sigma_ab d_cd + D_abce (F_inc)_de - d_ac sigma_db - d_bc sigma_ad

with D the (algorithmic) small-strain tangent d sigma / d eps. It has no
minor symmetry in general, which the assembly does not assume. Not
objective: for small rotations.
"""
import math

from ..kernels.jit import jit
from ..kernels.small import trace3
from .common import SQ32, identity_dyad, linear_yield_stress, strain_increment, sym_identity, yield_stress
from .model import PLASTICITY, Model, history_offsets, parameter_offsets

ELASTIC_HISTORY = {"strain": (3, 3), "deformation_gradient": (3, 3)}
PLASTIC_HISTORY = dict(ELASTIC_HISTORY, plastic_strain=(3, 3), eq_plastic_strain=(), plastic_work=())
_H = history_offsets(PLASTIC_HISTORY)
STRAIN, DEFORMATION_GRADIENT, PLASTIC_STRAIN = _H["strain"], _H["deformation_gradient"], _H["plastic_strain"]
EQ_PLASTIC_STRAIN, PLASTIC_WORK = _H["eq_plastic_strain"], _H["plastic_work"]
#: both models pack [mu, kappa, the plasticity parameters, plastic?]: linear
#: elasticity as constants (no yield), von Mises plasticity from the input
_P = parameter_offsets(PLASTICITY, ("plastic",))
YIELD_STRESS, HARDENING, SOFTENING_STRAIN, SOFTENING = (_P["yield_stress"], _P["hardening_modulus"],
                                                         _P["softening_strain"], _P["softening_modulus"])
PLASTIC = _P["plastic"]
ELASTIC_CONSTANTS = {"yield_stress": math.inf, "hardening_modulus": 0.0, "softening_strain": math.inf,
                     "softening_modulus": 0.0, "plastic": 0.0}


@jit
def _small_strain_tangent(sigma, D, F_inc, c):
    """c_abcd = sigma_ab d_cd + D_abce F_inc_de - d_ac sigma_db - d_bc sigma_ad."""
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
def point(prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane):
    """Hooke's law (linear_elastic) or radial return (j2_small_strain) in
    the accumulated small strain (module docstring)."""
    mu, kappa = prm[0], prm[1]
    tau0, h1, alpha_l, h2 = prm[YIELD_STRESS], prm[HARDENING], prm[SOFTENING_STRAIN], prm[SOFTENING]
    plastic_model = prm[PLASTIC] > 0.0
    F_inc = strain_increment(F, h_in, DEFORMATION_GRADIENT, w)
    eps = w[3]
    for i in range(3):
        for j in range(3):
            eps[i, j] = (h_in[STRAIN + 3 * i + j] + 0.5 * (F_inc[i, j] + F_inc[j, i])
                         - (1.0 if i == j else 0.0))
            h_out[STRAIN + 3 * i + j] = eps[i, j]
            h_out[DEFORMATION_GRADIENT + 3 * i + j] = F[i, j]
    eps_e = w[4]
    for i in range(3):
        for j in range(3):
            eps_e[i, j] = eps[i, j] - (h_in[PLASTIC_STRAIN + 3 * i + j] if plastic_model else 0.0)
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
        alpha = h_in[EQ_PLASTIC_STRAIN]
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
            if d_alpha < 0.0 or linear_yield_stress(alpha + d_alpha, tau0, h1, alpha_l, h2) <= 0.0:
                # no strength left, or softening faster than the elastic stiffness (snap-back:
                # the return had no solution of growing plastic strain): the deviator returns to zero
                d_alpha = q_trial / (3.0 * mu)
                slope = 0.0
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
                h_out[PLASTIC_STRAIN + 3 * i + j] = h_in[PLASTIC_STRAIN + 3 * i + j] + dp
                work += s * dp
    if plastic_model:
        h_out[EQ_PLASTIC_STRAIN] = h_in[EQ_PLASTIC_STRAIN] + d_alpha
        h_out[PLASTIC_WORK] = h_in[PLASTIC_WORK] + work
    if want_c:
        for i in range(3):
            for j in range(3):
                for k in range(3):
                    for m in range(3):
                        ii = identity_dyad(i, j, k, m)
                        D[i, j, k, m] = (kappa * ii + 2.0 * mu * theta * (sym_identity(i, j, k, m) - ii / 3.0)
                                         - 2.0 * mu * theta_bar * unit[i, j] * unit[k, m])
        _small_strain_tangent(sigma, D, F_inc, c)


@jit
def energy(prm, F, h):
    """1/2 eps_e : C : eps_e with eps_e = strain - plastic strain (history)."""
    mu, kappa = prm[0], prm[1]
    plastic_model = prm[PLASTIC] > 0.0
    tr = 0.0
    for i in range(3):
        tr += h[STRAIN + 4 * i] - (h[PLASTIC_STRAIN + 4 * i] if plastic_model else 0.0)
    e2 = 0.0
    for i in range(3):
        for j in range(3):
            e = h[STRAIN + 3 * i + j] - (h[PLASTIC_STRAIN + 3 * i + j] if plastic_model else 0.0)
            s = (kappa * tr if i == j else 0.0) + 2.0 * mu * (e - (tr / 3.0 if i == j else 0.0))
            e2 += s * e
    return 0.5 * e2


# measured 5% asymmetric for j2_small_strain (tests/mpi/jacobian_check.py);
# linear_elastic shares its kinematics and is not measured: LU for both
LINEAR_ELASTIC = Model("linear_elastic", point, energy, history=ELASTIC_HISTORY, constants=ELASTIC_CONSTANTS,
                       symmetric_tangent=False, identity_history=("deformation_gradient",))
J2_SMALL_STRAIN = Model("j2_small_strain", point, energy, parameters=PLASTICITY, constants={"plastic": 1.0},
                        history=PLASTIC_HISTORY, symmetric_tangent=False,
                        identity_history=("deformation_gradient",),
                        output=("eq_plastic_strain", "plastic_work"))
