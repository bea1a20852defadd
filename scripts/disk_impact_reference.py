"""An independent reference for the closest approach of two elastic disks
colliding head-on (issue 30, benchmark 2; docs/VALIDATION.md "Two disks
colliding head-on"): a finite-element solution of the same continuum
problem, not MPM.

Two equal disks meeting head-on without friction are mirror images of each
other: the plane between them is a symmetry plane, so each disk hits a
rigid frictionless wall at half their relative speed. This script solves
that with explicit dynamics, total Lagrangian, on linear triangles (plane
strain, the uncoupled neo-Hookean of Guilkey & Weiss eq. 17-18 that the MPM
runs use, with the same E, nu and rho), lumped masses and the central
difference rule; the wall is a kinematic constraint on the nodes (a node
that would cross it is put on it, with the velocity that gets it there:
with lumped masses this is the exact frictionless contact impulse). The
mesh is made of concentric rings of nodes, one node on the line of centres
at every ring, so the contact patch (a half-width of about 0.026 here) is
resolved by 6 to 26 element widths at the resolutions below.

The closest approach of the centres is twice the smallest distance from
the disk's centre of mass to the wall: the diameter less the elastic
flattening of both disks, inertia and ringing included. Printed for three
mesh sizes with the extrapolated limit (first order in the element size
at worst); the quasi-static plane-strain Hertz estimate (Johnson's
approach of two cylinders, P/(pi E*) (2 ln(4R/b) - 1) with all the kinetic
energy stored) is printed beside it.

    python scripts/disk_impact_reference.py [--json docs/data/disk_impact_reference.json]

numpy only; about four minutes at the default sizes (the 0.001 mesh has
120,000 nodes and takes most of it)."""
import argparse
import json
import math
import time

import numpy as np

#: Sulsky & Kaul's disks as scripts/body_contact_validation.py runs them
RADIUS, YOUNG, POISSON, DENSITY, SPEED = 0.2, 1000.0, 0.3, 1000.0, 0.01


def ring_mesh(radius, size):
    """A disk of concentric rings: ring k (k = 1..n) at radius k radius / n
    holds 6k nodes, the first at angle 0 (on the line of centres). Returns
    the reference positions (N, 2) and the triangles (M, 3), counter-
    clockwise."""
    n = max(1, int(round(radius / size)))
    points, first = [np.zeros((1, 2))], [0]
    for k in range(1, n + 1):
        angle = 2 * np.pi * np.arange(6 * k) / (6 * k)
        points.append(radius * k / n * np.column_stack([np.cos(angle), np.sin(angle)]))
        first.append(first[-1] + (1 if k == 1 else 6 * (k - 1)))
    triangles = [[0, 1 + j, 1 + (j + 1) % 6] for j in range(6)]
    for k in range(1, n):
        inner, outer = 6 * k, 6 * (k + 1)
        i = j = 0
        # walk both rings by angle, closing a triangle on the ring whose next node comes first
        while i < inner or j < outer:
            a_inner = (i + 1) / inner
            a_outer = (j + 1) / outer
            if j < outer and (i >= inner or a_outer <= a_inner):
                triangles.append([first[k] + i % inner, first[k + 1] + j, first[k + 1] + (j + 1) % outer])
                j += 1
            else:
                triangles.append([first[k] + i, first[k + 1] + j % outer, first[k] + (i + 1) % inner])
                i += 1
    return np.concatenate(points), np.array(triangles)


def stress_p(F, mu, kappa):
    """First Piola-Kirchhoff stress (in-plane, (M, 2, 2)) of the uncoupled
    neo-Hookean in plane strain (F_33 = 1): tau = kappa ln J I + mu dev(J^(-2/3) b)
    (Guilkey & Weiss eq. 18), P = tau F^-T."""
    f11, f12, f21, f22 = F[:, 0, 0], F[:, 0, 1], F[:, 1, 0], F[:, 1, 1]
    J = f11 * f22 - f12 * f21
    b11, b12, b22 = f11 * f11 + f12 * f12, f11 * f21 + f12 * f22, f21 * f21 + f22 * f22
    f = mu * J ** (-2.0 / 3.0)
    diag = kappa * np.log(J) - f * (b11 + b22 + 1.0) / 3.0
    t11, t12, t22 = f * b11 + diag, f * b12, f * b22 + diag
    # F^-T = [[f22, -f21], [-f12, f11]] / J
    P = np.empty_like(F)
    P[:, 0, 0] = (t11 * f22 - t12 * f12) / J
    P[:, 0, 1] = (-t11 * f21 + t12 * f11) / J
    P[:, 1, 0] = (t12 * f22 - t22 * f12) / J
    P[:, 1, 1] = (-t12 * f21 + t22 * f11) / J
    return P


def strain_energy_density(F, mu, kappa):
    J = F[:, 0, 0] * F[:, 1, 1] - F[:, 0, 1] * F[:, 1, 0]
    trC = np.einsum("mij,mij->m", F, F) + 1.0
    return 0.5 * mu * (J ** (-2.0 / 3.0) * trC - 3.0) + 0.5 * kappa * np.log(J) ** 2


def staircase_offset(Y, radius, spacing):
    """How far the MPM disk's surface stands out of the circle at height Y
    (along the line of centres): the disk is seeded as the sub-cells of side
    ``spacing`` whose centres lie inside the circle, on a lattice with a
    sub-cell face at the circle's extreme point (as in the benchmark), so
    the row of sub-cells holding Y ends at radius - k spacing, k the fewest
    sub-cells back from the extreme whose centre is inside."""
    centre = (np.floor(np.abs(Y) / spacing) + 0.5) * spacing
    half_chord = np.sqrt(np.maximum(radius ** 2 - centre ** 2, 0.0))
    k = np.maximum(np.ceil((radius - half_chord) / spacing - 0.5 + 1e-12), 0)
    return radius - k * spacing - np.sqrt(np.maximum(radius ** 2 - Y ** 2, 0.0))


def impact(size, end_time=4.0, courant=0.5, radius=RADIUS, speed=SPEED, staircase=None):
    """One disk at ``speed`` against a rigid frictionless wall it touches at
    t = 0. Returns the smallest distance from its centre of mass to the wall
    (over the run), the largest wall force, the rebound speed of the centre
    of mass and the energy balance. ``staircase``: the sub-cell size of an
    MPM seeding whose staircase surface the wall meets instead of the
    circle (the thin layer between them taken as rigid: each surface node
    meets the wall that much earlier); the run stops 0.25 after the contact
    ends."""
    mu, kappa = YOUNG / (2 * (1 + POISSON)), YOUNG / (3 * (1 - 2 * POISSON))
    X, tri = ring_mesh(radius, size)
    wall = np.full(len(X), np.inf)
    rim = np.isclose(np.hypot(X[:, 0], X[:, 1]), radius) & (X[:, 0] > 0)
    wall[rim] = radius - (staircase_offset(X[rim, 1], radius, staircase) if staircase else 0.0)
    xa, xb, xc = X[tri[:, 0]], X[tri[:, 1]], X[tri[:, 2]]
    area = 0.5 * ((xb[:, 0] - xa[:, 0]) * (xc[:, 1] - xa[:, 1]) - (xb[:, 1] - xa[:, 1]) * (xc[:, 0] - xa[:, 0]))
    assert np.all(area > 0), "a triangle is inverted"
    # reference gradients of the three shape functions, (M, 3, 2)
    grad = np.empty((len(tri), 3, 2))
    grad[:, 0] = np.column_stack([xb[:, 1] - xc[:, 1], xc[:, 0] - xb[:, 0]])
    grad[:, 1] = np.column_stack([xc[:, 1] - xa[:, 1], xa[:, 0] - xc[:, 0]])
    grad[:, 2] = np.column_stack([xa[:, 1] - xb[:, 1], xb[:, 0] - xa[:, 0]])
    grad /= (2 * area)[:, None, None]
    mass = np.bincount(tri.ravel(), np.repeat(DENSITY * area / 3, 3), minlength=len(X))
    total = mass.sum()
    edges = np.stack([xb - xa, xc - xb, xa - xc], axis=1)
    altitude = np.min(2 * area[:, None] / np.linalg.norm(edges, axis=2), axis=1)
    wave = math.sqrt((kappa + 4.0 / 3.0 * mu) / DENSITY)
    dt = courant * altitude.min() / wave
    steps = int(math.ceil(end_time / dt))
    dt = end_time / steps

    gx, gy = grad[:, :, 0], grad[:, :, 1]
    node = tri.ravel()

    def internal(x):
        xe, ye = x[tri, 0], x[tri, 1]
        F = np.empty((len(tri), 2, 2))
        F[:, 0, 0], F[:, 0, 1] = np.sum(xe * gx, 1), np.sum(xe * gy, 1)
        F[:, 1, 0], F[:, 1, 1] = np.sum(ye * gx, 1), np.sum(ye * gy, 1)
        P = stress_p(F, mu, kappa) * area[:, None, None]
        fx = P[:, 0, 0, None] * gx + P[:, 0, 1, None] * gy
        fy = P[:, 1, 0, None] * gx + P[:, 1, 1, None] * gy
        n = len(X)
        return np.column_stack([np.bincount(node, fx.ravel(), n), np.bincount(node, fy.ravel(), n)]), F

    x = X.copy()
    v = np.zeros_like(X)
    v[:, 0] = speed
    force, F = internal(x)
    a = -force / mass[:, None]
    nearest, peak, energy0 = np.inf, 0.0, 0.5 * total * speed ** 2
    t, touched, released, at_nearest = 0.0, False, None, 0.0
    # central differences: v^{n+1/2} = v^n + dt/2 a^n, x^{n+1} = x^n + dt v^{n+1/2}
    for _ in range(steps):
        t += dt
        v_half = v + 0.5 * dt * a
        x_new = x + dt * v_half
        over = x_new[:, 0] > wall
        if np.any(over):
            touched, released = True, None
            # the wall's impulse stops each crossing node on it: x = wall, v = (wall - x^n) / dt
            v_new_x = (wall[over] - x[over, 0]) / dt
            peak = max(peak, float(np.sum(mass[over] * (v_half[over, 0] - v_new_x))) / dt)
            v_half[over, 0] = v_new_x
            x_new[over, 0] = wall[over]
        elif touched and released is None:
            released = t
        x = x_new
        force, F = internal(x)
        a = -force / mass[:, None]
        v = v_half + 0.5 * dt * a
        gap = radius - float(mass @ x[:, 0]) / total
        if gap < nearest:
            nearest, at_nearest = gap, t
        if released is not None and t > released + 0.25:
            break
    kinetic = 0.5 * float(mass @ np.sum(v ** 2, axis=1))
    strain = float(area @ strain_energy_density(F, mu, kappa))
    return {"size": size, "staircase": staircase, "nodes": len(X), "triangles": len(tri), "steps": int(round(t / dt)),
            "dt": dt, "time_of_closest": at_nearest, "contact_ends": released,
            "closest": 2 * nearest, "flattening": 2 * (radius - nearest), "peak_force": peak,
            "restitution": -float(mass @ v[:, 0]) / total / speed, "energy_ratio": (kinetic + strain) / energy0,
            "mass": total}


def hertz_estimate(radius=RADIUS, speed=SPEED):
    """The quasi-static estimate: two cylinders approach by
    delta(P) = P / (pi E*) (2 ln(4R/b) - 1), b = sqrt(4 P R* / (pi E*)),
    1/E* = 2 (1 - nu^2) / E, R* = R/2 (Johnson, two cylinders with parallel
    axes), and store all the relative kinetic energy: int P d delta = m v^2 / 2
    (reduced mass m/2, relative speed 2 speed)."""
    e_star = YOUNG / (2 * (1 - POISSON ** 2))
    kinetic = 0.5 * (0.5 * DENSITY * math.pi * radius ** 2) * (2 * speed) ** 2

    def delta(P):
        b = math.sqrt(4 * P * (radius / 2) / (math.pi * e_star))
        return P / (math.pi * e_star) * (2 * math.log(4 * radius / b) - 1)

    def work(P, n=4000):
        # int_0^P p d delta(p) by parts: P delta(P) - int_0^P delta(p) dp (midpoint rule)
        p = (np.arange(n) + 0.5) * P / n
        return P * delta(P) - sum(delta(q) for q in p) * P / n

    lo, hi = 1e-9, 1e3
    for _ in range(200):
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if work(mid) < kinetic else (lo, mid)
    return {"peak_force": lo, "flattening": delta(lo), "closest": 2 * radius - delta(lo)}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=float, nargs="+", default=[0.005, 0.0025, 0.00125],
                        help="element sizes of the circle's refinement study")
    parser.add_argument("--cells", type=int, nargs="*", default=[20, 40, 80],
                        help="the MPM benchmark's cells across the unit grid (2 particles per cell and axis), "
                             "whose staircase surface the wall also meets")
    parser.add_argument("--staircase-size", type=float, default=0.0025, help="element size of the staircase runs")
    parser.add_argument("--end-time", type=float, default=4.0)
    parser.add_argument("--json")
    args = parser.parse_args()
    rows = []
    header = "| surface | element size | nodes | steps | closest | flattening | peak force | restitution | energy | time (s) |"
    print(header + "\n" + "|---" * (header.count("|") - 1) + "|")
    runs = [(size, None) for size in args.sizes] + [(args.staircase_size, 0.5 / c) for c in args.cells]
    for size, staircase in runs:
        start = time.perf_counter()
        r = impact(size, end_time=args.end_time, staircase=staircase)
        r["seconds"] = time.perf_counter() - start
        r["cells"] = None if staircase is None else int(round(0.5 / staircase))
        rows.append(r)
        surface = "circle" if staircase is None else f"staircase, {r['cells']} cells"
        print(f"| {surface} | {size:g} | {r['nodes']} | {r['steps']} | {r['closest']:.5f} | {r['flattening']:.5f} | "
              f"{r['peak_force']:.3f} | {r['restitution']:.3f} | {r['energy_ratio']:.4f} | {r['seconds']:.0f} |",
              flush=True)
    circle = [r for r in rows if r["staircase"] is None]
    limit = None
    if len(circle) >= 3:
        c = [r["closest"] for r in circle[-3:]]
        # Richardson with the observed order (halved sizes)
        ratio = (c[1] - c[0]) / (c[2] - c[1]) if c[2] != c[1] else math.inf
        order = math.log(abs(ratio), 2) if ratio > 0 else float("nan")
        limit = c[2] + (c[2] - c[1]) / (ratio - 1) if ratio > 1 else c[2]
        print(f"circle, extrapolated closest approach: {limit:.5f} (observed order {order:.2f})")
    hertz = hertz_estimate()
    print(f"quasi-static Hertz, all the kinetic energy stored: closest {hertz['closest']:.5f}, "
          f"peak force {hertz['peak_force']:.3f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"rows": rows, "extrapolated_closest": limit, "hertz": hertz}, f, indent=1)


if __name__ == "__main__":
    main()
