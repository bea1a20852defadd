"""The exact measure of curved bodies (pimpm/exact_volume.py) against closed
forms, and seeded bodies that weigh exactly that on 1 and 2 ranks."""
import math

import numpy as np
import pytest
from mpi4py import MPI

from pimpm.exact_volume import ball_box, disk_rectangle, exact_measure

INF = 1e9


def brute_force_area(center, r, lower, upper, moment=False, n=2000):
    """Midpoint rule on an n x n lattice (error ~ 1/n^1.5)."""
    xs = lower[0] + (np.arange(n) + 0.5) * (upper[0] - lower[0]) / n
    ys = lower[1] + (np.arange(n) + 0.5) * (upper[1] - lower[1]) / n
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    inside = (X - center[0]) ** 2 + (Y - center[1]) ** 2 < r * r
    weight = X if moment else 1.0
    return float(np.sum(inside * weight)) * (upper[0] - lower[0]) * (upper[1] - lower[1]) / n ** 2


@pytest.mark.parametrize("rect", [((-INF, -INF), (INF, INF)), ((0.0, 0.0), (INF, INF)),
                                  ((0.3, -0.2), (0.9, 0.5)), ((-0.5, 0.6), (2.0, 0.95)),
                                  ((0.8, 0.8), (2.0, 2.0)), ((-2.0, -2.0), (-1.5, 3.0))])
def test_disk_in_a_rectangle_is_exact(rect):
    lower, upper = rect
    exact = disk_rectangle((0.0, 0.0), 1.0, lower, upper)
    if lower == (-INF, -INF):
        assert abs(exact - math.pi) < 1e-14
    elif lower == (0.0, 0.0):
        assert abs(exact - math.pi / 4) < 1e-14
    else:
        lo = np.maximum(lower, -1.0)
        hi = np.maximum(np.minimum(upper, 1.0), lo)
        assert abs(exact - brute_force_area((0.0, 0.0), 1.0, lo, hi)) < 2e-5


def test_first_moment_gives_volumes_of_revolution():
    """Pappus: a half disk on the axis revolves into a ball, a disk at
    R0 > r into a torus 2 pi^2 R0 r^2."""
    ball = 2 * math.pi * disk_rectangle((0.0, 0.0), 1.0, (0.0, -INF), (INF, INF), moment=True)
    assert abs(ball - 4.0 / 3.0 * math.pi) < 1e-13
    torus = 2 * math.pi * disk_rectangle((3.0, 0.0), 0.5, (0.0, -INF), (INF, INF), moment=True)
    assert abs(torus - 2 * math.pi ** 2 * 3.0 * 0.25) < 1e-12
    cut = disk_rectangle((0.2, 0.1), 1.0, (0.0, -0.3), (0.7, 2.0), moment=True)
    assert abs(cut - brute_force_area((0.2, 0.1), 1.0, (0.0, -0.3), (0.7, 1.1), moment=True)) < 2e-5


def test_ball_in_a_box_is_exact():
    whole = ball_box((0.0, 0.0, 0.0), 2.0, (-INF,) * 3, (INF,) * 3)
    assert abs(whole - 32.0 / 3.0 * math.pi) < 1e-12 * whole
    octant = ball_box((0.0, 0.0, 0.0), 2.0, (0.0,) * 3, (INF,) * 3)
    assert abs(octant - whole / 8) < 1e-12 * whole
    h = 0.7                          # a cap of height h: pi h^2 (3 r - h) / 3
    cap = ball_box((0.0, 0.0, 0.0), 2.0, (-INF, -INF, 2.0 - h), (INF,) * 3)
    assert abs(cap - math.pi * h * h * (6.0 - h) / 3.0) < 1e-12 * whole
    # a slab of the ball cut by x = 0.5: the cap formula along x, turned
    side = ball_box((0.0, 0.0, 0.0), 2.0, (0.5, -INF, -INF), (INF,) * 3)
    hx = 1.5
    assert abs(side - math.pi * hx * hx * (6.0 - hx) / 3.0) < 1e-12 * whole


def test_exact_measure_by_geometry():
    quarter = {"type": "cylinder", "lower": [0.0, 0.0, 0.0], "upper": [10.0, 10.0, 15.0], "axis": "z",
               "center": [0.0, 0.0, 0.0], "radius": 10.0}
    grid = (np.zeros(3), np.array([24.0, 24.0, 18.0]))
    assert abs(exact_measure(quarter, *grid) - 25.0 * math.pi * 15.0) < 1e-10
    disk = {"type": "ball", "center": [0.5, 0.5], "radius": 0.2}
    assert abs(exact_measure(disk, np.zeros(2), np.ones(2)) - math.pi * 0.04) < 1e-15
    sphere = {"type": "ball", "center": [0.0, 0.5], "radius": 0.2}
    assert abs(exact_measure(sphere, np.zeros(2), np.ones(2), axisymmetric=True)
               - 4.0 / 3.0 * math.pi * 0.008) < 1e-15
    assert exact_measure({"type": "box", "lower": [0, 0], "upper": [1, 1]}, np.zeros(2), np.ones(2)) is None


@pytest.mark.parametrize("case", ["upsetting_3d", "disk", "axisymmetric_torus"])
def test_seeded_curved_bodies_weigh_exactly(case):
    """The particles of a ball or cylinder sum to its exact volume to 1e-12
    (on any number of ranks: run under mpiexec by the parallel suite too)."""
    import copy
    import os
    import yaml
    from helpers import ROOT
    from pimpm.config import validate
    from pimpm.simulation import Simulation
    if case == "upsetting_3d":
        with open(os.path.join(ROOT, "inputs", "upsetting_3d.yaml")) as f:
            raw = yaml.safe_load(f)
        exact = 25.0 * math.pi * 15.0
    else:
        with open(os.path.join(ROOT, "inputs", "colliding_disks.yaml")) as f:
            raw = yaml.safe_load(f)
        geometry = raw["bodies"][0]["geometry"]
        r = geometry["radius"]
        exact = math.pi * r * r
        if case == "axisymmetric_torus":
            raw = copy.deepcopy(raw)
            raw["kinematics"] = "axisymmetric"
            raw["bodies"] = [raw["bodies"][0]]
            exact = 2.0 * math.pi ** 2 * geometry["center"][0] * r * r        # a torus (Pappus)
    sim = Simulation(validate(raw), MPI.COMM_WORLD)
    volume = MPI.COMM_WORLD.allreduce(float(np.sum(sim.particles["volume0"][sim.particles["body"] == 0])))
    assert abs(volume - exact) < 1e-12 * exact
    sim.solver.destroy() if getattr(sim, "solver", None) is not None else None
