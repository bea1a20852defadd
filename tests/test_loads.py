"""Functions of time, prescribed motions and loads on particles (issue 12;
docs/INPUT.md): the functions and their exact integrals, their validation,
rigid bodies and grid faces that move with a function, and tractions, point
loads and body forces whose resultants equal what the input asks for."""
import copy

import numpy as np
import pytest

import petsc4py

petsc4py.init([])
from mpi4py import MPI  # noqa: E402

from pimpm.analysis import Analysis  # noqa: E402
from pimpm.config import ConfigError, validate  # noqa: E402
from pimpm.functions import TimeFunction  # noqa: E402
from pimpm.simulation import Simulation  # noqa: E402

E, NU = 1.0e4, 0.3


def test_table_values_and_exact_integrals():
    f = TimeFunction([[0.0, 0.0], [1.0, 1.0], [2.0, 1.0], [3.0, -1.0]])
    assert [f(t) for t in (-1.0, 0.5, 1.5, 2.5, 9.0)] == [0.0, 0.5, 1.0, 0.0, -1.0]
    # piecewise linear: trapezoids, and constant beyond the ends
    assert f.integral(0.0, 3.0) == pytest.approx(0.5 + 1.0 + 0.0)
    assert f.integral(0.5, 2.5) == pytest.approx(0.375 + 1.0 + 0.25)
    assert f.integral(3.0, 5.0) == pytest.approx(-2.0)
    assert f.integral(-2.0, 0.0) == 0.0
    # sums of integrals over any steps equal the integral over their union
    steps = np.sort(np.random.default_rng(0).uniform(0.0, 3.5, 17))
    assert sum(f.integral(a, b) for a, b in zip(steps[:-1], steps[1:])) == \
        pytest.approx(f.integral(steps[0], steps[-1]), abs=1e-14)
    jump = TimeFunction([[1.0, 0.0], [1.0, 2.0], [2.0, 2.0]])      # two equal times: a jump
    assert jump(0.5) == 0.0 and jump(1.0) == 2.0 and jump.integral(0.0, 2.0) == pytest.approx(2.0)


def block(dim=2, kinematics=None, **extra):
    """A unit block (0.5 cells) on a grid with room around it, linear elastic."""
    upper = [3.0] * dim
    raw = {"grid": {"lower": [0.0] * dim, "upper": upper, "cells": [6] * dim,
                    "shape_functions": "linear"},
           "materials": {"m": {"model": "neo_hookean", "youngs_modulus": E, "poisson_ratio": NU,
                               "density": 1.0}},
           "bodies": [{"name": "block", "material": "m", "particles_per_cell": 2,
                       "geometry": {"type": "box", "lower": [0.5] * dim, "upper": [1.5] * dim}}],
           "time": {"integrator": "quasi_static", "dt": 0.1, "end_time": 1.0}}
    if kinematics:
        raw["kinematics"] = kinematics
    if kinematics == "axisymmetric":                         # from the axis
        raw["bodies"][0]["geometry"]["lower"][0] = 0.0
    raw.update(extra)
    return raw


FUNCTION_ERRORS = {
    "an unknown function": (
        lambda r: r["bodies"].append({"name": "p", "rigid": True, "velocity": [0, -1], "function": "nope",
                                      "geometry": {"type": "box", "lower": [0.5, 1.5], "upper": [1.5, 2.0]}}),
        ["bodies[1].function = 'nope'", "a function defined under functions (none is defined)"]),
    "unsorted times": (
        lambda r: r.update(functions={"f": {"type": "table", "points": [[0, 0], [2, 1], [1, 0]]}}),
        ["functions.f.points[2][0] = 1", "times in increasing order"]),
    "a non-finite value": (
        lambda r: r.update(functions={"f": {"type": "table", "points": [[0, 0], [1, ".inf"]]}}),
        ["functions.f.points[1][1] = '.inf'", "a finite number"]),
    "a ramp that ends before it starts": (
        lambda r: r.update(functions={"f": {"type": "ramp", "start": 1.0, "end": 0.5}}),
        ["functions.f.end = 0.5", "a number > functions.f.start = 1.0"]),
    "a function on a deformable body": (
        lambda r: (r.update(functions={"f": {"type": "constant", "value": 2.0}}),
                   r["bodies"][0].update(function="f")),
        ["bodies[0].function = 'f'", "only on a rigid body"]),
    "a load on a rigid body": (
        lambda r: (r["bodies"].append({"name": "p", "rigid": True,
                                       "geometry": {"type": "box", "lower": [0.5, 1.5], "upper": [1.5, 2.0]}}),
                   r.update(loads=[{"type": "body_force", "body": "p", "acceleration": [0, -1]}])),
        ["loads[0].body = 'p'", "a deformable body: block"]),
    "a traction without a normal": (
        lambda r: r.update(loads=[{"type": "traction", "body": "block", "traction": [1, 0]}]),
        ["loads[0].normal is missing", "x-, x+, y-, y+"]),
    "a face velocity on an axis the grid lacks": (
        lambda r: r["grid"].update(boundary={"xmax": {"velocity": {"z": 1.0}}}),
        ["grid.boundary.xmax.velocity", "axes among x, y"]),
}


@pytest.mark.parametrize("name", list(FUNCTION_ERRORS))
def test_bad_functions_and_loads_are_named(name):
    edit, wanted = FUNCTION_ERRORS[name]
    raw = block()
    edit(raw)
    with pytest.raises(ConfigError) as err:
        validate(raw)
    assert all(w in str(err.value) for w in wanted), str(err.value)


def test_a_platen_approaches_holds_and_retracts_exactly():
    """The platen's position is the integral of its velocity, whatever the
    steps: after approach (0-0.4), hold (to 0.6) and retraction (to 1.0) it
    is back where it started, and at every step where the table says."""
    raw = block()
    raw["functions"] = {"cycle": {"type": "table",
                                  "points": [[0.0, 1.0], [0.4, 1.0], [0.4, 0.0], [0.6, 0.0],
                                             [0.6, -1.0], [1.0, -1.0]]}}
    raw["bodies"].append({"name": "platen", "rigid": True, "velocity": [0.0, -0.2], "function": "cycle",
                          "geometry": {"type": "box", "lower": [0.25, 1.5], "upper": [1.75, 1.75]}})
    raw["time"].update(dt=0.07)                  # steps that do not fall on the table's times
    sim = Simulation(validate(raw), MPI.COMM_WORLD)
    y0 = sim.comm.allreduce(float(sim.rigid["x"][:, 1].min()) if len(sim.rigid) else np.inf, op=MPI.MIN)
    positions = []

    class Watch:
        def step(self, analysis, info):
            y = sim.rigid["x"][:, 1].min() if len(sim.rigid) else np.inf
            positions.append((sim.time, sim.comm.allreduce(float(y), op=MPI.MIN) - y0,
                              float(info["displacements"]["platen"][1])))

        def __getattr__(self, name):
            return lambda *args: None

    assert Analysis(sim, [Watch()]).run() == 0
    f = sim.rigid_bodies[0].function
    for t, moved, recorded in positions:
        expected = -0.2 * f.integral(0.0, t)
        assert moved == pytest.approx(expected, abs=1e-12) and recorded == pytest.approx(expected, abs=1e-12)
    assert positions[-1][1] == pytest.approx(0.0, abs=1e-12)


def test_a_face_pulled_with_a_ramp_stretches_the_block_uniformly():
    """The block fills the grid between a roller face and a face moving with
    velocity x ramp. The face condition moves the material at the (fixed)
    grid face by the velocity times the ramp's integral over each step, so
    each step stretches the block by 1 + that over the grid's length: the
    stretch is uniform and the product of the steps' stretches."""
    raw = block()
    raw["grid"].update(lower=[0.0, 0.0], upper=[1.0, 1.0], cells=[4, 4],
                       boundary={"xmin": "roller", "ymin": "roller",
                                 "xmax": {"velocity": {"x": 0.05}, "function": "ramp"}})
    raw["bodies"][0]["geometry"] = {"type": "box", "lower": [0.0, 0.0], "upper": [1.0, 1.0]}
    raw["functions"] = {"ramp": {"type": "ramp", "start": 0.0, "end": 1.0}}
    sim = Simulation(validate(raw), MPI.COMM_WORLD)
    assert Analysis(sim).run() == 0
    ramp = sim.functions["ramp"]
    stretch = np.prod([1.0 + 0.05 * ramp.integral(0.1 * k, 0.1 * (k + 1)) for k in range(10)])
    p = sim.particles
    np.testing.assert_allclose(p["x"][:, 0], p["x0"][:, 0] * stretch, rtol=1e-9, atol=1e-12)
    assert np.allclose(p["F"][:, 0, 0], stretch, rtol=1e-9)


AREAS = {  # the loaded face y+ of the unit block [0.5, 1.5]^dim (axisymmetric: r in [0, 1.5])
    "plane_strain": 1.0, "plane_stress": 1.0, "axisymmetric": np.pi * 1.5 ** 2, "3d": 1.0}


@pytest.mark.parametrize("kinematics", list(AREAS))
def test_a_traction_adds_up_to_traction_times_the_loaded_area(kinematics):
    dim = 3 if kinematics == "3d" else 2
    raw = block(dim, None if kinematics == "3d" else kinematics)
    traction = [0.3, -2.0, 0.7][:dim]
    raw["loads"] = [{"name": "top", "type": "traction", "body": "block", "normal": "y+",
                     "traction": traction},
                    {"name": "side", "type": "traction", "body": "block", "normal": "x+",
                     "traction": [1.0] + [0.0] * (dim - 1),
                     "region": {"lower": [0.0] * dim, "upper": [3.0, 1.0] + [3.0] * (dim - 2)}}]
    sim = Simulation(validate(raw), MPI.COMM_WORLD)
    top, side = sim.loads
    area = AREAS[kinematics]
    np.testing.assert_allclose(top.resultant(0.0), np.asarray(traction) * area, rtol=1e-12)
    # the side x+ below y = 1 (half the face; in axisymmetry the cylinder r = 1.5, 2 pi r h)
    side_area = 2.0 * np.pi * 1.5 * 0.5 if kinematics == "axisymmetric" else 0.5
    assert side.total_share == pytest.approx(side_area, rel=1e-12)
    # the nodal external force adds up to the resultants (partition of unity)
    node_index, S, _ = sim.footprint()
    mass = np.ones(sim.grid.n_owned_nodes * dim)
    fext = sim.nodal_external_force(node_index, S, 0.0 * mass, 0.0).reshape(-1, dim).sum(axis=0)
    np.testing.assert_allclose(sim.comm.allreduce(fext), top.resultant(0.0) + side.resultant(0.0),
                               rtol=1e-12, atol=1e-12)


def test_point_loads_and_body_forces_have_their_resultants():
    raw = block()
    raw["functions"] = {"half": {"type": "constant", "value": 0.5}}
    raw["loads"] = [{"name": "poke", "type": "point", "body": "block", "point": [1.0, 1.5],
                     "force": [0.0, -3.0], "function": "half"},
                    {"name": "weight", "type": "body_force", "body": "block", "acceleration": [0.0, -9.8]}]
    sim = Simulation(validate(raw), MPI.COMM_WORLD)
    poke, weight = sim.loads
    np.testing.assert_allclose(poke.resultant(0.0), [0.0, -1.5], rtol=1e-14)
    mass = sim.comm.allreduce(float(np.sum(sim.particles["mass"])))
    assert mass == pytest.approx(1.0, rel=1e-12)
    np.testing.assert_allclose(weight.resultant(0.0), [0.0, -9.8 * mass], rtol=1e-12)
    # shared by the particles nearest the point (the two at equal distance)
    shares = sim.particles[poke.field]
    assert sim.comm.allreduce(int(np.sum(shares > 0))) == 2
    assert sim.comm.allreduce(float(np.sum(shares))) == pytest.approx(1.0)


def test_work_of_a_traction_is_the_stored_energy():
    """Quasi-static stretching of an elastic block by a ramped traction:
    the external work (trapezoidal in time) equals the stored energy."""
    raw = block()
    raw["grid"].update(boundary={"xmin": "roller", "ymin": "roller"})
    raw["bodies"][0]["geometry"] = {"type": "box", "lower": [0.0, 0.0], "upper": [1.0, 1.0]}
    raw["grid"]["lower"] = [0.0, 0.0]
    raw["functions"] = {"ramp": {"type": "ramp", "start": 0.0, "end": 1.0}}
    raw["loads"] = [{"name": "pull", "type": "traction", "body": "block", "normal": "x+",
                     "traction": [0.02 * E, 0.0], "function": "ramp"}]
    raw["time"].update(dt=0.05)
    sim = Simulation(validate(raw), MPI.COMM_WORLD)
    assert Analysis(sim).run() == 0
    stored = sim.strain_energy()
    assert stored > 0 and sim.work.total == pytest.approx(stored, rel=1e-2)
