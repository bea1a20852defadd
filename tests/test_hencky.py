"""Hencky's logarithmic-strain hyperelasticity (pimpm/materials/hencky.py):
exact in uniaxial strain, sigma = E ln(lambda) / lambda with nu = 0, at the
material point and in whole runs (implicit quasi-static on 1 and 2 ranks,
at two resolutions and two step sizes; explicit: the small-strain wave
speed). The tangent is checked against finite differences of the energy
with the other hyperelastic models in tests/test_materials.py and against
its numpy reference in tests/test_kernels.py."""
import numpy as np
import petsc4py
import pytest

petsc4py.init([])
from mpi4py import MPI  # noqa: E402

from helpers import run_on_ranks  # noqa: E402
from pimpm.config import validate  # noqa: E402
from pimpm.materials import make_material  # noqa: E402
from pimpm.simulation import Simulation  # noqa: E402
from reference.compiled import Compiled  # noqa: E402
from test_explicit import bar_config, vibrate  # noqa: E402

E = 2.0e6


def uniaxial(stretch):
    """sigma_11 of Hencky's model in uniaxial strain with nu = 0: tau = E ln(lambda), J = lambda."""
    return E * np.log(stretch) / stretch


def test_uniaxial_strain_is_exact_at_the_material_point():
    m = Compiled(make_material({"model": "hencky", "youngs_modulus": E, "poisson_ratio": 0.0, "density": 1.0}))
    stretches = np.array([0.3, 0.5, 0.8, 0.999, 1.0, 1.001, 1.3, 2.0, 4.0])
    F = np.zeros((len(stretches), 3, 3))
    F[:, 0, 0], F[:, 1, 1], F[:, 2, 2] = stretches, 1.0, 1.0
    sigma = m.stress(F)
    assert np.allclose(sigma[:, 0, 0], uniaxial(stretches), rtol=1e-13, atol=1e-9 * E)
    sigma[:, 0, 0] = 0.0
    assert np.max(np.abs(sigma)) <= 1e-12 * E
    # the energy: E/2 ln(lambda)^2
    assert np.allclose(m.strain_energy(F), 0.5 * E * np.log(stretches) ** 2, rtol=1e-13, atol=1e-20 * E)


def uniaxial_raw(cells_y, dt, steps, rate=1.0):
    """A 2 x 2 block filling a grid with roller walls on x = 0, x = 2 and
    y = 0, its top face moving down at ``rate``: uniaxial strain in y with
    nu = 0 (no lateral stress). The face's nodes stay at y = 2 (the grid is
    reset every step), so after n steps the stretch is exactly
    (1 - rate dt / 2)^n (tests/test_physics.py). Linear shape functions are
    exact while every cell keeps its particles (one cell in y: always; two:
    while the top moves less than a sixth of a cell, the patch test)."""
    return {
        "grid": {"lower": [0.0, 0.0], "upper": [2.0, 2.0], "cells": [2, cells_y], "shape_functions": "linear",
                 "boundary": {"xmin": "roller", "xmax": "roller", "ymin": "roller",
                              "ymax": {"velocity": {"y": -rate}}}},
        "materials": {"m": {"model": "hencky", "youngs_modulus": E, "poisson_ratio": 0.0, "density": 10.0}},
        "bodies": [{"name": "block", "material": "m", "particles_per_cell": 3,
                    "geometry": {"type": "box", "lower": [0.0, 0.0], "upper": [2.0, 2.0]}}],
        "time": {"integrator": "quasi_static", "dt": dt, "end_time": dt * steps},
        "output": {"directory": "out", "every": 1000},
    }


def uniaxial_block(cells_y, dt, steps, rate=1.0):
    return validate(uniaxial_raw(cells_y, dt, steps, rate))


@pytest.mark.parametrize("cells_y,dt,steps,rate", [(1, 0.2, 5, 1.0), (1, 0.1, 10, 1.0), (1, 0.1, 10, -0.35),
                                                   (2, 0.05, 8, 0.4), (2, 0.025, 16, 0.4)])
def test_uniaxial_strain_block_has_the_exact_stress(cells_y, dt, steps, rate):
    """To 1e-10 of the stress at every particle, whatever h and dt: large
    compression (to 0.59) and tension (to 1.19) on one cell, 8% on two."""
    config = uniaxial_block(cells_y, dt, steps, rate)
    sim = Simulation(config, MPI.COMM_WORLD)
    for _ in range(steps):
        sim.advance(dt)
    stretch = (1.0 - rate * dt / 2.0) ** steps
    sigma = sim.particles["stress"]
    exact = uniaxial(stretch)
    assert abs(np.log(stretch)) > (0.15 if cells_y == 1 else 0.075)
    assert np.max(np.abs(sigma[:, 1, 1] - exact)) < 1e-10 * abs(exact)
    assert np.max(np.abs(sigma[:, 0, 0])) < 1e-10 * abs(exact)
    assert np.allclose(sim.particles["F"], np.diag([1.0, stretch, 1.0]), rtol=0, atol=1e-12)
    sim.solver.destroy()


def test_uniaxial_strain_block_on_one_and_two_ranks(tmp_path):
    raw = uniaxial_raw(1, 0.2, 5)
    (one, _, h1), (two, _, h2) = run_on_ranks(tmp_path, raw, [1, 2])
    exact = uniaxial((1.0 - 0.2 / 2.0) ** 5)
    for particles in (one, two):
        stress = particles["stress"].reshape(-1, 3, 3)
        assert np.max(np.abs(stress[:, 1, 1] - exact)) < 1e-10 * abs(exact)
    assert np.allclose(h1["strain_energy"], h2["strain_energy"], rtol=1e-12)
    # the stored energy: E/2 ln(lambda)^2 per unit reference volume, 4 of it
    assert h1["strain_energy"][-1] == pytest.approx(4.0 * 0.5 * E * np.log((1.0 - 0.1) ** 5) ** 2, rel=1e-10)


def test_explicit_bar_of_hencky_material_vibrates_at_the_small_strain_frequency():
    config = bar_config("explicit")
    config["materials"]["m"] = make_material_spec = dict(config["materials"]["m"], model="hencky")
    assert make_material(make_material_spec).name == "hencky"
    sim, period, measured, energy = vibrate(config, 3)
    assert len(measured) >= 2 and np.all(np.abs(measured - period) < 0.01 * period)
    assert energy.max() < 1.05 * energy[0] and energy.min() > 0.9 * energy[0]
