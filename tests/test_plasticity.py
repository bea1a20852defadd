"""Small-strain J2 plasticity (Sulsky & Kaul 2004 eq. 2.1.13-2.1.19): the
return mapping, its algorithmic tangent, plastic work, the uniaxial
stress-strain curve, and the linear elastic small-strain model; and
finite-strain J2: all through the compiled material points."""
import numpy as np
import pytest

from pimpm import materials
from reference.compiled import Compiled
from reference.materials import yield_stress


def make_material(spec):
    """The material through its compiled kernels (the code that runs; the
    numpy references are compared with them in tests/test_kernels.py)."""
    return Compiled(materials.make_material(spec))

E, NU = 1000.0, 0.3
SPEC = {"model": "j2_small_strain", "youngs_modulus": E, "poisson_ratio": NU, "density": 10.0,
        "yield_stress": 6.0, "hardening_modulus": 50.0}


def history(n, eps_p=None, alpha=None):
    return {"plastic_strain": np.zeros((n, 3, 3)) if eps_p is None else eps_p,
            "eq_plastic_strain": np.zeros(n) if alpha is None else alpha,
            "plastic_work": np.zeros(n)}


def random_states(n, scale, seed):
    rng = np.random.default_rng(seed)
    F = np.eye(3) + scale * rng.standard_normal((n, 3, 3))
    F[: n // 2, 2, :2] = F[: n // 2, :2, 2] = 0.0        # half of them plane-strain shaped
    F[: n // 2, 2, 2] = 1.0
    sym = rng.standard_normal((n, 3, 3)) * 0.002
    eps_p = 0.5 * (sym + np.swapaxes(sym, 1, 2))
    eps_p -= np.trace(eps_p, axis1=1, axis2=2)[:, None, None] / 3 * np.eye(3)
    return F, history(n, eps_p, np.abs(rng.standard_normal(n)) * 0.003)


@pytest.mark.parametrize("spec", [SPEC, dict(SPEC, softening_strain=0.004, softening_modulus=30.0)])
def test_return_mapping_lands_on_the_yield_surface(spec):
    m = make_material(spec)
    F, h = random_states(40, 0.02, 1)
    sigma, _, new = m.update(F, h, tangent=False)
    s = sigma - np.trace(sigma, axis1=1, axis2=2)[:, None, None] / 3 * np.eye(3)
    q = np.sqrt(1.5 * np.sum(s * s, axis=(1, 2)))
    limit = yield_stress(new["eq_plastic_strain"], m.yield_stress, m.hardening_modulus,
                         m.softening_strain, m.softening_modulus)
    plastic = new["eq_plastic_strain"] > h["eq_plastic_strain"]
    assert plastic.sum() > 10 and (~plastic).sum() >= 0
    np.testing.assert_allclose(q[plastic], limit[plastic], rtol=1e-10)
    assert np.all(q[~plastic] <= limit[~plastic] * (1 + 1e-10))
    assert np.all(new["plastic_work"] >= 0.0) and np.all(new["plastic_work"][plastic] > 0.0)
    # plastic flow is deviatoric
    assert np.allclose(np.trace(new["plastic_strain"], axis1=1, axis2=2),
                       np.trace(h["plastic_strain"], axis1=1, axis2=2), atol=1e-15)


@pytest.mark.parametrize("scale", [1e-4, 0.02])     # elastic and plastic states
@pytest.mark.parametrize("model", ["j2_small_strain", "linear_elastic"])
def test_algorithmic_tangent_matches_finite_differences(scale, model):
    """d tau / d eps for F -> (1 + eps H) F equals J c:H + H tau + tau H^T
    (the solver's convention) with the history at t held fixed."""
    spec = SPEC if model == "j2_small_strain" else {k: v for k, v in SPEC.items()
                                                    if k in ("youngs_modulus", "poisson_ratio", "density")}
    m = make_material(dict(spec, model=model))
    F, h = random_states(30, scale, 2)
    if model == "linear_elastic":
        h = {}
    sigma, c, _ = m.update(F, h)
    _check_tangent(m, F, h, sigma, c)
    # the incremental form: strain accumulated since a previous F_n
    rng = np.random.default_rng(9)
    F_n = np.eye(3) + 0.01 * rng.standard_normal((len(F), 3, 3))
    sym = 0.002 * rng.standard_normal((len(F), 3, 3))
    h = dict(h, strain=0.5 * (sym + np.swapaxes(sym, 1, 2)), deformation_gradient=F_n)
    F = np.matmul(np.eye(3) + scale * rng.standard_normal((len(F), 3, 3)), F_n)
    sigma, c, _ = m.update(F, h)
    _check_tangent(m, F, h, sigma, c)


def _check_tangent(m, F, h, sigma, c):
    rng = np.random.default_rng(5)
    J = np.linalg.det(F)
    tau = J[:, None, None] * sigma
    for _ in range(3):
        H = rng.standard_normal((3, 3))
        eps = 1e-7
        taus = []
        for sgn in (1, -1):
            Fe = np.matmul(np.eye(3) + sgn * eps * H, F)
            s, _, _ = m.update(Fe, h, tangent=False)
            taus.append(np.linalg.det(Fe)[:, None, None] * s)
        fd = (taus[0] - taus[1]) / (2 * eps)
        exact = J[:, None, None] * np.einsum("pabcd,cd->pab", c, H) + H @ tau + tau @ H.T
        assert np.max(np.abs(fd - exact)) < 1e-6 * np.max(np.abs(J[:, None, None, None, None] * c))


def test_uniaxial_stress_follows_the_bilinear_curve():
    """Strain-controlled uniaxial stress (sigma_yy = sigma_zz = 0 by local
    Newton on the lateral stretches): sigma = E eps below yield, then
    tau0 + E_t (eps - tau0 / E) with E_t = E H / (E + H)."""
    m = make_material(SPEC)
    h = history(1)
    lateral = np.zeros(2)
    H = m.hardening_modulus
    for eps_x in np.linspace(0.0005, 0.03, 60):
        for _ in range(30):
            F = np.diag([1.0 + eps_x, 1.0 + lateral[0], 1.0 + lateral[1]])[None]
            sigma, c, new = m.update(F, h)
            r = np.array([sigma[0, 1, 1], sigma[0, 2, 2]])
            if np.max(np.abs(r)) < 1e-11 * E:
                break
            # small strain: d sigma_ii / d eps_jj from the spatial tangent (F ~ 1)
            K = np.array([[c[0, 1, 1, 1, 1], c[0, 1, 1, 2, 2]], [c[0, 2, 2, 1, 1], c[0, 2, 2, 2, 2]]])
            lateral -= np.linalg.solve(K, r)
        h = new
        tau0 = m.yield_stress
        strain = new["strain"][0, 0, 0]      # accumulated (incremental) axial strain
        assert abs(strain - eps_x) < 0.02 * eps_x
        expected = E * strain if E * strain <= tau0 else tau0 + E * H / (E + H) * (strain - tau0 / E)
        assert abs(sigma[0, 0, 0] - expected) < 1e-6 * max(expected, 1.0), eps_x


def test_linear_elastic_small_strain_is_hookes_law():
    m = make_material({"model": "linear_elastic", "youngs_modulus": E, "poisson_ratio": NU,
                       "density": 1.0})
    eps = 1e-3 * np.array([[1.0, 0.3, 0.0], [0.3, -0.5, 0.2], [0.0, 0.2, 0.4]])
    sigma = m.stress((np.eye(3) + eps)[None])[0]
    lam, mu = E * NU / ((1 + NU) * (1 - 2 * NU)), E / (2 * (1 + NU))
    np.testing.assert_allclose(sigma, lam * np.trace(eps) * np.eye(3) + 2 * mu * eps, rtol=1e-12)


FINITE = {"model": "j2_finite_strain", "shear_modulus": 80.0, "bulk_modulus": 170.0, "density": 1.0,
          "yield_stress": 0.5, "hardening_modulus": 3.0}


def finite_history(n, seed):
    rng = np.random.default_rng(seed)
    F_n = np.eye(3) + 0.05 * rng.standard_normal((n, 3, 3))
    b = np.eye(3) + 0.003 * rng.standard_normal((n, 3, 3))
    b = 0.5 * (b + np.swapaxes(b, 1, 2))
    b = b / np.linalg.det(b)[:, None, None] ** (1 / 3)
    return F_n, {"deformation_gradient": F_n, "elastic_left_cauchy_green": b,
                 "eq_plastic_strain": 0.01 * np.abs(rng.standard_normal(n)), "plastic_work": np.zeros(n)}


@pytest.mark.parametrize("yield_stress", [1e6, 0.5])     # elastic, plastic
@pytest.mark.parametrize("scale", [1e-5, 0.03])
def test_finite_strain_j2_tangent_matches_finite_differences(yield_stress, scale):
    m = make_material(dict(FINITE, yield_stress=yield_stress))
    F_n, h = finite_history(20, 0)
    rng = np.random.default_rng(1)
    F = np.matmul(np.eye(3) + scale * rng.standard_normal((20, 3, 3)), F_n)
    sigma, c, new = m.update(F, h)
    plastic = new["eq_plastic_strain"] > h["eq_plastic_strain"]
    assert plastic.sum() == (0 if yield_stress > 1e3 else 20) or scale < 1e-3
    _check_tangent(m, F, h, sigma, c)


def test_finite_strain_j2_return_mapping():
    """After the return the Kirchhoff deviator is on the yield surface,
    ||s|| = sqrt(2/3) sigma_y(alpha); plastic work is non-negative;
    objectivity of the update. (As in Simo & Hughes Box 9.1, bbar_e =
    s / mu + I_e 1 is not renormalized to det = 1.)"""
    m = make_material(FINITE)
    F_n, h = finite_history(30, 3)
    rng = np.random.default_rng(4)
    F = np.matmul(np.eye(3) + 0.03 * rng.standard_normal((30, 3, 3)), F_n)
    sigma, _, new = m.update(F, h, tangent=False)
    J = np.linalg.det(F)
    tau = J[:, None, None] * sigma
    s = tau - np.trace(tau, axis1=1, axis2=2)[:, None, None] / 3 * np.eye(3)
    plastic = new["eq_plastic_strain"] > h["eq_plastic_strain"]
    assert plastic.sum() > 20
    limit = np.sqrt(2 / 3) * (m.yield_stress + m.hardening_modulus * new["eq_plastic_strain"])
    np.testing.assert_allclose(np.sqrt(np.sum(s * s, axis=(1, 2)))[plastic], limit[plastic], rtol=1e-10)
    assert np.all(new["plastic_work"] >= 0) and np.all(new["plastic_work"][plastic] > 0)
    # rotating the current configuration rotates the stress
    theta = 0.7
    Q = np.array([[np.cos(theta), -np.sin(theta), 0], [np.sin(theta), np.cos(theta), 0], [0, 0, 1.0]])
    sigma_q, _, _ = m.update(np.matmul(Q, F), h, tangent=False)
    np.testing.assert_allclose(sigma_q, Q @ sigma @ Q.T, atol=1e-12 * np.abs(sigma).max())


@pytest.mark.parametrize("kinematics,model,integrator", [
    ("plane_strain", "j2_finite_strain", "quasi_static"),
    ("plane_strain", "j2_small_strain", "quasi_static"),
    ("axisymmetric", "j2_finite_strain", "quasi_static"),
    ("axisymmetric", "j2_finite_strain", "newmark"),
    ("axisymmetric", "j2_finite_strain", "explicit")])
def test_energy_balance_of_plastic_compression(kinematics, model, integrator):
    """The first 0.1 mm of inputs/upsetting.yaml at 2 mm cells (yielding
    under the platen): the platen's work equals the stored elastic energy
    plus kinetic energy plus the plastic work, to 1% (measured 0.02-0.5%).
    Catches a stored energy that counts plastic work (the finite-strain
    model's bbar_e loses unimodularity in the return map)."""
    from mpi4py import MPI
    from helpers import coarse_upsetting
    from pimpm.config import validate
    from pimpm.simulation import Simulation
    raw = coarse_upsetting()
    raw["kinematics"] = kinematics
    raw["materials"]["steel"]["model"] = model
    end = 1.0e-4
    raw["time"] = {"integrator": integrator, "end_time": end}
    if integrator != "explicit":
        raw["time"]["dt"] = end / 8
    sim = Simulation(validate(raw), MPI.COMM_WORLD)
    while sim.time < end - 1e-15:
        info = sim.advance(sim.stable_time_step() if integrator == "explicit" else end / 8)
    p = sim.particles
    plastic = float(np.sum(p["volume0"] * p["h_plastic_work"]))
    stored = info["kinetic_energy"] + info["strain_energy"]
    work = info["external_work"]
    assert plastic > 0.3 * work                 # well into plastic flow
    assert abs(work - stored - plastic) < 0.01 * work
    if sim.solver is not None:
        sim.solver.destroy()


@pytest.mark.parametrize("model", ["j2_small_strain", "j2_finite_strain"])
def test_softening_ends_at_zero_strength_not_a_negative_yield_stress(model):
    """Issue 32: softening that would drive the yield stress below zero
    (6.05 - 1000 (alpha - 0.001) reaches 0 at alpha = 0.00705) leaves a material
    without strength: the deviatoric stress returns to zero, the plastic
    strain only grows (it ran backwards before), the plastic work stays
    positive; below the zero the return lands on the yield surface as before.
    A softening steeper than 3 mu (a snap-back, no return of growing plastic
    strain exists) ends at zero strength too."""
    spec = dict(SPEC, model=model, softening_strain=0.001, softening_modulus=1000.0)
    m = make_material(spec)
    F, h = random_states(120, 0.0035, 3)
    sigma, _, new = m.update(F, h, tangent=False)
    s = sigma - np.trace(sigma, axis1=1, axis2=2)[:, None, None] / 3 * np.eye(3)
    q = np.sqrt(1.5 * np.sum(s * s, axis=(1, 2)))
    if model == "j2_finite_strain":          # Kirchhoff stress: sigma J
        q = q * np.linalg.det(F)
    alpha = new["eq_plastic_strain"]
    assert np.all(alpha >= h["eq_plastic_strain"])
    spent = alpha >= 0.00705
    assert spent.sum() > 10 and (~spent).sum() > 0
    assert np.all(q[spent] < 1e-9 * 6.0)
    limit = yield_stress(alpha, 6.0, 50.0, 0.001, 1000.0)
    plastic = (alpha > h["eq_plastic_strain"]) & ~spent
    assert plastic.sum() > 0
    np.testing.assert_allclose(q[plastic], limit[plastic], rtol=1e-8)
    assert np.all(new["plastic_work"] >= 0.0)
    snap = make_material(dict(spec, hardening_modulus=-2000.0, softening_strain=None, softening_modulus=0.0))
    _, _, new = snap.update(F, h, tangent=False)
    assert np.all(new["eq_plastic_strain"] >= h["eq_plastic_strain"])
