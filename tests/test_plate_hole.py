"""The plate with a circular hole of inputs/plate_with_hole.yaml, seeded from
the Gmsh mesh inputs/plate_with_hole.msh (issue 12; docs/VALIDATION.md,
"Plate with a hole"): the peak hoop stress against Heywood's stress
concentration factor within 5%, on 1 and 2 ranks alike; and a meshed box
under uniform tension keeps the exact stress resultant (GIMP domains of
mesh particles end on the grid's faces)."""
import os
import sys

import numpy as np
import pytest
import yaml

from helpers import MPIEXEC, ROOT

sys.path.insert(0, os.path.join(ROOT, "scripts"))
import plate_hole_validation as ph  # noqa: E402

pytestmark = pytest.mark.skipif(MPIEXEC is None, reason="mpiexec not found")


@pytest.mark.slow
def test_peak_hoop_stress_matches_heywood(tmp_path):
    """10 cells per hole radius (half the shipped resolution; measured
    Kt 3.142 there, 3.131 at the shipped 20 and 3.144 at 40, Heywood 3.140)."""
    one, two = (ph.run(10, n, str(tmp_path / str(n))) for n in (1, 2))
    assert abs(two["difference"]) < 0.05, two
    assert two["kt"] > two["largest_particle"] > 2.5          # the edge is between the particles and the hole
    assert one["kt"] == pytest.approx(two["kt"], rel=1e-8)
    assert one["particles"] == two["particles"]


def test_a_meshed_box_in_tension_carries_the_load(tmp_path):
    """sum_p V_p sigma_p = sum_I x_I (x) f_I holds only if the shape functions
    are complete at every particle: mesh particles whose GIMP domain would
    cross a symmetry face used to lose part of theirs (their domains now
    start clipped to the grid, pimpm/seeding.py) (the resultant came
    out 5% low on this box, 12-15% on the plate)."""
    import petsc4py
    petsc4py.init([])
    from pimpm.analysis import run_to_end
    from pimpm.config import validate
    meshio = pytest.importorskip("meshio")
    # a box [0, 2] x [0, 4] of right triangles, 0.1 apart, not aligned with the 0.125 cells
    n = (20, 40)
    xs, ys = np.meshgrid(np.linspace(0, 2, n[0] + 1), np.linspace(0, 4, n[1] + 1), indexing="ij")
    points = np.c_[xs.ravel(), ys.ravel(), np.zeros(xs.size)]
    index = np.arange(xs.size).reshape(xs.shape)
    a, b, c, d = index[:-1, :-1].ravel(), index[1:, :-1].ravel(), index[1:, 1:].ravel(), index[:-1, 1:].ravel()
    triangles = np.r_[np.c_[a, b, c], np.c_[a, c, d]]
    meshio.write_points_cells(str(tmp_path / "box.vtu"), points, [("triangle", triangles)])
    with open(os.path.join(ROOT, "inputs", "plate_with_hole.yaml")) as f:
        raw = yaml.safe_load(f)
    raw["grid"].update(upper=[2.25, 4.25], cells=[18, 34])
    raw["bodies"][0]["geometry"] = {"type": "mesh", "file": str(tmp_path / "box.vtu"), "particles_per_element": 2}
    raw["output"] = {"directory": str(tmp_path / "out")}
    sim, stats, status = run_to_end(validate(raw))
    assert status == 0, stats.failure
    p = sim.particles
    volume = p["volume0"] * np.linalg.det(p["F"])
    mean = np.sum(volume * p["stress"].reshape(len(volume), 3, 3)[:, 1, 1]) / np.sum(volume)
    # the exact discrete identity (Newton converged to 1e-8): the traction's share
    # times the loaded particles' height, over the volume
    expected = np.sum(p["load_pull"] * 1.0e4 * p["x"][:, 1]) / np.sum(volume)
    assert mean == pytest.approx(expected, rel=1e-6)
    assert mean == pytest.approx(1.0e4, rel=0.01)
