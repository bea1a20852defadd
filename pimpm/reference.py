"""Analytic and semi-analytic reference solutions of the shipped validation
problems (docs/VALIDATION.md), defined once for the scripts and tests that
compare with them.

* :func:`timoshenko_cantilever`: tip deflection of an end-loaded cantilever,
  bending plus shear (Timoshenko beam theory).
* :func:`elastica_tip`: the inextensible elastica of an end-loaded
  cantilever under a dead load (Bisshopp & Drucker 1945, Mattiasson 1981),
  integrated here by shooting.
* :func:`reissner_tip`: the same with the beam's axial and shear
  flexibility (Reissner's geometrically exact beam).
* :func:`heywood_kt`: stress concentration factor of a circular hole in a
  strip under tension (Heywood's fit to Howland's solution).
* :func:`homogeneous_upsetting`: the frictionless upsetting of a cylinder of
  linearly hardening J2 material (Sulsky & Kaul 3.2.7 with the platen made
  frictionless): homogeneous compression.
"""
import numpy as np


def timoshenko_cantilever(load, length, depth, youngs_modulus, poisson_ratio, x=None,
                          shear_coefficient=5.0 / 6.0):
    """Deflection at ``x`` (default the tip) of a cantilever of rectangular
    section (unit thickness) clamped at x = 0 under a transverse end load
    ``load`` (force per unit thickness): v(x) = P x^2 (3 L - x) / (6 E I) +
    P x / (kappa G A), with I = d^3/12, A = d, G = E / (2 (1 + nu)); kappa
    is 5/6 by default (Cowper's 10 (1 + nu) / (12 + 11 nu) differs from it by
    0.3% at nu = 0.3, which changes v by 0.003%)."""
    x = length if x is None else x
    inertia = depth ** 3 / 12.0
    shear = youngs_modulus / (2.0 * (1.0 + poisson_ratio))
    bending = load * x ** 2 * (3.0 * length - x) / (6.0 * youngs_modulus * inertia)
    return bending + load * x / (shear_coefficient * shear * depth)


def elastica_tip(k, points=400):
    """Tip displacements of the inextensible, unshearable elastica of a
    cantilever under a dead end load of fixed direction, for the load
    parameter k = P L^2 / (E I): returns (vertical, horizontal) displacement
    over L.

    The angle theta(s) of the centre line (s in [0, 1]) solves theta'' =
    -k cos theta with theta(0) = 0 (clamped) and theta'(1) = 0 (no moment at
    the tip); its first integral is theta'^2 = 2 k (sin a - sin theta), a
    the tip angle. With sin a - sin theta = t^2, ds = 2 dt / (sqrt(2 k) cos
    theta), so the length 1 = int_0^sqrt(sin a) 2 dt / (sqrt(2 k) cos theta)
    fixes a (bisection on (0, pi/2)), the tip's x is sqrt(2 sin a / k) and
    its deflection int sin theta ds; Gauss-Legendre with ``points`` points
    (smooth integrands, error below 1e-12 up to k = 100). Mattiasson (1981)
    tabulates, e.g., k = 1: 0.30172, 0.05643; k = 10: 0.81061, 0.55500."""
    nodes, weights = np.polynomial.legendre.leggauss(points)

    def integrals(a):
        top = np.sqrt(np.sin(a))
        t = 0.5 * top * (nodes + 1.0)
        theta = np.arcsin(np.sin(a) - t * t)
        ds = 0.5 * top * weights * 2.0 / (np.sqrt(2.0 * k) * np.cos(theta))
        return ds.sum(), (np.sin(theta) * ds).sum()

    lo, hi = 0.0, 0.5 * np.pi
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if integrals(mid)[0] < 1.0:
            lo = mid
        else:
            hi = mid
    a = 0.5 * (lo + hi)
    return float(integrals(a)[1]), float(1.0 - np.sqrt(2.0 * np.sin(a) / k))


def reissner_tip(k, axial=0.0, shear=0.0, at=1.0, samples=400):
    """Displacements (vertical, horizontal, over L) of the point of the centre
    line at reference arclength ``at`` L (default the tip) of an extensible and
    shear-deformable cantilever under a dead end load (Reissner's geometrically
    exact beam, linear in its strains): with s the reference arclength over L,
    theta' = m, m' = -k x', x' = (1 + e) cos theta - g sin theta, y' = (1 + e)
    sin theta + g cos theta, where the axial strain e = ``axial`` sin theta and
    the shear strain g = ``shear`` cos theta come from the load's components
    along and across the section (``axial`` = P / (E A), ``shear`` = P /
    (kappa G A)); theta(0) = 0, m(1) = 0. ``axial = shear = 0`` is the
    inextensible elastica of :func:`elastica_tip`; at small k the deflection
    is Timoshenko's (bending + shear). Shooting on m(0) from the elastica's
    value with the secant method, RK4 with ``samples`` steps (1e-11 against 2000 steps at k = 10); then the initial
    value problem to ``at``."""

    def rate(y):
        theta, m = y[0], y[1]
        e, g = axial * np.sin(theta), shear * np.cos(theta)
        dx = (1.0 + e) * np.cos(theta) - g * np.sin(theta)
        dy = (1.0 + e) * np.sin(theta) + g * np.cos(theta)
        return np.array([m, -k * dx, dx, dy])

    def shoot(m0, length=1.0):
        y = np.array([0.0, m0, 0.0, 0.0])
        h = length / samples
        for _ in range(samples):
            a = rate(y)
            b = rate(y + 0.5 * h * a)
            c = rate(y + 0.5 * h * b)
            d = rate(y + h * c)
            y = y + h / 6.0 * (a + 2.0 * b + 2.0 * c + d)
        return y

    _, horizontal = elastica_tip(k)
    m0, m1 = k * (1.0 - horizontal), k * (1.0 - horizontal) * (1.0 + 1e-3)
    f0, f1 = shoot(m0)[1], shoot(m1)[1]
    for _ in range(50):
        if f1 == f0 or abs(f1) < 1e-13 * max(k, 1.0):
            break
        m0, m1 = m1, m1 - f1 * (m1 - m0) / (f1 - f0)
        f0, f1 = f1, shoot(m1)[1]
    y = shoot(m1, at)
    return float(y[3]), float(at - y[2])


def heywood_kt(diameter, width):
    """Stress concentration factor of a central circular hole of
    ``diameter`` in a strip of ``width`` under uniaxial tension, on the
    gross (remote) stress: Kt_net = 2 + (1 - d/w)^3 (Heywood 1952; within
    about 1% of Howland's series for d/w <= 0.5), Kt_gross = Kt_net / (1 -
    d/w). Infinite plate: 3."""
    ratio = diameter / width
    return (2.0 + (1.0 - ratio) ** 3) / (1.0 - ratio)


def homogeneous_upsetting(height, initial_height=15.0, radius=10.0, yield_stress=700.0, hardening=300.0,
                          youngs_modulus=2.0e5, poisson_ratio=0.3):
    """(platen force, J) of a cylinder (``radius``, half height
    ``initial_height``) compressed homogeneously to half height ``height``
    by frictionless platens: the axial stress sigma = yield + hardening
    eps_p with eps_p = ln(h0/h) - sigma/E (solved by fixed point), the
    volume ratio J = 1 - (1 - 2 nu) sigma / E, and the force sigma x
    A0 h0 / h x J (the current area)."""
    sigma = yield_stress
    for _ in range(50):                       # sigma = yield + hardening (ln(h0/h) - sigma/E)
        sigma = yield_stress + hardening * (np.log(initial_height / height) - sigma / youngs_modulus)
    J = 1.0 - (1.0 - 2.0 * poisson_ratio) * sigma / youngs_modulus
    return sigma * np.pi * radius ** 2 * initial_height / height * J, J
