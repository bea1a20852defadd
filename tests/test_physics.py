"""Physics verification against analytic solutions (serial, in process):
the compression patch test and Sulsky & Kaul's bar in tension.

Kinematics of a rigid body in MPM: it prescribes the velocity of the grid
nodes it touches, and those nodes stay at fixed points in space (the grid is
reset every step). A platen that moves a distance d per step towards a
symmetry plane at distance H therefore applies a per-step stretch of
1 - d/H to the material in between, whatever the material's current extent:
after n steps the exact homogeneous deformation is (1 - d/H)^n, which tends
to exp(-v t / H) for small steps (an Eulerian velocity gradient v/H). The
analytic solutions below use that stretch.
"""
import os

import numpy as np
import petsc4py
petsc4py.init([])
from mpi4py import MPI

from helpers import ROOT
from pimpm.config import load_config, validate
from reference.materials import make_reference as make_material
from pimpm.simulation import Simulation


def stress_free_stretch(material, F_of, component):
    """The stretch lam with sigma[component, component] = 0 for F = F_of(lam)
    (scalar Newton with a finite-difference slope on the material model
    itself), and the stress there."""
    def s(lam):
        return material.stress(F_of(lam)[None])[0][component, component]
    lam = 1.0
    for _ in range(60):
        step = s(lam) / ((s(lam + 1e-7) - s(lam - 1e-7)) / 2e-7)
        lam -= step
        if abs(step) < 1e-15:
            break
    return lam, material.stress(F_of(lam)[None])[0]


def homogeneous_plane_strain(material, stretch, axis, free_axis):
    """Cauchy stress for F = diag(l0, l1, 1) with F[axis] = stretch and the
    other in-plane stretch chosen so that sigma[free_axis] = 0."""
    def F_of(lam):
        F = np.eye(3)
        F[axis, axis] = stretch
        F[free_axis, free_axis] = lam
        return F
    lam, sigma = stress_free_stretch(material, F_of, free_axis)
    return sigma, lam


def equal_lateral_stretch(material, F_of):
    """The lateral stretch lam with sigma_00(F_of(lam)) = 0, and the stress there."""
    return stress_free_stretch(material, F_of, 0)


def run(sim, steps, dt):
    info = None
    for _ in range(steps):
        info = sim.advance(dt)
    return info


def patch_config(model, shape="linear"):
    # with GIMP the platen's particle domains touch nodes within half a
    # particle spacing, so it starts half a cell higher to keep touching only
    # the top row of the block
    platen_bottom = 2.0 if shape == "linear" else 2.25
    return validate({
        "grid": {"lower": [0.0, 0.0], "upper": [3.0, 3.0], "cells": [6, 6], "shape_functions": shape,
                 "boundary": {"xmin": "roller", "ymin": "roller"}},
        "materials": {"m": {"model": model, "shear_modulus": 6.0e6, "bulk_modulus": 6.0e7,
                            "density": 10.0}},
        "bodies": [
            {"name": "block", "material": "m", "particles_per_cell": 3,
             "geometry": {"type": "box", "lower": [0.0, 0.0], "upper": [2.0, 2.0]}},
            # frictionless platen: imposes only the normal (y) velocity
            {"name": "platen", "rigid": True, "particles_per_cell": 2, "constrain": ["y"],
             "velocity": [0.0, -2.5],
             "geometry": {"type": "box", "lower": [0.0, platen_bottom],
                          "upper": [3.0, platen_bottom + 0.5]}},
        ],
        "time": {"integrator": "quasi_static", "dt": 0.01, "end_time": 0.04},
    })


def test_patch_test_uniform_compression_has_analytic_stress():
    """A block between a frictionless platen and two symmetry planes,
    compressed 5% in 4 steps: every particle carries the analytic stress of
    homogeneous plane-strain compression, and the platen force equals
    sigma_yy times the current width."""
    for model, shape in (("neo_hookean", "linear"), ("neo_hookean_compressible", "linear")):
        # (GIMP integrates the stress over the particle domains exactly, so once
        # the block's top surface lies between node rows while the platen
        # prescribes the row above it, the discrete solution is not
        # homogeneous: GIMP is checked on the vibrating bar instead)
        config = patch_config(model, shape)
        sim = Simulation(config, MPI.COMM_WORLD)
        info = run(sim, 4, 0.01)
        stretch = (1.0 - 0.01 * 2.5 / 2.0) ** 4
        material = make_material(config["materials"]["m"])
        exact, lam_x = homogeneous_plane_strain(material, stretch, axis=1, free_axis=0)
        sigma = sim.particles["stress"]
        scale = abs(exact[1, 1])
        assert scale > 1e5
        assert np.max(np.abs(sigma - exact)) < 1e-8 * scale, (model, shape)
        F = sim.particles["F"]
        assert np.allclose(F, np.diag([lam_x, stretch, 1.0]), rtol=0, atol=1e-10)
        force = info["forces"]["platen"]
        # the platen pushes down (sampling of the boundary by particles makes
        # the force only approximately sigma_yy times the width)
        assert force[1] < 0 and abs(force[1] - exact[1, 1] * 2.0 * lam_x) < 0.05 * abs(force[1])
        assert force[0] == 0.0


def test_bar_in_tension_matches_analytic_stress():
    """inputs/bar_tension.yaml (Sulsky & Kaul 3.1.1): uniform sigma_xx equal
    to the analytic uniaxial-stress value for the imposed elongation (within
    1%, the issue's bound; MPM reproduces it to round-off here)."""
    config = load_config(os.path.join(ROOT, "inputs", "bar_tension.yaml"))
    sim = Simulation(config, MPI.COMM_WORLD)
    t = config["time"]
    steps = int(round(t["end_time"] / t["dt"]))
    info = run(sim, steps, t["dt"])
    elongation = 0.001 * t["end_time"]
    material = make_material(config["materials"]["elastic"])
    # continuous-time analytic: velocity -v at x = 0.4, 0 at x = 0.7 -> F = exp(v t / L)
    continuous, _ = homogeneous_plane_strain(material, np.exp(elongation / 0.3), axis=0, free_axis=1)
    # the same with the 10 steps taken: F = (1 + v dt / L)^10
    exact, lam_y = homogeneous_plane_strain(material, (1.0 + 0.001 * t["dt"] / 0.3) ** steps,
                                            axis=0, free_axis=1)
    sigma_xx = sim.particles["stress"][:, 0, 0]
    assert np.max(np.abs(sigma_xx - continuous[0, 0])) < 0.01 * continuous[0, 0]
    assert np.max(np.abs(sigma_xx - exact[0, 0])) < 1e-8 * exact[0, 0]
    assert np.max(np.abs(sim.particles["stress"][:, 1, 1])) < 1e-8 * exact[0, 0]
    # small-strain plane-strain check of the order of magnitude: E/(1-nu^2) * strain
    assert abs(exact[0, 0] - 1000.0 / (1 - 0.09) * elongation / 0.3) < 0.03 * exact[0, 0]
    # the puller pulls left with about the bar's tension times its height
    # (within the particle sampling of the boundary cell row, ~3% here)
    force = info["forces"]["puller"]
    assert force[0] < 0 and abs(force[0] + exact[0, 0] * 0.3 * lam_y) < 0.05 * exact[0, 0] * 0.3
    assert force[1] == 0.0


def test_3d_patch_test_uniaxial_compression():
    """3D: a cube between a frictionless platen and three symmetry planes,
    compressed 5%: homogeneous uniaxial stress (sigma_xx = sigma_yy = 0) with
    the analytic sigma_zz on every particle."""
    config = validate({
        # linear shape functions: the platen sits on a cell line (with GIMP its
        # particle domains reach the cube's top nodes; see patch_config)
        "grid": {"lower": [0.0, 0.0, 0.0], "upper": [1.5, 1.5, 1.5], "cells": [6, 6, 6],
                 "shape_functions": "linear",
                 "boundary": {"xmin": "roller", "ymin": "roller", "zmin": "roller"}},
        "materials": {"m": {"model": "neo_hookean", "youngs_modulus": 200.0, "poisson_ratio": 0.3,
                            "density": 1.0}},
        "bodies": [
            {"name": "cube", "material": "m", "particles_per_cell": 2,
             "geometry": {"type": "box", "lower": [0, 0, 0], "upper": [1.0, 1.0, 1.0]}},
            {"name": "platen", "rigid": True, "particles_per_cell": 2, "constrain": ["z"],
             "velocity": [0.0, 0.0, -1.25],
             "geometry": {"type": "box", "lower": [0, 0, 1.0], "upper": [1.5, 1.5, 1.25]}},
        ],
        "time": {"integrator": "quasi_static", "dt": 0.01, "end_time": 0.04},
    })
    sim = Simulation(config, MPI.COMM_WORLD)
    info = run(sim, 4, 0.01)
    stretch = (1.0 - 0.0125) ** 4
    material = make_material(config["materials"]["m"])

    lam, exact = equal_lateral_stretch(material, lambda lam: np.diag([lam, lam, stretch]))
    sigma = sim.particles["stress"]
    assert len(sigma) == 512
    assert abs(exact[2, 2]) > 5.0
    assert np.max(np.abs(sigma - exact)) < 1e-8 * abs(exact[2, 2])
    assert np.allclose(sim.particles["F"], np.diag([lam, lam, stretch]), rtol=0, atol=1e-10)
    assert info["forces"]["platen"][2] < 0


def test_elastic_plastic_bar_reproduces_sulsky_and_kaul():
    """inputs/bar_plastic.yaml (Sulsky & Kaul 3.1.2, plane stress, small-strain
    J2, E = 1000, yield 6, hardening 5000, 8% strain): uniform uniaxial stress
    6 + E H / (E + H) (0.08 - 6 / E) = 67.67, within 2% of the paper's 68.5;
    zero out-of-plane stress (plane stress) and non-negative plastic work."""
    config = load_config(os.path.join(ROOT, "inputs", "bar_plastic.yaml"))
    sim = Simulation(config, MPI.COMM_WORLD)
    t = config["time"]
    run(sim, int(round(t["end_time"] / t["dt"])), t["dt"])
    sigma = sim.particles["stress"]
    E, H, tau0 = 1000.0, 5000.0, 6.0
    exact = tau0 + E * H / (E + H) * (0.08 - tau0 / E)
    assert np.max(np.abs(sigma[:, 0, 0] - exact)) < 1e-8 * exact
    assert abs(sigma[:, 0, 0].mean() - 68.5) < 0.02 * 68.5
    assert np.max(np.abs(sigma[:, 2, 2])) < 1e-9 * exact          # plane stress
    assert np.max(np.abs(sigma[:, 1, 1])) < 1e-9 * exact          # uniaxial
    assert np.all(sim.particles["h_plastic_work"] > 0)
    # the thickness shrank (F33 < 1) and the volume follows it
    assert np.all(sim.particles["F"][:, 2, 2] < 1.0)


def test_axisymmetric_uniform_compression_matches_3d_and_analytic():
    """A cylinder (r-z model: axis and mid-plane rollers) compressed 5% by a
    frictionless platen: homogeneous uniaxial stress, the same as the 3D
    cube of test_3d_patch_test_uniaxial_compression and the analytic value
    (F = diag(lambda, lambda_z, lambda) with sigma_rr = sigma_thth = 0)."""
    config = validate({
        "kinematics": "axisymmetric",
        "grid": {"lower": [0.0, 0.0], "upper": [1.5, 1.5], "cells": [6, 6],
                 "shape_functions": "linear",          # as the 3D cube
                 "boundary": {"xmin": "roller", "ymin": "roller"}},
        "materials": {"m": {"model": "neo_hookean", "youngs_modulus": 200.0, "poisson_ratio": 0.3,
                            "density": 1.0}},
        "bodies": [
            {"name": "cylinder", "material": "m", "particles_per_cell": 2,
             "geometry": {"type": "box", "lower": [0, 0], "upper": [1.0, 1.0]}},
            {"name": "platen", "rigid": True, "particles_per_cell": 2, "constrain": ["y"],
             "velocity": [0.0, -1.25],
             "geometry": {"type": "box", "lower": [0, 1.0], "upper": [1.5, 1.25]}},
        ],
        "time": {"integrator": "quasi_static", "dt": 0.01, "end_time": 0.04},
    })
    sim = Simulation(config, MPI.COMM_WORLD)
    run(sim, 4, 0.01)
    stretch = (1.0 - 0.0125) ** 4
    material = make_material(config["materials"]["m"])

    lam, exact = equal_lateral_stretch(material, lambda lam: np.diag([lam, stretch, lam]))
    sigma = sim.particles["stress"]
    assert abs(exact[1, 1]) > 5.0
    assert np.max(np.abs(sigma - exact)) < 1e-8 * abs(exact[1, 1])
    assert np.allclose(sim.particles["F"], np.diag([lam, stretch, lam]), rtol=0, atol=1e-10)
    # the volume of a particle is its area times 2 pi r
    p = sim.particles
    assert np.allclose(p["volume0"], (0.25**2 / 4) * 2 * np.pi * p["x0"][:, 0])
    # the same as the 3D cube (sigma_zz of the 3D test is sigma_yy here)
    exact_3d = material.stress(np.diag([lam, lam, stretch])[None])[0]
    assert abs(exact_3d[2, 2] - sigma[0, 1, 1]) < 1e-8 * abs(exact_3d[2, 2])


def test_upsetting_reaches_60_percent_axisymmetric():
    """inputs/upsetting.yaml (Sulsky & Kaul 3.2.7, 1 mm cells, the tied
    platen): 60% height reduction with dt ~2900x the explicit step; the
    radius at mid-height is within 3% of the paper's ~16.5 mm and the final
    load within 7% of the converged one (837 kN at 0.25 mm cells,
    docs/VALIDATION.md; measured 849 kN, +1.4%; the 1 mm load moves by 7%
    with the path; the paper: about 1050 kN on their 1 mm mesh, whose platen
    holds the nodes as pimpm's bonded one does, "converging toward about 800
    kN"); plastic work is non-negative everywhere. With the run's step
    control (one step is cut at this resolution)."""
    from pimpm.analysis import Observer, run_to_end

    class Last(Observer):
        def step(self, analysis, info):
            self.info = info

    config = load_config(os.path.join(ROOT, "inputs", "upsetting.yaml"))
    dt = config["time"]["dt"]
    last = Last()
    sim, stats, status = run_to_end(config, observers=[last])
    assert status == 0 and stats.failure is None and stats.cuts <= 2
    assert dt > 1000 * sim.stable_time_step() / config["time"]["cfl"]
    info = last.info
    p = sim.particles
    assert abs(sim.time - 9.0e-3) < 1e-12
    assert abs(sim.rigid["x"][:, 1].min() - (15.0 + 0.25 - 9.0)) < 1e-9      # platen travelled 9 mm
    radius = p["x"][p["x"][:, 1] < 1.0, 0].max()
    assert abs(radius - 16.5) < 0.03 * 16.5
    force = -info["forces"]["platen"][1] / 1000.0
    assert abs(force - 837.0) < 0.07 * 837.0
    assert np.all(p["h_plastic_work"] >= 0.0) and p["h_eq_plastic_strain"].max() > 1.0


def test_upsetting_3d_quarter_cylinder_on_2_ranks(tmp_path):
    """inputs/upsetting_3d.yaml (GIMP, the tied platen) on 2 ranks reaches
    60% reduction (steps of ~2900x the explicit one, some cut) with a bulge
    like the axisymmetric model's at the same 2 mm resolution (16.53 mm;
    measured 17.05 mm: the largest particle radius, which on the 3D lattice
    starts nearer the surface)."""
    from helpers import MPIEXEC, last_particles, run_pimpm
    if MPIEXEC is None:
        import pytest
        pytest.skip("mpiexec not found")
    proc = run_pimpm(2, [os.path.join(ROOT, "inputs", "upsetting_3d.yaml")], cwd=tmp_path, timeout=600)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    particles, time = last_particles(tmp_path / "upsetting_3d_output" / "results.h5")
    assert abs(time - 9.0e-3) < 1e-12
    x = particles["position"][particles["body"] == 0]
    radius = np.sqrt(x[:, 0] ** 2 + x[:, 1] ** 2)[x[:, 2] < 1.5].max()
    assert abs(radius - 16.53) < 0.05 * 16.53
    assert abs(x[:, 2].max() - 6.0) < 0.3


def test_explicit_axisymmetric_upsetting_matches_implicit():
    """The explicit axisymmetric step (hoop stretch 1 + dt v_r / r, hoop force
    sigma_thth N_i / r) against the quasi-static implicit one on the first
    0.1 mm of inputs/upsetting.yaml at 2 mm cells: the platen is slow
    compared with the wave speed, so both give the same load and bulge."""
    import copy
    from helpers import coarse_upsetting
    raw = coarse_upsetting()
    results = {}
    for integrator in ("explicit", "quasi_static"):
        cfg = copy.deepcopy(raw)
        cfg["time"] = {"integrator": integrator, "end_time": 1.0e-4}
        if integrator == "quasi_static":
            cfg["time"]["dt"] = 2.5e-5
        sim = Simulation(validate(cfg), MPI.COMM_WORLD)
        while sim.time < 1.0e-4 - 1e-15:
            info = sim.advance(sim.stable_time_step() if integrator == "explicit" else 2.5e-5)
        results[integrator] = (-info["forces"]["platen"][1], sim.particles["x"][:, 0].max(), sim)
    (f_ex, r_ex, explicit), (f_im, r_im, _) = results["explicit"], results["quasi_static"]
    assert explicit.step_index > 300 and explicit.particles["h_eq_plastic_strain"].max() > 0.0
    assert f_im > 5.0e4                                      # yielding, ~100 kN
    assert abs(f_ex - f_im) < 0.02 * f_im
    assert abs(r_ex - r_im) < 1e-3
