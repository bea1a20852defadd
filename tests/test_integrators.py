"""Time integrators as swappable pieces: HHT-alpha (Hilber, Hughes & Taylor
1977) on the vibrating bar of test_explicit.py.

HHT applied to an undamped oscillator of frequency omega at the step dt
damps it by an amount that is zero for alpha = 0 (the trapezoidal rule)
and grows with |alpha| and with omega dt: the scheme removes high
frequencies and keeps low ones. :func:`hht_oscillator_energy` propagates
that oscillator with the scheme's amplification matrix; the bar, started
in one of its modes, must lose energy as that oscillator does.
"""
import numpy as np
import petsc4py
petsc4py.init([])
import pytest
from mpi4py import MPI

from pimpm.analysis import Analysis, Observer
from pimpm.config import validate
from pimpm.integrators import INTEGRATORS, HHT, Newmark
from pimpm.materials import make_material
from pimpm.simulation import Simulation

from test_explicit import bar_config

DT = 0.0025


def hht_oscillator_energy(omega_dt, alpha, steps):
    """Energy left (relative) after ``steps`` steps of HHT on an undamped
    oscillator started at d = 0, v = 1, a = 0: the state (d, dt v, dt^2 a)
    propagated by the scheme's amplification matrix."""
    beta, gamma = 0.25 * (1.0 - alpha) ** 2, 0.5 - alpha
    w2 = omega_dt ** 2
    # a(n+1) + (1 + alpha) w2 d(n+1) - alpha w2 d(n) = 0 with the Newmark updates
    # d(n+1) = d + v + (1/2 - beta) a + beta a(n+1), v(n+1) = v + (1 - gamma) a + gamma a(n+1)
    lhs = np.array([[1.0, 0.0, -beta], [0.0, 1.0, -gamma], [(1.0 + alpha) * w2, 0.0, 1.0]])
    rhs = np.array([[1.0, 1.0, 0.5 - beta], [0.0, 1.0, 1.0 - gamma], [alpha * w2, 0.0, 0.0]])
    d, v, _ = np.linalg.matrix_power(np.linalg.solve(lhs, rhs), steps) @ np.array([0.0, 1.0, 0.0])
    return v ** 2 + w2 * d ** 2


class EnergyRecord(Observer):
    def start(self, analysis):
        self.energy = [analysis.sim.kinetic_energy() + analysis.sim.strain_energy()]

    def step(self, analysis, info):
        self.energy.append(info["kinetic_energy"] + info["strain_energy"])


def vibrate_mode(integrator, mode, periods, alpha=None, shape="linear"):
    """The bar started in its mode ``mode`` (0: fundamental) at velocity
    amplitude 0.01, run with pimpm's loop for whole steps of DT covering
    ``periods`` periods of the mode; returns (simulation, period of the mode,
    energy per step)."""
    config = bar_config(integrator, dt=DT, shape=shape)
    m = make_material(config["materials"]["m"])
    k = (2 * mode + 1) * np.pi / 2.0                # fixed at x = 0, free at x = L = 1
    period = 2.0 * np.pi / (k * m.wave_speed())
    time = dict(config["time"], end_time=DT * max(1, int(np.ceil(periods * period / DT - 1e-9))))
    if alpha is not None:
        time["alpha"] = alpha
    sim = Simulation(dict(config, time=time), MPI.COMM_WORLD)
    sim.particles["v"][:, 0] = 0.01 * np.sin(k * sim.particles["x"][:, 0])
    record = EnergyRecord()
    assert Analysis(sim, [record]).run() == 0
    return sim, period, np.array(record.energy)


def test_hht_is_registered_with_its_alpha():
    assert INTEGRATORS["hht"] is HHT
    cfg = validate({**_bar_raw(), "time": {"integrator": "hht", "dt": DT, "end_time": 1.0, "alpha": -0.1}})
    assert cfg["time"]["alpha"] == -0.1
    hht = HHT(-0.1)
    assert hht.beta == pytest.approx(0.3025) and hht.gamma == pytest.approx(0.6)
    with pytest.raises(ValueError):
        HHT(-0.4)


def _bar_raw():
    return {"grid": {"lower": [0, 0], "upper": [1.25, 0.1], "cells": [25, 2]},
            "materials": {"m": {"model": "neo_hookean", "youngs_modulus": 1000.0, "poisson_ratio": 0.3,
                                "density": 1.0}},
            "bodies": [{"name": "bar", "material": "m",
                        "geometry": {"type": "box", "lower": [0, 0], "upper": [1.0, 0.1]}}]}


def test_hht_with_alpha_zero_is_the_trapezoidal_rule_bit_for_bit():
    a, _, ea = vibrate_mode("newmark", 0, 1.0)
    b, _, eb = vibrate_mode("hht", 0, 1.0, alpha=0.0)
    assert isinstance(a.integrator, Newmark) and type(b.integrator) is HHT
    assert a.step_index == b.step_index > 40
    for name in ("x", "v", "a", "F", "stress"):
        assert np.array_equal(a.particles[name], b.particles[name]), name
    assert np.array_equal(ea, eb)
    a.solver.destroy()
    b.solver.destroy()


def test_hht_dissipation_grows_with_alpha_and_matches_the_scheme():
    """Fundamental mode over 4 periods: the energy lost grows strictly with
    |alpha|; relative to the trapezoidal run (which keeps the energy to
    0.5%: the transfers' own loss) it is the loss of the HHT oscillator at
    the mode's omega dt, to 20%."""
    periods = 4.0
    final = {}
    for alpha in (0.0, -0.05, -0.15, -0.3):
        sim, period, energy = vibrate_mode("hht", 0, periods, alpha=alpha)
        final[alpha] = energy[-1] / energy[0]
        steps = sim.step_index
        sim.solver.destroy()
    values = [final[a] for a in (0.0, -0.05, -0.15, -0.3)]
    assert all(later < earlier for earlier, later in zip(values, values[1:])), values
    assert abs(final[0.0] - 1.0) < 0.005
    omega_dt = 2.0 * np.pi / period * DT
    for alpha in (-0.05, -0.15, -0.3):
        predicted = 1.0 - hht_oscillator_energy(omega_dt, alpha, steps)
        measured = 1.0 - final[alpha] / final[0.0]
        assert abs(measured / predicted - 1.0) < 0.2, (alpha, measured, predicted)


def test_hht_damps_high_frequencies_more_than_low_ones():
    """At the same step and alpha, the third mode (5x the frequency) loses a
    far larger share of its energy over the same time than the fundamental,
    relative to the trapezoidal rule, each as the HHT oscillator does."""
    loss = {}
    for mode in (0, 2):
        periods_of_mode = 2.0 * (2 * mode + 1)      # two fundamental periods
        ref_sim, _, ref = vibrate_mode("hht", mode, periods_of_mode, alpha=0.0)
        sim, period, damped = vibrate_mode("hht", mode, periods_of_mode, alpha=-0.1)
        loss[mode] = 1.0 - (damped[-1] / damped[0]) / (ref[-1] / ref[0])
        predicted = 1.0 - hht_oscillator_energy(2.0 * np.pi / period * DT, -0.1, sim.step_index)
        assert abs(loss[mode] / predicted - 1.0) < 0.2, (mode, loss[mode], predicted)
        ref_sim.solver.destroy()
        sim.solver.destroy()
    assert loss[2] > 10.0 * loss[0]


@pytest.mark.parametrize("shape", ["gimp", "bspline"])
def test_hht_runs_with_every_shape_function(shape):
    sim, _, energy = vibrate_mode("hht", 0, 1.0, alpha=-0.1, shape=shape)
    assert energy[-1] < energy[0] and energy[-1] > 0.8 * energy[0]
    sim.solver.destroy()


@pytest.mark.parametrize("time,message", [
    ({"integrator": "newmark", "alpha": -0.1}, "time.alpha = -0.1: expected to be given only with time.integrator: hht"),
    ({"integrator": "hht", "alpha": -0.5}, "time.alpha = -0.5: expected a number in [-0.333333, 0]"),
    ({"integrator": "hht", "alpha": 0.1}, "time.alpha = 0.1: expected a number in [-0.333333, 0]"),
    ({"integrator": "hht", "alpha": "abc"}, "time.alpha = 'abc': expected a number in [-0.333333, 0]"),
    ({"integrator": "hht", "alpha": -0.1, "formulation": "momentum", "cfl": 0.5},
     "time.cfl = 0.5: expected to be given only with time.integrator: explicit"),
])
def test_hht_alpha_is_validated(time, message):
    from pimpm.config import ConfigError
    with pytest.raises(ConfigError) as err:
        validate({**_bar_raw(), "time": {"dt": DT, "end_time": 1.0, **time}})
    assert message in str(err.value)


def test_hht_alpha_takes_a_rounded_minus_one_third_as_minus_one_third():
    cfg = validate({**_bar_raw(), "time": {"integrator": "hht", "dt": DT, "end_time": 1.0,
                                           "alpha": -0.33333333333334}})
    assert cfg["time"]["alpha"] == -1.0 / 3.0
    assert "alpha" not in validate({**_bar_raw(), "time": {"dt": DT, "end_time": 1.0}})["time"]
