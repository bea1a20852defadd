"""Explicit MPM (MPM intro eq. 1-10) and energy behaviour of the Newmark
integrator, on a bar in free longitudinal vibration.

The bar (length L = 1, plane strain, rollers top and bottom so that the
strain is uniaxial) is fixed at x = 0 and free at x = L, and starts with the
velocity of its fundamental mode, v = v0 sin(pi x / 2L). Its period is
T = 4 L / c with c = sqrt((kappa + 4/3 mu) / rho).
"""
import numpy as np
import petsc4py
petsc4py.init([])
import pytest
from mpi4py import MPI

from pimpm.analysis import Analysis, Observer
from pimpm.config import validate
from pimpm.materials import make_material
from pimpm.simulation import SetupError, Simulation
from pimpm.step_control import TimeStepControl


def bar_config(integrator, dt=None, stress_update=None, shape="linear", formulation=None):
    raw = {
        "grid": {"lower": [0, 0], "upper": [1.25, 0.1], "cells": [25, 2], "shape_functions": shape,
                 "boundary": {"xmin": "fixed", "ymin": "roller", "ymax": "roller"}},
        "materials": {"m": {"model": "neo_hookean", "youngs_modulus": 1000.0,
                            "poisson_ratio": 0.3, "density": 1.0}},
        "bodies": [{"name": "bar", "material": "m", "particles_per_cell": 2,
                    "geometry": {"type": "box", "lower": [0, 0], "upper": [1.0, 0.1]}}],
        "time": {"integrator": integrator, "end_time": 10.0},
    }
    if dt is not None:
        raw["time"]["dt"] = dt
    if stress_update:
        raw["time"]["stress_update"] = stress_update
    if formulation:
        raw["time"]["formulation"] = formulation
    return validate(raw)


class TipRecord(Observer):
    """Time, tip velocity and total energy after every step."""

    def __init__(self, tip_id):
        self.tip_id = tip_id
        self.times, self.tip_velocity, self.energy = [], [], []

    def start(self, analysis):
        self.energy.append(analysis.sim.kinetic_energy() + analysis.sim.strain_energy())

    def step(self, analysis, info):
        p = analysis.sim.particles
        self.times.append(info["time"])
        self.tip_velocity.append(p["v"][np.flatnonzero(p["id"] == self.tip_id)[0], 0])
        self.energy.append(info["kinetic_energy"] + info["strain_energy"])


def vibrate(config, periods, dt=None):
    """The bar in its fundamental mode for ``periods`` periods, with pimpm's
    loop at the input's dt (or the CFL step when explicit); returns the
    simulation, the analytic period, the periods measured from the tip
    velocity's zero crossings and the total energy after every step."""
    m = make_material(config["materials"]["m"])
    period = 4.0 / np.sqrt((m.bulk_modulus + 4.0 / 3.0 * m.shear_modulus) / m.density)
    assert dt is None or dt == config["time"]["dt"]
    sim = Simulation(dict(config, time=dict(config["time"], end_time=periods * period)), MPI.COMM_WORLD)
    p = sim.particles
    p["v"][:, 0] = 0.01 * np.sin(np.pi * p["x"][:, 0] / 2.0)
    record = TipRecord(p["id"][np.argmax(p["x0"][:, 0])])
    assert Analysis(sim, [record], TimeStepControl(dict(sim.config["time"], max_cuts=0))).run() == 0
    t, v, energy = np.array(record.times), np.array(record.tip_velocity), record.energy
    down = np.flatnonzero((v[:-1] > 0) & (v[1:] <= 0))
    crossings = t[down] + (t[down + 1] - t[down]) * v[down] / (v[down] - v[down + 1])
    return sim, period, np.diff(crossings), np.array(energy)


@pytest.mark.parametrize("stress_update,shape", [("musl", "linear"), ("usl", "linear"),
                                                 ("usf", "linear"), ("musl", "gimp"),
                                                 ("musl", "bspline")])
def test_explicit_bar_vibrates_at_the_analytic_frequency(stress_update, shape):
    sim, period, measured, energy = vibrate(bar_config("explicit", stress_update=stress_update,
                                                       shape=shape), 3)
    assert len(measured) >= 2
    assert np.all(np.abs(measured - period) < 0.01 * period)
    # stable at the CFL step: the energy stays bounded (no growth)
    assert energy.max() < 1.05 * energy[0] and energy.min() > 0.9 * energy[0]
    assert sim.step_index > 100 and sim.solver is None


def test_explicit_refuses_a_step_above_the_cfl_limit():
    limit = 0.05 / np.sqrt((1000.0 / 3 / 0.4 + 4.0 / 3.0 * 1000.0 / 2.6) / 1.0)
    Simulation(bar_config("explicit", dt=0.9 * limit), MPI.COMM_WORLD)
    with pytest.raises(SetupError, match="explicit stability limit"):
        Simulation(bar_config("explicit", dt=1.5 * limit), MPI.COMM_WORLD)


@pytest.mark.parametrize("shape,formulation", [("linear", "velocity"), ("gimp", "velocity"),
                                               ("bspline", "velocity"), ("linear", "momentum")])
def test_newmark_conserves_energy_of_a_free_vibration(shape, formulation):
    """Trapezoidal rule (G&W eq. 14-16) at 3.7x the explicit step: total
    energy within 0.5% over 10 periods (0.34% measured), period elongation
    below 1%. The grid itself conserves energy; the particle-grid transfers
    lose a little each step (0.66% at 7x, 1.3% at 14x the explicit step)."""
    sim, period, measured, energy = vibrate(bar_config("newmark", dt=0.0025, shape=shape,
                                                       formulation=formulation), 10, dt=0.0025)
    assert 0.0025 > 3 * sim.stable_time_step()
    assert np.max(np.abs(energy - energy[0])) < 0.005 * energy[0]
    assert len(measured) >= 8 and np.all(np.abs(measured - period) < 0.01 * period)
    sim.solver.destroy()


def test_backward_euler_dissipates_where_newmark_conserves():
    """Sulsky & Kaul's theta = 1 scheme at the same step loses a large part
    of the vibration energy (numerical damping), unlike the trapezoidal rule."""
    sim, period, measured, energy = vibrate(bar_config("backward_euler", dt=0.0025), 10, dt=0.0025)
    assert energy[-1] < 0.5 * energy[0]
    assert np.all(np.diff(energy) < 1e-3 * energy[0])     # monotone decay (up to round-off)
    sim.solver.destroy()


def test_explicit_billet_same_on_1_and_2_ranks(tmp_path):
    from helpers import MPIEXEC, coarse_billet, run_on_ranks
    if MPIEXEC is None:
        pytest.skip("mpiexec not found")
    raw = coarse_billet("explicit", directory="out")
    raw["time"] = {"integrator": "explicit", "end_time": 0.01}
    (p1, t1, _), (p2, t2, _) = run_on_ranks(tmp_path, raw, (1, 2), timeout=300)
    assert t1 == pytest.approx(0.01, rel=1e-12) and t2 == pytest.approx(0.01, rel=1e-12)
    assert np.array_equal(p1["id"], p2["id"])
    assert np.max(np.abs(p1["displacement"])) > 0.1
    np.testing.assert_allclose(p2["position"], p1["position"], rtol=0, atol=1e-10)
    np.testing.assert_allclose(p2["stress"], p1["stress"], rtol=0, atol=1e-8 * np.abs(p1["stress"]).max())


def test_explicit_axisymmetric_upsetting_same_on_1_and_3_ranks(tmp_path):
    """Explicit axisymmetric J2 (the first 0.1 mm of inputs/upsetting.yaml at
    2 mm cells) on 1 rank and on 3 ranks: the
    same history (forces, energies, external work) and particle state."""
    from helpers import MPIEXEC, coarse_upsetting, run_on_ranks
    if MPIEXEC is None:
        pytest.skip("mpiexec not found")
    raw = coarse_upsetting()
    raw["time"] = {"integrator": "explicit", "end_time": 1.0e-4}
    raw["output"] = {"directory": "out", "every": 1000}
    (p1, t1, h1), (p3, t3, h3) = run_on_ranks(tmp_path, raw, (1, 3), timeout=300)
    assert t1 == pytest.approx(1.0e-4, rel=1e-12) and len(h1) == len(h3) > 300
    for column in ("platen_force_y", "strain_energy", "external_work"):
        np.testing.assert_allclose(h3[column], h1[column], rtol=1e-9)
    assert h1["external_work"][-1] > 0
    assert np.array_equal(p1["id"], p3["id"])
    np.testing.assert_allclose(p3["position"], p1["position"], rtol=0, atol=1e-9)
    assert p1["eq_plastic_strain"].max() > 0.0
