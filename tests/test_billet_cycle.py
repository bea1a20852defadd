"""The load cycle of inputs/billet_cycle.yaml (issue 12; docs/VALIDATION.md,
"Billet load cycle"): the hyperelastic billet compressed to 20% and brought
back with a time function returns to its initial shape, and the platen's
force-displacement loop closes, the more so the smaller the step. Run as a
user runs it (the CLI with --set), at 1 cm cells (half the shipped
resolution), through scripts/billet_cycle_validation.py, which makes the
documented table."""
import os
import sys

import numpy as np
import pytest

from helpers import MPIEXEC, ROOT

sys.path.insert(0, os.path.join(ROOT, "scripts"))
import billet_cycle_validation as bc  # noqa: E402

pytestmark = pytest.mark.skipif(MPIEXEC is None, reason="mpiexec not found")
COARSE = (40, 21)                       # 1 cm cells


@pytest.fixture(scope="module")
def cycles(tmp_path_factory):
    work = str(tmp_path_factory.mktemp("cycle"))
    return {dt: bc.run(dt, 2, work, COARSE) for dt in (0.01, 0.005)}


def test_the_platen_returns_exactly_and_the_billet_returns_to_its_shape(cycles):
    for r in cycles.values():
        assert abs(r["final_platen_position"]) < 1e-12       # the exact integral of the function
        assert r["residual_max"] < 0.02 and r["residual_rms"] < 0.005, r
        assert r["final_force"] < 0.01 and r["final_strain_energy"] < 0.005, r
        assert r["loop_gap"] < 0.03 and abs(r["net_work"]) < 0.02, r


def test_the_residual_shrinks_with_the_step(cycles):
    coarse, fine = cycles[0.01], cycles[0.005]
    assert fine["residual_rms"] < 0.8 * coarse["residual_rms"], (coarse, fine)
    assert fine["loop_gap"] < coarse["loop_gap"], (coarse, fine)


def test_the_cycle_is_the_same_on_1_and_2_ranks(tmp_path, cycles):
    one = bc.run(0.01, 1, str(tmp_path), COARSE)
    two = cycles[0.01]
    for key in ("residual_max", "residual_rms", "final_force", "loop_gap", "net_work", "peak_force"):
        assert one[key] == pytest.approx(two[key], rel=1e-6, abs=1e-10), key
    assert one["steps"] == two["steps"] and one["newton"] == two["newton"]
