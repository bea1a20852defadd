"""Velocity and momentum formulations (Sulsky & Kaul 3.2.1).

The case Sulsky & Kaul describe: a material point crosses into a cell close
to the cell boundary, so the node across gets a tiny mass m_p N_ip while the
gradient of N_ip, and so the internal force, stays finite. Dividing that
force by the tiny mass (velocity formulation) gives a huge nodal velocity;
the momentum formulation multiplies by N_ip before dividing (eq. 3.2.5-3.2.7)
and remaps the velocity that strains the particles.

Here a stress-free elastic disk translates across the grid, so every step
some particles enter new cells and the exact answer is a rigid translation
with zero stress. Explicitly, the velocity formulation (update-stress-last
from v + dt f/m, ``usl``) amplifies round-off at the tiny-mass nodes (whose
own explicit stability limit ~ sqrt(m_i / k_i) vanishes with the mass) until
particles fly apart or invert; the explicit momentum formulation (``musl``:
eq. 3.2.5-3.2.7 with the lumped mass) keeps the disk intact. The implicit
step is unconditionally stable, so both implicit formulations keep it exact,
including steps that leave particles exactly on cell faces.
"""
import numpy as np
import petsc4py
petsc4py.init([])
import pytest
from mpi4py import MPI

from pimpm.analysis import Analysis
from pimpm.config import validate
from pimpm.simulation import Simulation
from pimpm.step_control import TimeStepControl

VELOCITY = np.array([0.01, 0.006])
E = 1000.0


def translating_disk(time):
    return validate({
        # linear shape functions, as in Sulsky & Kaul's case (with GIMP the
        # weights change smoothly across cell faces and USL does not tear it)
        "grid": {"lower": [0, 0], "upper": [1, 1], "cells": [10, 10], "shape_functions": "linear"},
        "materials": {"e": {"model": "neo_hookean", "youngs_modulus": E, "poisson_ratio": 0.3,
                            "density": 1000.0}},
        "bodies": [{"name": "disk", "material": "e", "particles_per_cell": 2,
                    "velocity": VELOCITY.tolist(),
                    "geometry": {"type": "ball", "center": [0.3, 0.3], "radius": 0.2}}],
        "time": {"end_time": 20.0, **time},
        # exact zero stress is asked of the converged step: Newton to round-off
        # (pimpm's default rtol 1e-8 leaves stresses of ~5e-8 E)
        "solver": {"petsc": {"snes_rtol": 1e-13}},
    })


def translate(sim, until, dt=None):
    """Advance to ``until`` with pimpm's loop, at the step of the input (dt)
    or the CFL step (explicit), no step cut; returns (failure message or
    None, max |stress|, max deviation of any particle from the rigid
    translation)."""
    p = sim.particles
    start = dict(zip(p["id"].tolist(), p["x"]))
    time = dict(sim.config["time"], end_time=until, max_cuts=0)
    assert dt is None or dt == time["dt"]
    analysis = Analysis(sim, control=TimeStepControl(time))
    analysis.run()
    failure = analysis.failure
    p = sim.particles
    x0 = np.array([start[i] for i in p["id"].tolist()])
    deviation = np.max(np.abs(p["x"] - x0 - VELOCITY * sim.time))
    return failure, np.max(np.abs(p["stress"])), deviation


def test_explicit_velocity_formulation_tears_the_disk_apart_momentum_keeps_it():
    velocity_form = Simulation(translating_disk({"integrator": "explicit", "stress_update": "usl"}),
                               MPI.COMM_WORLD)
    failure, stress, deviation = translate(velocity_form, 15.0)
    # it breaks after particles cross their first cell faces (about t = 4)
    assert failure is not None or stress > 1e-2 * E or deviation > 0.01, (failure, stress, deviation)

    momentum_form = Simulation(translating_disk({"integrator": "explicit", "stress_update": "musl"}),
                               MPI.COMM_WORLD)
    failure, stress, deviation = translate(momentum_form, 15.0)
    assert failure is None
    assert momentum_form.step_index > 300          # 1.5 cells of travel in about 350 steps
    assert stress < 1e-12 * E and deviation < 1e-12
    v = momentum_form.particles["v"]
    np.testing.assert_allclose(v, np.broadcast_to(VELOCITY, v.shape), rtol=0, atol=1e-14)


@pytest.mark.parametrize("formulation", ["velocity", "momentum"])
def test_implicit_translation_stays_rigid_in_both_formulations(formulation):
    """dt = 0.5 moves the particle lattice (spacing h/2) by exactly h/2 in x
    every 5 steps, so particles sit exactly on cell faces: the node across
    such a face has zero mass but full stiffness and must stay free (fixing
    it at zero used to strain the particle by ~5%)."""
    sim = Simulation(translating_disk({"integrator": "newmark", "dt": 0.5,
                                       "formulation": formulation}), MPI.COMM_WORLD)
    failure, stress, deviation = translate(sim, 15.0, dt=0.5)
    assert failure is None and sim.step_index == 30
    assert stress < 1e-9 * E and deviation < 1e-10
    sim.solver.destroy()
