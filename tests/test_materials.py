"""Tests of the hyperelastic models, compiled (pimpm.materials, the code
that runs) and their numpy references (tests/reference/materials.py).

Every model is checked against its strain energy (Guilkey & Weiss 2003,
eq. 17-20; MPM introduction eq. 11; Hencky's W = lam/2 (tr eps)^2 + mu
eps:eps) by finite differences, so the stress formulas (G&W eq. 18, the
corrected intro eq. 12, tau = lam tr(eps) 1 + 2 mu eps) and the spatial
elasticity tensors (G&W eq. 21, the derived compressible and Hencky
tangents) are verified independently of how they were written.
"""
import warnings

import numpy as np
import pytest

from pimpm import materials as P
from reference import materials as M
from reference.compiled import Compiled

# Moduli of the G&W elastic billet (section 5.1): mu = 6e6, kappa = 6e7, rho = 10.
MU, KAPPA, RHO = 6.0e6, 6.0e7, 10.0
LAM = KAPPA - 2.0 / 3.0 * MU
I3 = np.eye(3)


HYPERELASTIC = ["neo_hookean", "neo_hookean_compressible", "hencky"]


def compiled(name):
    return Compiled(P.make_material({"model": name, "density": RHO, "shear_modulus": MU,
                                     "bulk_modulus": KAPPA}))


@pytest.fixture(params=[(kind, name) for name in HYPERELASTIC for kind in ("compiled", "reference")],
                ids=lambda p: f"{p[1]}-{p[0]}")
def mat(request):
    kind, name = request.param
    return compiled(name) if kind == "compiled" else M.REFERENCES[name](MU, KAPPA, RHO)


@pytest.fixture(params=HYPERELASTIC)
def reference_mat(request):
    return M.REFERENCES[request.param](MU, KAPPA, RHO)


def random_F(n=20, seed=0, scale=0.3):
    """F = I + scale * random with det F > 0.2 (well inside the admissible set)."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        F = I3 + scale * rng.standard_normal((3, 3))
        if np.linalg.det(F) > 0.2:
            out.append(F)
    return np.array(out)


def plane_strain_F(n=8, seed=1):
    """Plane-strain shaped F: random 2x2 block, F[2,2] = 1, zero off-plane entries."""
    F = np.zeros((n, 3, 3))
    F[:, :2, :2] = random_F(n, seed)[:, :2, :2]
    F[:, 2, 2] = 1.0
    assert np.all(np.linalg.det(F) > 0)
    return F


def all_F():
    return np.concatenate([random_F(), plane_strain_F()])


def random_rotation(seed=2):
    Q, R = np.linalg.qr(np.random.default_rng(seed).standard_normal((3, 3)))
    Q = Q * np.sign(np.diag(R))
    if np.linalg.det(Q) < 0:
        Q[:, 0] *= -1
    return Q


def isotropic_c(lam, mu):
    """Small-strain elasticity tensor lam I(x)I + mu (d_ik d_jl + d_il d_jk)."""
    return (lam * np.einsum("ij,kl->ijkl", I3, I3)
            + mu * (np.einsum("ik,jl->ijkl", I3, I3) + np.einsum("il,jk->ijkl", I3, I3)))


def rel_err(a, b, scale=None):
    scale = np.max(np.abs(b)) if scale is None else scale
    return np.max(np.abs(a - b)) / scale


# 1. ---------------------------------------------------------------------------
def test_zero_stress_and_energy_at_identity(mat):
    F = np.tile(I3, (4, 1, 1))
    sigma, c = mat.stress_and_tangent(F)
    assert np.max(np.abs(sigma)) <= 1e-12 * MU
    assert np.max(np.abs(mat.strain_energy(F))) <= 1e-12 * MU
    assert np.all(np.isfinite(c))


# 2. ---------------------------------------------------------------------------
def test_stress_is_derivative_of_energy(mat):
    """First Piola P = J sigma F^-T equals dW/dF (central differences)."""
    F = all_F()
    sigma = mat.stress(F)
    J = np.linalg.det(F)
    P = J[:, None, None] * sigma @ np.linalg.inv(F).transpose(0, 2, 1)
    h = 1e-6
    P_fd = np.zeros_like(F)
    for i in range(3):
        for j in range(3):
            dF = np.zeros((3, 3))
            dF[i, j] = h
            P_fd[:, i, j] = (mat.strain_energy(F + dF) - mat.strain_energy(F - dF)) / (2 * h)
    assert rel_err(P, P_fd) < 1e-6
    # sigma is symmetric (balance of angular momentum)
    assert rel_err(sigma, sigma.transpose(0, 2, 1), scale=np.max(np.abs(sigma))) < 1e-14


# 3. ---------------------------------------------------------------------------
def test_tangent_matches_truesdell_rate_of_kirchhoff_stress(mat):
    """d tau / d eps of tau((I + eps H) F) = J c:H + H tau + tau H^T (G&W eq. 21)."""
    F = all_F()
    J = np.linalg.det(F)
    sigma, c = mat.stress_and_tangent(F)
    tau = J[:, None, None] * sigma
    Jc = J[:, None, None, None, None] * c
    rng = np.random.default_rng(3)
    eps = 1e-6
    for _ in range(4):
        H = rng.standard_normal((3, 3))  # not symmetric
        tau_p = np.linalg.det((I3 + eps * H) @ F)[:, None, None] * mat.stress((I3 + eps * H) @ F)
        tau_m = np.linalg.det((I3 - eps * H) @ F)[:, None, None] * mat.stress((I3 - eps * H) @ F)
        dtau_fd = (tau_p - tau_m) / (2 * eps)
        dtau = np.einsum("nijkl,kl->nij", Jc, H) + H @ tau + tau @ H.T
        assert rel_err(dtau, dtau_fd, scale=np.max(np.abs(Jc))) < 1e-6


# 4. ---------------------------------------------------------------------------
def test_tangent_symmetries(mat):
    _, c = mat.stress_and_tangent(all_F())
    s = np.max(np.abs(c))
    assert rel_err(c.transpose(0, 3, 4, 1, 2), c, s) < 1e-14  # major: ijkl = klij
    assert rel_err(c.transpose(0, 2, 1, 3, 4), c, s) < 1e-14  # minor: ijkl = jikl
    assert rel_err(c.transpose(0, 1, 2, 4, 3), c, s) < 1e-14  # minor: ijkl = ijlk


# 5. ---------------------------------------------------------------------------
def test_objectivity(mat):
    """sigma(QF) = Q sigma Q^T and c(QF) = Q Q Q Q c for a rotation Q."""
    F = all_F()
    Q = random_rotation()
    sigma, c = mat.stress_and_tangent(F)
    sigma_q, c_q = mat.stress_and_tangent(Q @ F)
    assert rel_err(sigma_q, Q @ sigma @ Q.T) < 1e-12
    c_rot = np.einsum("ia,jb,kc,ld,nabcd->nijkl", Q, Q, Q, Q, c)
    assert rel_err(c_q, c_rot) < 1e-12
    # energy is invariant
    assert rel_err(mat.strain_energy(Q @ F), mat.strain_energy(F)) < 1e-12


# 6. ---------------------------------------------------------------------------
def test_small_strain_limit(mat):
    """Linear elasticity: sigma ~ lam tr(e) I + 2 mu e, and c(I) is isotropic."""
    rng = np.random.default_rng(4)
    E = rng.standard_normal((5, 3, 3))
    e = 1e-7 * 0.5 * (E + E.transpose(0, 2, 1))
    sigma = mat.stress(I3 + e)
    sigma_lin = LAM * np.trace(e, axis1=1, axis2=2)[:, None, None] * I3 + 2 * MU * e
    assert rel_err(sigma, sigma_lin) < 1e-5

    _, c = mat.stress_and_tangent(I3[None])
    assert rel_err(c[0], isotropic_c(LAM, MU)) < 1e-12


# 7. ---------------------------------------------------------------------------
@pytest.mark.parametrize("E, nu", [(1.0e7, 0.25), (2.0e11, 0.3)])
def test_make_material_from_youngs_and_poisson(E, nu):
    m = P.make_material({"model": "neo_hookean", "density": 7800.0,
                         "youngs_modulus": E, "poisson_ratio": nu, "other_key": "ignored"})
    mu, kappa = E / (2 * (1 + nu)), E / (3 * (1 - 2 * nu))
    assert m.model is P.MODELS["neo_hookean"]
    assert m.shear_modulus == pytest.approx(mu, rel=1e-14)
    assert m.bulk_modulus == pytest.approx(kappa, rel=1e-14)
    assert m.density == 7800.0
    # small-strain tangent reproduces E, nu through the Voigt constants C11, C12
    _, c = Compiled(m).stress_and_tangent(I3[None])
    C11, C12 = c[0, 0, 0, 0, 0], c[0, 0, 0, 1, 1]
    assert C11 == pytest.approx(E * (1 - nu) / ((1 + nu) * (1 - 2 * nu)), rel=1e-12)
    assert C12 == pytest.approx(E * nu / ((1 + nu) * (1 - 2 * nu)), rel=1e-12)


def test_make_material_from_shear_and_bulk_and_registry():
    spec = {"model": "neo_hookean_compressible", "density": RHO,
            "shear_modulus": MU, "bulk_modulus": KAPPA}
    m = P.make_material(spec)
    assert m.model is P.MODELS["neo_hookean_compressible"] and m.name == "neo_hookean_compressible"
    assert (m.shear_modulus, m.bulk_modulus, m.density) == (MU, KAPPA, RHO)
    assert m.lame_lambda == pytest.approx(LAM)
    assert P.elastic_moduli(spec) == (MU, KAPPA)
    assert m.wave_speed() == pytest.approx(np.sqrt((KAPPA + 4 / 3 * MU) / RHO), rel=1e-14)
    # the registry's order is the kernels' codes, and every model has a numpy reference
    assert [model.code for model in P.MODELS.values()] == list(range(len(P.MODELS)))
    for name, model in P.MODELS.items():
        assert model.name == name and name in M.REFERENCES
    with pytest.raises(ValueError):
        P.make_material({"model": "no_such_model", "density": 1.0, "shear_modulus": 1.0,
                         "bulk_modulus": 1.0})
    with pytest.raises(ValueError):
        P.make_material({"model": "neo_hookean", "density": 1.0, "shear_modulus": 1.0})


def test_parameters_are_packed_in_declaration_order_with_absent_values():
    m = P.make_material({"model": "j2_finite_strain", "density": 1.0, "shear_modulus": 2.0,
                         "bulk_modulus": 3.0, "yield_stress": 0.5, "softening_strain": None})
    assert list(m.packed_parameters()) == [2.0, 3.0, 0.5, 0.0, np.inf, 0.0]
    assert m.yield_stress == 0.5 and m.softening_strain == np.inf
    assert list(P.make_material({"model": "hencky", "density": 1.0, "shear_modulus": 2.0,
                                 "bulk_modulus": 3.0}).packed_parameters()) == [2.0, 3.0]
    with pytest.raises(ValueError, match="needs yield_stress"):
        P.make_material({"model": "j2_small_strain", "density": 1.0, "shear_modulus": 2.0,
                         "bulk_modulus": 3.0})


def test_von_mises():
    s = np.zeros((3, 3, 3))
    s[0, 0, 0] = -5.0                      # uniaxial compression
    s[1, 1, 2] = s[1, 2, 1] = 2.0          # pure shear tau = 2
    s[2] = 7.0 * I3                        # hydrostatic
    assert np.allclose(M.von_mises(s), [5.0, np.sqrt(3) * 2.0, 0.0], rtol=1e-14, atol=1e-12)
    # invariant under added pressure
    assert M.von_mises(s[:1] + 3.0 * I3)[0] == pytest.approx(5.0, rel=1e-14)


def test_inverted_F_gives_nan_without_exception(mat):
    F = random_F(5)
    F[1] = np.diag([-1.0, 1.0, 1.0])      # reflection, det = -1
    F[3] = np.diag([0.0, 1.0, 1.0])       # singular, det = 0
    bad = np.array([False, True, False, True, False])
    with warnings.catch_warnings():
        warnings.simplefilter("error")    # no RuntimeWarning from log/sqrt/power either
        sigma, c = mat.stress_and_tangent(F)
        W = mat.strain_energy(F)
    assert np.all(np.isnan(sigma[bad])) and np.all(np.isnan(c[bad])) and np.all(np.isnan(W[bad]))
    assert np.all(np.isfinite(sigma[~bad])) and np.all(np.isfinite(c[~bad]))
    # good particles are unaffected by bad neighbours
    sigma_good, c_good = mat.stress_and_tangent(F[~bad])
    assert np.array_equal(sigma[~bad], sigma_good) and np.array_equal(c[~bad], c_good)


# Extra interface checks -------------------------------------------------------
def test_vectorised_matches_single_particle_and_shapes(reference_mat):
    mat = reference_mat
    F = all_F()
    sigma, c = mat.stress_and_tangent(F)
    assert sigma.shape == (len(F), 3, 3) and c.shape == (len(F), 3, 3, 3, 3)
    assert mat.strain_energy(F).shape == (len(F),)
    for p in (0, 7, len(F) - 1):
        s1, c1 = mat.stress_and_tangent(F[p:p + 1])
        assert np.allclose(s1[0], sigma[p], rtol=1e-14, atol=0)
        assert np.allclose(c1[0], c[p], rtol=1e-14, atol=0)
    assert np.array_equal(mat.stress(F), sigma)
    # arbitrary leading batch dimensions
    assert mat.stress(F[:6].reshape(2, 3, 3, 3)).shape == (2, 3, 3, 3)
    with pytest.raises(ValueError):
        mat.stress(np.ones((4, 2, 2)))


def test_plane_strain_has_no_out_of_plane_shear(mat):
    F = plane_strain_F()
    sigma = mat.stress(F)
    assert np.max(np.abs(sigma[:, :2, 2])) <= 1e-12 * MU
    assert np.max(np.abs(sigma[:, 2, :2])) <= 1e-12 * MU
    assert np.max(np.abs(sigma[:, 2, 2])) > 1e-3 * MU  # but sigma_zz is not zero in general


def test_pure_kernels_tangent_flag():
    F = random_F(3)
    for kernel, a, b in [(M.uncoupled_neo_hookean, MU, KAPPA), (M.compressible_neo_hookean, LAM, MU)]:
        sigma, c = kernel(F, a, b, tangent=False)
        assert c is None and sigma.shape == (3, 3, 3)
        sigma2, c2 = kernel(F, a, b)
        assert np.array_equal(sigma, sigma2) and c2.shape == (3, 3, 3, 3, 3)


def test_compressible_stress_closed_form():
    """Compressible stress is sigma = lam/2 (J - 1/J) I + mu/J (F F^T - I)
    (derived from eq. 11; the printed eq. 12 drops the 1/J)."""
    F = random_F(6, seed=5)
    J = np.linalg.det(F)[:, None, None]
    expected = 0.5 * LAM * (J - 1 / J) * I3 + MU / J * (F @ F.transpose(0, 2, 1) - I3)
    sigma, _ = M.compressible_neo_hookean(F, LAM, MU, tangent=False)
    assert rel_err(sigma, expected) < 1e-13
