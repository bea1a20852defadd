"""Rigid tools in unilateral contact with Coulomb friction
(pimpm/terms/contact.py, pimpm/kernels/contact.py): the contact law's
derivative against finite differences for every tool geometry and state,
the whole Jacobian with contact on 1-3 ranks in 2D and 3D (assembled and
matrix-free), the input's contact keys, and two benchmarks with exact
answers: a plate that compresses a square and lets go, and a block sliding
down a ramp."""
import csv
import os

import numpy as np
import petsc4py
import pytest

petsc4py.init([])
from mpi4py import MPI  # noqa: E402

from helpers import HERE, BatchedChecks, run_pimpm  # noqa: E402
from pimpm.analysis import Observer, Trace, run_to_end  # noqa: E402
from pimpm.config import ConfigError, load_config, validate  # noqa: E402
from pimpm.kernels import contact as kernels  # noqa: E402
from pimpm.measures import mean_displacement  # noqa: E402
from pimpm.reference import homogeneous_upsetting  # noqa: E402

REPO = os.path.dirname(HERE)


# ----------------------------------------------------------------- the contact law
def _point(kind, params, y, slip, history, friction, dim, mu=0.3, kt=0.0, pressure=False):
    f, D, t, elastic = np.zeros(3), np.zeros((3, 3)), np.zeros(3), np.zeros(3)
    status, p, _ = kernels.contact_point(kind, params, y, slip, history, 0.7, 1e3, 5.0, kt, mu, friction,
                                         dim, f, D, t, elastic)
    if pressure:
        return status, f[:dim].copy(), D[:dim, :dim].copy(), p
    return status, f[:dim].copy(), D[:dim, :dim].copy()


def _random_points(seed, dim, history_scale, count=200):
    """``count`` random (point, carried elastic slip, slip over the step), the
    points about the tools' size, zero beyond ``dim``."""
    rng = np.random.default_rng(seed)
    for _ in range(count):
        y, history, slip = rng.normal(size=3) * 0.9, rng.normal(size=3) * history_scale, rng.normal(size=3) * 0.01
        y[dim:] = history[dim:] = slip[dim:] = 0.0
        yield y, history, slip


def _derivative_error(force, y, slip, D, dim, step=1e-7):
    """The relative difference of ``D`` from central differences of
    ``force(y, slip)`` (the point and its slip moved together)."""
    fd = np.zeros((dim, dim))
    for b in range(dim):
        e = np.zeros(3)
        e[b] = step
        fd[:, b] = (force(y + e, slip + e) - force(y - e, slip - e)) / (2.0 * step)
    return np.max(np.abs(fd - D)) / max(np.max(np.abs(fd)), 1e-30)


def _tools():
    base = np.zeros(12)
    base[11] = 1e-3
    half = base.copy()
    normal = np.array([0.3, 1.0, 0.2])
    half[3:6] = normal / np.linalg.norm(normal)
    ball = base.copy()
    ball[:3], ball[6] = [0.1, -0.2, 0.3], 1.0
    box = base.copy()
    box[:3], box[3:6] = [-1, -1, -1], [1, 1, 1]
    cylinder = box.copy()
    cylinder[6], cylinder[7], cylinder[8:11] = 0.8, 2, [0.1, 0.0, 0.0]
    return {"half_space": (kernels.HALF_SPACE, half), "ball": (kernels.BALL, ball),
            "box": (kernels.BOX, box), "cylinder": (kernels.CYLINDER, cylinder)}


def _tool(name, dim):
    """(kind, params) of the tool ``name`` of :func:`_tools` in ``dim``
    dimensions (a cylinder's test is skipped in 2D)."""
    if name == "cylinder" and dim == 2:
        pytest.skip("a cylinder is a 3D tool")
    return _tools()[name]


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("tool", ["half_space", "ball", "box", "cylinder"])
@pytest.mark.parametrize("kt", [0.0, 20.0])
def test_the_contact_laws_derivative_equals_finite_differences_in_every_state(dim, tool, kt):
    """df/dy of the penalty with Coulomb's return map (the slip moves with
    the point), at random points inside and outside the tool: open, stick
    and slip all occur, and every derivative matches central differences;
    with a cap kt on the tangential stiffness, both below the cap (mu p <
    kt stick) and above it."""
    kind, params = _tool(tool, dim)
    seen, worst = set(), 0.0
    for y, history, slip in _random_points(5, dim, history_scale=5.0):
        for friction in (False, True):
            status, _, D, p = _point(kind, params, y, slip, history, friction, dim, kt=kt, pressure=True)
            seen.add((friction, int(status)))
            if friction and status == kernels.STICK:
                seen.add(("capped", bool(kt > 0.0 and 0.3 * p > kt * 5.0)))
            worst = max(worst, _derivative_error(
                lambda y, slip: _point(kind, params, y, slip, history, friction, dim, kt=kt)[1], y, slip, D, dim))
    assert worst < 1e-6
    assert {(False, kernels.OPEN), (False, kernels.SLIP), (True, kernels.OPEN), (True, kernels.STICK),
            (True, kernels.SLIP)} <= seen
    assert ("capped", False) in seen and (("capped", True) in seen) == (kt > 0.0)


def _tied(kind, params, y, slip, history, dim, hold):
    f, D, t, elastic = np.zeros(3), np.zeros((3, 3)), np.zeros(3), np.zeros(3)
    status, p, _ = kernels.contact_point(kind, params, y, slip, history, 0.7, 1e3, 5.0, 20.0, 0.0, True,
                                         dim, f, D, t, elastic, -1, hold, -1.0, 0.0, True)
    return status, f[:dim].copy(), D[:dim, :dim].copy(), p, elastic[:dim].copy()


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("tool", ["half_space", "ball", "box", "cylinder"])
def test_a_tied_points_derivative_equals_finite_differences_and_it_pulls(dim, tool):
    """``contact: tied``: a point that touched (held) is welded, inside and
    outside the tool: force p n + t with p = -k_n phi (negative outside: it
    pulls) and t = -k_t s on the elastic slip s = P (history + slip); a point
    that never touched is open outside and frictionless inside (status SLIP,
    no elastic slip: it is tied from the next step on). df/dy against
    central differences everywhere."""
    kind, params = _tool(tool, dim)
    seen, worst = set(), 0.0
    for y, history, slip in _random_points(11, dim, history_scale=0.01):
        for hold in (False, True):
            status, f, D, p, elastic = _tied(kind, params, y, slip, history, dim, hold)
            n, H = np.zeros(3), np.zeros((3, 3))
            phi = kernels.tool_distance(kind, params, y, dim, n, H, -1)
            if not hold and phi > 0.0:
                assert status == kernels.OPEN and not np.any(f)
                seen.add("open")
                continue
            if not hold:
                assert status == kernels.SLIP and p == pytest.approx(-1e3 * phi) and not np.any(elastic)
                assert np.allclose(f, 0.7 * p * n[:dim])
                seen.add("first touch")
                continue
            assert status == kernels.STICK and p == pytest.approx(-1e3 * phi)
            s = (history + slip)[:dim] - n[:dim] * np.dot(n[:dim], (history + slip)[:dim])
            assert np.allclose(elastic, s) and np.allclose(f, 0.7 * (p * n[:dim] - 20.0 * s))
            seen.add("pulls" if p < 0.0 else "pushes")
            worst = max(worst, _derivative_error(
                lambda y, slip: _tied(kind, params, y, slip, history, dim, hold)[1], y, slip, D, dim))
    assert worst < 1e-6
    assert seen == {"open", "first touch", "pulls", "pushes"}


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("kt", [0.0, 2e4])
def test_the_corners_kernel_equals_the_law_at_each_corner(dim, kt):
    """contact_forces gathers each particle's displacement and gradient once
    for its corners (u_p + grad_p r_c): the same as the corner weights
    S + G . r_c of corner_weights applied node by node, with the law at each
    corner (contact_point) and its force scattered by those weights."""
    rng = np.random.default_rng(7 + dim)
    n, nn, nodes, corners = 40, 3 ** dim, 60, 1 << dim
    node_index = rng.integers(0, nodes, size=(n, nn))
    S, G = rng.random((n, nn)) / nn, rng.normal(size=(n, nn, dim))
    half = 0.05 + 0.02 * rng.random((n, dim))
    W, offsets = np.empty((n, corners, nn)), np.empty((n, corners, dim))
    kernels.corner_weights(node_index, S, G, half, W, offsets)
    x = rng.normal(size=(n, dim)) * 0.3
    x[:, -1] = rng.normal(size=n) * 0.04                  # about the floor: some corners in it
    u_local = rng.normal(size=(nodes, dim)) * 2e-3
    params = np.zeros(12)
    params[3 + dim - 1] = 1.0                             # the floor y (z) < 0, normal up
    offset_end, increment = np.zeros(dim), rng.normal(size=dim) * 1e-3
    history = rng.normal(size=(n, corners, dim)) * 1e-3
    area = 0.5 + rng.random((n, corners))
    faces = np.full(n, -1, dtype=np.int64)
    held = np.zeros((n, corners), dtype=np.int8)
    kn, stick, mu = 1e3, 1e-3, 0.3
    out = {"force": np.zeros((nodes, dim)), "D": np.empty((n, corners, dim, dim)),
           "status": np.empty((n, corners), dtype=np.int8), "pressure": np.empty((n, corners)),
           "traction": np.empty((n, corners, dim)), "elastic": np.empty((n, corners, dim)),
           "dissipation": np.empty((n, corners)), "corner_force": np.empty((n, corners, dim))}
    kernels.contact_forces(kernels.HALF_SPACE, params, node_index, S, G, W, x, offsets, u_local, offset_end,
                           increment, history, area, faces, kn, stick, kt, mu, True, held, out["force"], out["D"],
                           out["status"], out["pressure"], out["traction"], out["elastic"], out["dissipation"],
                           out["corner_force"], np.full((n, corners), -1.0))
    force = np.zeros((nodes, dim))
    for p in range(n):
        for c in range(corners):
            moved = W[p, c] @ u_local[node_index[p]]
            y, slip = np.zeros(3), np.zeros(3)
            y[:dim] = x[p] + offsets[p, c] + moved - offset_end
            slip[:dim] = moved - increment
            f, D, t, elastic = np.zeros(3), np.zeros((3, 3)), np.zeros(3), np.zeros(3)
            status, pressure, _ = kernels.contact_point(kernels.HALF_SPACE, params, y, slip, history[p, c], area[p, c],
                                                        kn, stick, kt, mu, True, dim, f, D, t, elastic)
            assert status == out["status"][p, c]
            assert pressure == pytest.approx(out["pressure"][p, c], rel=1e-12, abs=1e-12)
            np.testing.assert_allclose(out["corner_force"][p, c], f[:dim], rtol=1e-10, atol=1e-12)
            np.testing.assert_allclose(out["D"][p, c], D[:dim, :dim], rtol=1e-10, atol=1e-9)
            if status != kernels.OPEN:
                np.add.at(force, node_index[p], W[p, c][:, None] * f[:dim])
    counts = np.bincount(out["status"].ravel(), minlength=3)
    assert counts[kernels.OPEN] > 0 and counts[kernels.STICK] > 0 and counts[kernels.SLIP] > 0
    np.testing.assert_allclose(out["force"], force, rtol=1e-10, atol=1e-12)


def test_a_tool_never_pulls():
    """Outside the tool, no force, however the point slid."""
    kind, params = _tools()["box"]
    status, f, D = _point(kind, params, np.array([0.0, 1.01, 0.0]), np.array([0.3, 0.0, 0.0]),
                          np.array([50.0, 0.0, 0.0]), True, 2)
    assert status == kernels.OPEN and not np.any(f) and not np.any(D)


def test_the_predictor_keeps_a_resting_corners_depth_and_pushes_out_the_rest():
    """The contact predictor (kernels.push_out) moves a corner that the
    Newton guess puts deeper than its depth at the start of the step (0 for
    an open corner, the last step's penetration for a resting one) by more
    than the stick length back to that depth, and leaves the others alone."""
    kind, params = 0, np.zeros(12)                     # the half-space y < 0
    params[4] = 1.0
    depths = np.array([-0.01, -0.004, -0.00505, 0.002])       # four corners, one node each
    x = np.zeros((4, 2))
    x[:, 1] = depths
    node_index = np.arange(4).reshape(4, 1)
    W = np.ones((4, 1, 1))
    offsets = np.zeros((4, 1, 2))
    faces = np.full(4, -1)
    for target, expected in ((np.zeros((4, 1)), [0.01, 0.004, 0.00505, 0.0]),
                             (np.full((4, 1), -0.005), [0.005, 0.0, 0.0, 0.0])):
        moved, weight = np.zeros((4, 2)), np.zeros(4)
        kernels.push_out(kind, params, node_index, W, x, offsets, np.zeros((4, 2)), np.zeros(2), faces, target,
                         1e-4, moved, weight)
        assert np.allclose(moved[:, 1], expected) and not np.any(moved[:, 0])
        assert np.array_equal(weight > 0, np.array(expected) > 0)


CONTACT_JACOBIAN_CASES = [
    (1, "2d", "frictionless", "ball", []), (1, "2d", "friction", "box", []), (2, "2d", "friction", "box", []),
    (3, "2d", "friction", "half_space", []), (2, "3d", "friction", "box", []),
    (1, "3d", "frictionless", "ball", []),
    (1, "2d", "friction", "box", ["hht", "axisymmetric"]),
    (2, "2d", "friction", "box", ["quasi_static", "axisymmetric", "linear"]),
    (1, "2d", "frictionless", "box", ["backward_euler", "plane_stress", "bspline"]),
    (2, "2d", "friction", "box", ["newmark", "plane_strain", "gimp", "uncapped"]),
    (3, "3d", "friction", "box", []),
    (2, "2d", "friction", "surface", []), (2, "3d", "frictionless", "surface", []),
    (1, "2d", "tied", "box", ["quasi_static", "axisymmetric"]), (2, "2d", "tied", "box", []),
    (3, "3d", "tied", "box", ["quasi_static"])]
#: the cases of a rank count run as one MPI job (tests/mpi/batch.py)
CONTACT_JACOBIAN_CHECKS = BatchedChecks("contact_jacobian_check.py", [
    (nranks, [dim, law, geometry] + options) for nranks, dim, law, geometry, options in CONTACT_JACOBIAN_CASES])


@pytest.mark.mpi
@pytest.mark.parametrize("nranks, dim, law, geometry, options", CONTACT_JACOBIAN_CASES)
def test_the_jacobian_with_contact_equals_finite_differences(nranks, dim, law, geometry, options):
    """Every integrator's, kinematics' and shape function's tangent with
    contact (options: integrator, kinematics, shape functions)."""
    proc = CONTACT_JACOBIAN_CHECKS.result(nranks, [dim, law, geometry] + options)
    assert proc.returncode == 0, proc.stdout + proc.stderr


# ----------------------------------------------------------------- input
def _plate_raw():
    import yaml
    with open(f"{REPO}/inputs/plate_release.yaml") as f:
        return yaml.safe_load(f)


@pytest.mark.parametrize("change, message", [
    ({"contact": "glue"}, "bodies[1].contact = 'glue': expected one of bonded, frictionless, friction, tied"),
    ({"contact": "friction"}, "bodies[1].friction_coefficient is missing"),
    ({"contact": "friction", "friction_coefficient": -0.1}, "bodies[1].friction_coefficient = -0.1: expected a number >= 0"),
    ({"contact": "friction", "friction_coefficient": float("nan")}, "bodies[1].friction_coefficient = nan"),
    ({"contact": "friction", "friction_coefficient": float("inf")}, "bodies[1].friction_coefficient = inf"),
    ({"contact": "friction", "friction_coefficient": "rough"}, "bodies[1].friction_coefficient = 'rough'"),
    ({"friction_coefficient": 0.3}, "no friction_coefficient with contact: frictionless"),
    ({"contact_stiffness": 0.0}, "bodies[1].contact_stiffness = 0.0: expected a positive number"),
    ({"contact": "bonded", "contact_stiffness": 10.0}, "no contact_stiffness with contact: bonded"),
    ({"contact": "friction", "friction_coefficient": 0.3, "slip_tolerance": 0.0},
     "bodies[1].slip_tolerance = 0.0: expected a positive number"),
    ({"contact": "friction", "friction_coefficient": 0.3, "slip_tolerance": float("nan")},
     "bodies[1].slip_tolerance = nan"),
    ({"contact": "friction", "friction_coefficient": 0.3, "slip_tolerance": "small"},
     "bodies[1].slip_tolerance = 'small'"),
    ({"slip_tolerance": 0.01}, "no slip_tolerance with contact: frictionless"),
    ({"contact": "friction", "friction_coefficient": 0.3, "tangential_stiffness": -1.0},
     "bodies[1].tangential_stiffness = -1.0: expected a positive number"),
    ({"contact": "friction", "friction_coefficient": 0.3, "tangential_stiffness": float("inf")},
     "bodies[1].tangential_stiffness = inf"),
    ({"contact": "bonded", "tangential_stiffness": 1.0}, "no tangential_stiffness with contact: bonded "
                                                         "(it applies only with contact: friction or tied)"),
    ({"contact": "tied", "slip_tolerance": 1.0}, "no slip_tolerance with contact: tied"),
    ({"contact": "tied", "tangential_stiffness": -1.0}, "bodies[1].tangential_stiffness = -1.0"),
    ({"contact": "tied", "friction_coefficient": 0.3}, "no friction_coefficient with contact: tied"),
])
def test_bad_contact_input_is_one_clear_message(change, message):
    raw = _plate_raw()
    raw["bodies"][1].update(change)
    with pytest.raises(ConfigError) as err:
        validate(raw)
    assert message in str(err.value)


def test_contact_on_a_deformable_body_and_a_half_space_body_are_refused():
    raw = _plate_raw()
    raw["bodies"][0]["contact"] = "frictionless"
    with pytest.raises(ConfigError, match=r"bodies\[0\].contact = 'frictionless': expected no 'contact' "
                                          r"on a deformable body"):
        validate(raw)
    raw = _plate_raw()
    raw["bodies"][0]["geometry"] = {"type": "half_space", "point": [0, 0.5], "normal": [0, 1]}
    with pytest.raises(ConfigError, match="a half_space only on a rigid body"):
        validate(raw)
    raw = _plate_raw()
    raw["bodies"][1]["geometry"] = {"type": "half_space", "point": [0, 0.9], "normal": [0, 0]}
    with pytest.raises(ConfigError, match=r"bodies\[1\].geometry.normal = \[0, 0\]: expected a list of 2 "
                                          r"numbers, not all zero"):
        validate(raw)


# ----------------------------------------------------------------- benchmarks
class _Rows(Observer):
    def __init__(self):
        self.rows = []

    def step(self, analysis, info):
        sim = analysis.sim
        p = sim.particles
        top = sim.comm.allreduce(float(np.max(p["x"][:, 1] + 0.5 * np.sqrt(p["volume0"])))
                                 if len(p) else -np.inf, op=MPI.MAX)
        mean_x = sim.comm.allreduce(float(np.sum(p["mass"] * (p["x"][:, 0] - p["x0"][:, 0])))) / sim.mass0
        self.rows.append({"time": sim.time, "force": np.array(info["forces"][sim.rigid_bodies[0].name]),
                          "plate": info["displacements"][sim.rigid_bodies[0].name].copy(),
                          "newton": info["newton_iterations"], "top": top, "mean_x": mean_x,
                          "stress_yy": sim.comm.allreduce(float(np.sum(p["stress"][:, 1, 1])))
                          / sim.particles.global_count(sim.comm)})


def _run(path, overrides=()):
    rows = _Rows()
    sim, stats, status = run_to_end(load_config(path, list(overrides)), observers=[rows])
    return sim, stats, rows.rows


def test_a_rigid_plate_compresses_exactly_and_lets_go():
    """Benchmark 3 (AMPSSIE's tutorial 2): nu = 0, so the stress is uniaxial
    and uniform; the plate's force over the width follows (E/2)(lambda^2 -
    1)/lambda within 1% over the whole loading, then falls to exactly zero
    once the plate has withdrawn past the square's height, and the square
    stands 0.8 m tall again; Newton needs at most 12 iterations a step."""
    sim, stats, rows = _run(f"{REPO}/inputs/plate_release.yaml")
    assert stats.cuts == 0 and stats.failure is None
    E = 1.0e6
    _assert_plate_stress(rows, axis=1, area=0.8, tolerance=0.01)
    assert rows[19]["stress_yy"] == pytest.approx(0.5 * E * (0.75 ** 2 - 1) / 0.75, rel=0.01)
    for row in rows[40:]:                     # the plate is above the square's top: no force
        assert row["force"][1] == 0.0 and row["force"][0] == 0.0
    assert abs(rows[-1]["stress_yy"]) < 1e-5 * E
    p = sim.particles
    moved = sim.comm.allreduce(float(np.max(np.abs(p["x"] - p["x0"]))) if len(p) else 0.0, op=MPI.MAX)
    # back where it started, to the drift of a load cycle on the grid (1.6 mm,
    # 1.6% of a cell: the billet's load cycle, docs/VALIDATION.md, shows the same)
    assert moved < 0.025 * 0.1, moved
    assert max(row["newton"] for row in rows) <= 12


def _assert_plate_stress(rows, axis, area, tolerance):
    """Over the plate's 20 loading steps, its force over the loaded area
    (along ``axis``) within ``tolerance`` of the exact stress of the 0.8 m
    neo-Hookean block with nu = 0 and E = 1 MPa, (E/2)(lambda^2 - 1)/lambda."""
    for row in rows[:20]:
        stretch = (0.8 + row["plate"][axis]) / 0.8
        exact = 0.5 * 1.0e6 * (stretch ** 2 - 1.0) / stretch
        assert abs(row["force"][axis] / area - exact) <= tolerance * abs(exact), (row, exact)


def test_a_bonded_plate_pulls_the_square_into_tension():
    """The same plate bonded (the default law) does not let go: on the way
    back it pulls (a positive force on the material), which the frictionless
    one never does."""
    sim, stats, rows = _run(f"{REPO}/inputs/plate_release.yaml",
                            ["bodies[1].contact=bonded", "time.end_time=45"])
    assert rows[-1]["force"][1] > 1e4
    sim, stats, rows = _run(f"{REPO}/inputs/plate_release.yaml", ["time.end_time=45"])
    assert all(row["force"][1] <= 0.0 for row in rows)


def test_a_tied_plate_holds_the_square_in_compression_and_tension_exactly():
    """``contact: tied``: the plate is welded to the square at its surface from
    the first touch, so on the way back it pulls the square into tension: the
    plate's force over the width follows (E/2)(lambda^2 - 1)/lambda within 1%
    (and 2e-4 of the largest stress, where it passes zero) over the whole
    cycle, compression and tension alike (measured: 0.4%; the bonded plate,
    which prescribes the nodes its particles reach, is off by up to 6% with
    the plate's position against the grid), with no step cut."""
    sim, stats, rows = _run(f"{REPO}/inputs/plate_release.yaml",
                            ["bodies[1].contact=tied", "time.end_time=45"])
    assert stats.cuts == 0 and stats.failure is None
    assert rows[-1]["plate"][1] == pytest.approx(0.05)       # 5 cm above where it started
    for row in rows:
        stretch = (0.8 + row["plate"][1]) / 0.8
        exact = 0.5 * 1.0e6 * (stretch ** 2 - 1.0) / stretch
        assert abs(row["force"][1] / 0.8 - exact) <= 0.01 * abs(exact) + 2e-4 * 291.7e3, (row, exact)
    assert rows[-1]["stress_yy"] == pytest.approx(0.5 * 1.0e6 * (1.0625 ** 2 - 1) / 1.0625, rel=0.01)


def test_a_tied_platens_first_step_from_rest_is_the_held_corners_linear_response():
    """The 3D upsetting at 1 mm cells, its tied platen moving half a cell in
    the first step onto the cylinder at rest: Newton starts from the
    linearized response to the motion of the corners the platen holds
    (ContactTool.predict). The platen then reaches past corners inside the
    cylinder, a third of a cell below its top; pressed by the penalty too,
    they crushed the top cell layer in that response (a particle to J =
    0.12, nodes a cell below the platen moving 0.4 mm up) and the step was
    cut. Now: no cut, and the load that two steps of half the size
    reach (measured: 0.7% apart, the step's own error)."""
    case = ["grid.cells=[24,24,18]", "time.end_time=5e-4", "output.every=100000"]
    sim, stats, rows = _run(f"{REPO}/inputs/upsetting_3d.yaml", case + ["time.dt=5e-4"])
    assert stats.cuts == 0 and stats.failure is None and len(rows) == 1
    assert rows[0]["newton"] <= 6
    sim, stats, halves = _run(f"{REPO}/inputs/upsetting_3d.yaml", case + ["time.dt=2.5e-4"])
    assert stats.cuts == 0 and len(halves) == 2
    assert rows[0]["force"][2] == pytest.approx(halves[-1]["force"][2], rel=0.015)


@pytest.mark.parametrize("integrator", ["backward_euler", "explicit"])
def test_a_block_hangs_from_a_tied_ceiling(integrator):
    """The block of the ramp benchmark on a tied floor, with gravity turned
    to pull it away from the floor and along it (the floor is a ceiling):
    the tool holds it, pulling and shearing, with the force -m g (within 1%,
    averaged over the explicit step's ringing), and the block stays put (its
    mean displacement below 1 um: the elastic stretch is 0.4 um). Gravity
    ramped on over 10 ms, as for the explicit block that sticks."""
    g = np.array([4.903325, 8.49280804])
    changes = ["bodies[1].contact=tied", "bodies[1].friction_coefficient=null", f"time.integrator={integrator}",
               f"time.gravity=[{g[0]}, {g[1]}]", "time.gravity_function=ramp", "time.end_time=0.02",
               "functions={ramp: {type: table, points: [[0, 0], [0.01, 1], [1, 1]]}}", "output.every=100000"]
    if integrator == "explicit":
        changes.append("time.dt=null")
    sim, stats, rows = _run(f"{REPO}/inputs/block_on_ramp.yaml", changes)
    assert stats.failure is None and stats.cuts == 0
    late = [r for r in rows if r["time"] > 0.012]
    force = np.mean([r["force"] for r in late], axis=0)
    assert force == pytest.approx(-0.4 * g, rel=0.01)        # 0.4 kg per m of thickness
    p = sim.particles
    moved = sim.comm.allreduce(float(np.max(np.abs(p["x"] - p["x0"]))) if len(p) else 0.0, op=MPI.MAX)
    assert moved < 1e-6, moved


def _acceleration(rows):
    t = np.array([0.0] + [r["time"] for r in rows])
    x = np.array([0.0] + [r["mean_x"] for r in rows])
    return 2.0 * np.polyfit(t, x, 2)[0]


@pytest.mark.parametrize("mu", [0.0, 0.3, 0.7])
def test_a_block_slides_down_a_ramp_with_coulombs_acceleration(mu):
    """Benchmark 1 (NairnMPM's Inclined_Plane), the floor variant: gravity
    tilted by 30 degrees; the block's centre of mass accelerates along the
    floor with g (sin 30 - mu cos 30) within 1% (fitted over 0.1 s); with
    mu = 0.7 > tan 30 it stays put (it moves less than 1% of a cell, the
    elastic slip of sticking and the block's own shear)."""
    sim, stats, rows = _run(f"{REPO}/inputs/block_on_ramp.yaml",
                            [f"bodies[1].friction_coefficient={mu}"])
    g, angle = 9.80665, np.radians(30.0)
    assert stats.cuts == 0
    if mu > np.tan(angle):
        assert abs(rows[-1]["mean_x"]) < 0.01 * 0.0025
        assert abs(_acceleration(rows)) < 1e-3 * g
        return
    exact = g * (np.sin(angle) - mu * np.cos(angle))
    assert _acceleration(rows) == pytest.approx(exact, rel=0.01)


@pytest.mark.parametrize("law", ["frictionless", "tied"])
def test_the_plate_gives_the_same_answer_on_two_ranks(tmp_path, law):
    """1 and 2 ranks agree to 1e-8 (the history's forces), the plate
    frictionless or tied (withdrawing and pulling from step 21 on)."""
    histories = []
    for n in (1, 2):
        out = tmp_path / f"r{n}"
        proc = run_pimpm(n, [f"{REPO}/inputs/plate_release.yaml", "--output", out,
                             "--set", "time.end_time=25", "--set", f"bodies[1].contact={law}"])
        assert proc.returncode == 0, proc.stdout + proc.stderr
        with open(out / "history.csv") as f:
            histories.append([float(r["plate_force_y"]) for r in csv.DictReader(f)])
    a, b = np.array(histories[0]), np.array(histories[1])
    assert np.max(np.abs(a - b)) <= 1e-8 * np.max(np.abs(a))


def test_friction_onset_sticks_until_mu_n_then_accelerates():
    """Benchmark 2 (Kratos's friction_tests/conforming): pressed by 1000 N,
    pulled by 300 t N, mu = 0.3, Newmark at dt = 0.1 s: the block sticks
    (it moves only its elastic slip, 1e-3 of a cell) until t = 1 s and slips
    from the next step on; at t = 2 s its velocity is 0.15 m/s within 2% and
    it has slipped 0.05 m within 3%; the normal force stays 1000 N; no step
    is cut."""
    sim, stats, rows = _run(f"{REPO}/inputs/friction_onset.yaml")
    assert stats.cuts == 0 and stats.failure is None
    stick = 1e-3 * 0.25
    # sticking, the block moves at most its elastic slip (2.44e-4 m at t = 1 s); the first
    # step of slip takes it to 3.75e-4 m (so a threshold of 1.5 x stick sat on it)
    onset = next(r["time"] for r in rows if r["mean_x"] > 1.2 * stick)
    assert onset == pytest.approx(1.1)                     # the first step after t = 1 s
    p = sim.particles
    v = sim.comm.allreduce(float(np.sum(p["mass"] * p["v"][:, 0]))) / sim.mass0
    assert v == pytest.approx(0.15, rel=0.02)
    assert rows[-1]["mean_x"] - stick == pytest.approx(0.05, rel=0.03)
    assert all(abs(r["force"][1] - 1000.0) < 1.0 for r in rows)


def test_the_energy_account_books_the_frictional_dissipation(tmp_path):
    """history.csv of the friction onset: the tool's normal and tangential
    force, contact area and points; no dissipation while the block sticks;
    then total energy - external work + dissipation stays within 1% of the
    external work (what is left: the elastic slip's stored energy and the
    trapezoidal rule's error), and the dissipation is about mu N times the
    slip (300 N x 0.05 m)."""
    out = tmp_path / "onset"
    proc = run_pimpm(None, [f"{REPO}/inputs/friction_onset.yaml", "--output", out])
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "floor contact 16" in proc.stdout
    with open(out / "history.csv") as f:
        rows = list(csv.DictReader(f))
    for row in rows:
        assert float(row["floor_normal_force"]) == pytest.approx(1000.0, rel=1e-3)
        assert float(row["floor_contact_area"]) == pytest.approx(1.0)
        assert int(row["floor_contact_points"]) == 16
        if float(row["time"]) < 1.0:
            assert float(row["frictional_dissipation"]) == 0.0
            assert float(row["floor_tangential_force"]) < 0.3 * 1000.0      # below Coulomb's limit
    last = rows[-1]
    balance = (float(last["total_energy"]) - float(last["external_work"])
               + float(last["frictional_dissipation"]))
    assert abs(balance) < 0.01 * float(last["external_work"])
    assert float(last["frictional_dissipation"]) == pytest.approx(300.0 * 0.05, rel=0.03)


def _barrel(sim):
    """Largest particle radius near mid-height and near the platen, and the
    particles' J range (the cylinder's particles)."""
    p = sim.particles
    x = p["x"]
    top = sim.comm.allreduce(float(np.max(x[:, 1])) if len(p) else -np.inf, op=MPI.MAX)
    mid = sim.comm.allreduce(float(np.max(x[x[:, 1] < 0.25 * top, 0], initial=-np.inf)), op=MPI.MAX)
    upper = sim.comm.allreduce(float(np.max(x[x[:, 1] > 0.75 * top, 0], initial=-np.inf)), op=MPI.MAX)
    J = np.linalg.det(p["F"])
    return mid, upper, (sim.comm.allreduce(float(J.min()), op=MPI.MIN), sim.comm.allreduce(float(J.max()), op=MPI.MAX))


def test_a_frictionless_platen_upsets_the_cylinder_homogeneously():
    """Benchmark 4 with mu = 0 (Sulsky & Kaul's cylinder, inputs/upsetting.yaml,
    1 mm cells): the exact answer is homogeneous: at 60% the platen force is
    (700 + 300 eps_p) MPa x A0 h0 / h x J with eps_p = ln(h0/h) - sigma/E and
    J = 1 - (1 - 2 nu) sigma / E (763 kN); pimpm's is within 1.5%, the
    radius at mid-height equals the radius near the platen within a
    particle spacing (no barrelling), particle J within 0.6% of the exact
    0.998, and no step is cut. (The bonded platen gives 1054 kN.)"""
    sim, stats, rows = _run(f"{REPO}/inputs/upsetting.yaml", ["bodies[1].contact=frictionless"])
    assert stats.cuts == 0 and stats.failure is None
    exact, J = homogeneous_upsetting(15.0 - 9.0)
    assert -rows[-1]["force"][1] == pytest.approx(exact, rel=0.015)
    mid, upper, (J_min, J_max) = _barrel(sim)
    assert abs(mid - upper) < 0.5
    assert J_min > 0.994 * J and J_max < 1.006 * J


def test_a_frictionless_platen_upsets_the_cylinder_homogeneously_with_the_nodal_f_bar():
    """The same with F-bar averaged on the nodes (f_bar: nodes): the force
    within 1.5% of the homogeneous one (measured -0.7%), no barrelling, and
    particle J within 0.2% of the exact 0.998 (measured 0.9975-0.9989); it
    cuts a step once on the way (docs/VALIDATION.md)."""
    sim, stats, rows = _run(f"{REPO}/inputs/upsetting.yaml", ["bodies[1].contact=frictionless",
                                                              "materials.steel.f_bar=nodes"])
    assert stats.failure is None and sim.f_bar_average == "nodes"
    exact, J = homogeneous_upsetting(15.0 - 9.0)
    assert -rows[-1]["force"][1] == pytest.approx(exact, rel=0.015)
    mid, upper, (J_min, J_max) = _barrel(sim)
    assert abs(mid - upper) < 0.5
    assert J_min > 0.998 * J and J_max < 1.002 * J


def _history(out, column):
    with open(out / "history.csv") as f:
        return np.array([[float(r[c]) for c in column] for r in csv.DictReader(f)])


def test_a_frictional_run_restarts_to_the_same_answer(tmp_path):
    """The friction onset stopped at t = 1.2 s (sliding) with a checkpoint and
    continued with --restart ends where the run left alone ends: the tool's
    position, the corners' elastic slips and contact state travel in the
    checkpoint. Bitwise up to the stop; after it to 1e-5 (forces) and 1e-6
    (energies), not bitwise: the stopped run's last step lands on t = 1.2
    exactly and so differs from the whole run's twelfth in the last bits of
    dt, and the forces of this stiff block (E = 200 GPa, a contact penalty
    of 1e14 Pa/m) are converged to about 1e-6 of themselves at the default
    Newton tolerances (rtol 1e-8 of a residual scaled by E h = 5e10 N)."""
    columns = ["floor_force_x", "floor_force_y", "floor_tangential_force", "frictional_dissipation",
               "kinetic_energy"]
    whole, parts = tmp_path / "whole", tmp_path / "parts"
    proc = run_pimpm(None, [f"{REPO}/inputs/friction_onset.yaml", "--output", whole])
    assert proc.returncode == 0, proc.stderr
    proc = run_pimpm(None, [f"{REPO}/inputs/friction_onset.yaml", "--output", parts,
                            "--set", "time.end_time=1.2", "--set", "output.checkpoint_every=1"])
    assert proc.returncode == 0, proc.stderr
    proc = run_pimpm(None, [f"{REPO}/inputs/friction_onset.yaml", "--output", parts, "--restart"])
    assert proc.returncode == 0, proc.stdout + proc.stderr
    a, b = _history(whole, columns), _history(parts, columns)
    assert a.shape == b.shape
    assert np.array_equal(a[:11], b[:11])
    scale = np.max(np.abs(a), axis=0)
    error = np.max(np.abs(a - b), axis=0) / scale
    assert np.all(error[:3] < 1e-5) and np.all(error[3:] < 1e-6), error


@pytest.mark.parametrize("nranks", [2, 3, 4])
def test_friction_gives_the_same_answer_on_1_to_4_ranks(nranks, tmp_path):
    """The friction onset (stick until t = 1 s, then slip) on 1 and on 2, 3
    and 4 ranks (a 2x2 process grid) with the direct solver: the tool's
    forces, the dissipation and the kinetic energy agree to 1e-8 (measured
    1.5e-10 at most). The block is made ten thousand times softer than the
    input's (E = 20 MPa): the input's steel block strains by 5e-9 under its
    1000 N, and Newton's residual stalls at 2e-6 of its first value (round-off
    in stresses of E (F - I) with F - I = 5e-9), so its forces are known to
    about 1e-6 on any number of ranks (see the restart test)."""
    columns = ["floor_force_x", "floor_force_y", "frictional_dissipation", "kinetic_energy"]
    histories = []
    for n in (1, nranks):
        out = tmp_path / f"r{n}"
        proc = run_pimpm(n, [f"{REPO}/inputs/friction_onset.yaml", "--output", out,
                             "--set", "grid.cells=[16, 12]", "--set", "materials.steel.youngs_modulus=2e7"])
        assert proc.returncode == 0, proc.stdout + proc.stderr
        histories.append(_history(out, columns))
    a, b = histories
    assert a[-1, 2] > 1.0 and a[5, 2] == 0.0          # it slipped, after sticking
    error = np.max(np.abs(a - b), axis=0) / np.max(np.abs(a), axis=0)
    assert np.all(error < 1e-8), error


def test_explicit_friction_gives_the_same_answer_on_1_and_2_ranks_and_books_its_dissipation(tmp_path):
    """The explicit block on the ramp (mu = 0.3, 5 ms, 487 steps) on 1 and 2
    ranks: forces, kinetic energy and dissipation agree to 1e-9 (measured
    3e-11, and on 4 ranks too); kinetic plus strain energy less the work
    of gravity is minus the frictional dissipation within 1% (measured
    0.5%)."""
    columns = ["ramp_force_x", "ramp_force_y", "kinetic_energy", "frictional_dissipation", "strain_energy",
               "external_work"]
    histories = []
    for n in (1, 2):
        out = tmp_path / f"r{n}"
        proc = run_pimpm(n, [f"{REPO}/inputs/block_on_ramp.yaml", "--output", out, "--set", "time.integrator=explicit",
                             "--set", "time.dt=null", "--set", "time.end_time=0.005", "--set", "output.every=100000"])
        assert proc.returncode == 0, proc.stdout + proc.stderr
        histories.append(_history(out, columns))
    a, b = histories
    error = np.max(np.abs(a - b)[:, :4], axis=0) / np.max(np.abs(a[:, :4]), axis=0)
    assert np.all(error < 1e-9), error
    kinetic, dissipation, strain, work = a[-1, 2], a[-1, 3], a[-1, 4], a[-1, 5]
    assert dissipation > 0.0
    assert kinetic + strain - work == pytest.approx(-dissipation, rel=0.01)


def test_a_particle_that_reaches_a_tool_from_afar_in_one_step_cuts_the_step():
    """Only particles within two cells (plus the tool's travel and their half
    diagonal) of a tool are contact candidates for a step; a block thrown at
    the floor three cells a step reaches it from farther: the step is cut,
    not run through the floor."""
    raw = load_config(f"{REPO}/inputs/block_on_ramp.yaml",
                      ["time.gravity=[0.0, 0.0]", "bodies[0].velocity=[0.0, -7.5]",
                       "bodies[0].geometry.lower=[0.005, 0.0105]", "bodies[0].geometry.upper=[0.025, 0.0305]",
                       "grid.upper=[0.06, 0.04]", "grid.cells=[24, 16]", "time.end_time=0.002"])
    rows = _Rows()
    sim, stats, status = run_to_end(raw, observers=[rows])
    assert stats.cuts >= 1 and stats.failure is None
    p = sim.particles
    assert np.min(p["x"][:, 1]) > 0.005            # nothing went through the floor


def test_an_explicit_block_slides_down_a_frictionless_floor():
    """The explicit step with frictionless contact (the same corners and law,
    at the step's trial state, with a penalty the step can carry): the block
    on the floor with gravity tilted 30 degrees accelerates at g sin 30 within
    1e-4 over 0.02 s."""
    sim, stats, rows = _run(f"{REPO}/inputs/block_on_ramp.yaml",
                            ["time.integrator=explicit", "time.dt=null", "time.end_time=0.02",
                             "bodies[1].contact=frictionless", "bodies[1].friction_coefficient=null"])
    assert stats.failure is None
    g = 9.80665
    assert _acceleration(rows) == pytest.approx(g * 0.5, rel=1e-4)
    assert all(abs(r["force"][0]) < 1e-9 for r in rows)      # a frictionless floor: no tangential force


def test_an_explicit_block_slides_down_a_ramp_with_coulombs_acceleration():
    """The explicit step with Coulomb friction (the same corners and law at
    the step's trial state; a sticking point's stiffness the explicit
    penalty; the elastic slips settled where the step took the corners,
    under the pressures it applied): the block on the floor with gravity
    tilted 30 degrees and mu = 0.3 accelerates at g (sin 30 - mu cos 30)
    within 1e-3 over 0.02 s (about 2000 steps; measured 7e-5), and the
    reported friction is mu times the reported normal force, which averages
    the block's weight across the floor (its elastic ringing, undamped in
    the explicit step, makes it swing from step to step)."""
    sim, stats, rows = _run(f"{REPO}/inputs/block_on_ramp.yaml",
                            ["time.integrator=explicit", "time.dt=null", "time.end_time=0.02", "output.every=100000"])
    assert stats.failure is None
    g = 9.80665
    assert _acceleration(rows) == pytest.approx(g * (0.5 - 0.3 * np.cos(np.pi / 6)), rel=1e-3)
    late = [r for r in rows if r["time"] > 0.005]
    normal = np.mean([abs(r["force"][1]) for r in late])
    tangential = np.mean([abs(r["force"][0]) for r in late])
    assert normal == pytest.approx(0.4 * g * np.cos(np.pi / 6), rel=0.02)     # 0.4 kg per m of thickness
    assert tangential == pytest.approx(0.3 * normal, rel=0.01)


def test_an_explicit_block_sticks_where_coulomb_says():
    """mu = 0.7 > tan 30 in the explicit step, gravity ramped on over 10 ms
    (at once, it rings the undamped elastic block, whose normal force then
    swings by +-40% and lets it creep): the block stays put, less than 1 um
    in all and less than 0.05 um after the ramp (measured: 0.39 um, then 2
    nm)."""
    sim, stats, rows = _run(f"{REPO}/inputs/block_on_ramp.yaml",
                            ["time.integrator=explicit", "time.dt=null", "time.end_time=0.02", "output.every=100000",
                             "bodies[1].friction_coefficient=0.7", "time.gravity_function=ramp",
                             "functions={ramp: {type: table, points: [[0, 0], [0.01, 1], [1, 1]]}}"])
    assert stats.failure is None
    x = np.array([r["mean_x"] for r in rows])
    t = np.array([r["time"] for r in rows])
    assert np.max(np.abs(x)) < 1e-6
    assert np.max(np.abs(x[t > 0.012] - x[t > 0.012][0])) < 5e-8


@pytest.mark.parametrize("mu", [0.3, 0.7])
def test_a_block_turned_on_an_inclined_ramp_slides_as_on_the_tilted_floor(mu):
    """Benchmark 1's other variant (inputs/block_on_incline.yaml): the block
    seeded turned by 30 degrees on an inclined half-space under vertical
    gravity slides down it at g (sin 30 - mu cos 30) within 1% (mu = 0.3),
    or stays put (mu = 0.7: less than 10 um over 0.1 s), as the block on the
    floor under tilted gravity does, without a step cut at the input's step
    (its contact_stiffness 30; the default 100 cut two steps at mu = 0.3)."""
    g, angle = 9.80665, np.radians(30.0)
    down = np.array([np.cos(angle), -np.sin(angle)])
    along = Trace(lambda sim: mean_displacement(sim, down))
    sim, stats, status = run_to_end(load_config(f"{REPO}/inputs/block_on_incline.yaml",
                                                [f"bodies[1].friction_coefficient={mu}"]), observers=[along])
    assert stats.failure is None and stats.cuts == 0
    t, s = np.array(along.values).T
    if mu < np.tan(angle):
        assert 2.0 * np.polyfit(t, s, 2)[0] == pytest.approx(g * (np.sin(angle) - mu * np.cos(angle)), rel=0.01)
    else:
        assert abs(s[-1]) < 1e-5


@pytest.mark.slow
def test_friction_raises_the_upsetting_force_and_barrelling_in_order():
    """Benchmark 4's trend (GIMP, 1 mm): the force at 60% and the barrelling
    (radius at mid-height less the radius near the platen) grow from
    frictionless to mu = 0.1 to mu = 0.3 to bonded; frictionless does not
    barrel; no step is cut."""
    forces, barrels = [], []
    for contact in (["bodies[1].contact=frictionless"],
                    ["bodies[1].contact=friction", "bodies[1].friction_coefficient=0.1"],
                    ["bodies[1].contact=friction", "bodies[1].friction_coefficient=0.3"],
                    ["bodies[1].contact=bonded"]):
        sim, stats, rows = _run(f"{REPO}/inputs/upsetting.yaml", ["grid.shape_functions=gimp"] + contact)
        assert stats.cuts == 0 and stats.failure is None
        mid, upper, _ = _barrel(sim)
        forces.append(-rows[-1]["force"][1])
        barrels.append(mid - upper)
    assert forces == sorted(forces) and barrels == sorted(barrels)
    assert abs(barrels[0]) < 0.1 and barrels[1] > 1.0


@pytest.mark.slow
def test_a_frictional_platen_on_the_billet_approaches_bonded_as_mu_grows():
    """Benchmark 5 (Guilkey & Weiss's billet, inputs/billet.yaml at 1 cm
    cells, 50%): with mu = 0.1, 0.3 and 1 every step converges at the
    input's step; the platen force and the barrelling grow with mu toward
    the bonded platen's; the tangential force stays within mu times the
    normal force; with mu = 0.1 the bulging side folds onto the platen and
    presses on it through the contact law (the contact length grows beyond
    the 20 cm top face). Newton takes at most 6 iterations a step on average
    at every mu (5.0-5.3; 6.0-6.5 when the predictor pushed every corner
    deeper than the stick length out to the platen's surface, and 8.7 when
    the step's first Jacobian also held the touching corners in the normal
    direction only: every corner slipped in the first iterate)."""
    forces, barrels, lengths = [], [], []
    for mu in (0.1, 0.3, 1.0, None):
        contact = (["bodies[1].contact=bonded"] if mu is None else
                   ["bodies[1].contact=friction", f"bodies[1].friction_coefficient={mu}"])
        sim, stats, rows = _run(f"{REPO}/inputs/billet.yaml", ["grid.cells=[40, 21]"] + contact)
        assert stats.cuts == 0 and stats.failure is None
        assert stats.newton <= 6 * len(rows), (mu, stats.newton, len(rows))
        mid, upper, _ = _barrel(sim)
        forces.append(-rows[-1]["force"][1])
        barrels.append(mid - upper)
        if mu is not None:
            tool = sim.contact_tools[0]
            assert tool.last["tangential_force"] <= mu * tool.last["normal_force"] * (1 + 1e-9)
            lengths.append(tool.last["contact_area"])
    assert forces == sorted(forces) and barrels == sorted(barrels)
    assert lengths[0] > 22.0 and lengths[1] > 20.0


PLATE_3D = ["grid={lower: [0, 0, 0], upper: [1.0, 1.0, 1.2], cells: [5, 5, 6], "
            "boundary: {xmin: symmetry, ymin: symmetry, zmin: symmetry}}",
            "bodies[0].geometry={type: box, lower: [0, 0, 0], upper: [0.8, 0.8, 0.8]}",
            "bodies[1].geometry={type: box, lower: [0, 0, 0.8], upper: [1.0, 1.0, 0.9]}",
            "bodies[1].velocity=[0, 0, -0.01]"]


def test_a_rigid_plate_compresses_a_cube_and_lets_go():
    """Benchmark 3 in 3D (the 0.8 m cube, 0.2 m cells): the stress follows
    (E/2)(lambda^2 - 1)/lambda within 1.5% over the loading (0.99% here,
    0.35% at 0.1 m cells: docs/VALIDATION.md) and the force is exactly zero
    once the plate has withdrawn."""
    sim, stats, rows = _run(f"{REPO}/inputs/plate_release.yaml", PLATE_3D)
    assert stats.cuts == 0 and stats.failure is None
    _assert_plate_stress(rows, axis=2, area=0.64, tolerance=0.015)
    assert all(not np.any(row["force"]) for row in rows[40:])


def test_a_step_leaves_no_particle_state_behind(monkeypatch):
    """Once a step has ended, converged or failed, neither the Newton problem
    nor a contact tool keeps its particle state (the footprint, weights,
    stiffness densities, corner weights and iterates, about 2 kB a particle
    in 3D): the migration's copies and the next step's state are not made
    beside it (docs/PERFORMANCE.md, "A step's particle state goes when the
    step ends")."""
    import gc
    import weakref

    from pimpm.errors import StepFailed
    from pimpm.simulation import Simulation
    from pimpm.steps import implicit as implicit_step

    made = []
    prepare = implicit_step.prepare

    def recording(sim, dt):
        state, cons = prepare(sim, dt)
        made.append(weakref.ref(state))
        return state, cons

    monkeypatch.setattr(implicit_step, "prepare", recording)
    sim = Simulation(load_config(f"{REPO}/inputs/block_on_ramp.yaml"), MPI.COMM_SELF)
    tool = sim.contact_tools[0]
    for _ in range(2):
        sim.advance(1e-3)
    gc.collect()
    assert len(made) == 2 and all(ref() is None for ref in made)
    assert sim.problem.state is None and tool._step is None and tool._local is None and tool._x is None
    assert tool.last["contact_points"] > 0          # what the step reported stays
    # a step that fails (one Newton iteration allowed) lets go of its state too
    sim.solver.snes.setTolerances(max_it=1)
    with pytest.raises(StepFailed):
        sim.advance(1e-3)
    gc.collect()
    assert len(made) == 3 and made[-1]() is None and sim.problem.state is None and tool._step is None
