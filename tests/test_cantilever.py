"""The cantilever of inputs/cantilever.yaml (issue 12; docs/VALIDATION.md,
"Cantilever"), run as a user runs it (the CLI with --set), through the
functions of scripts/cantilever_validation.py that make the documented
tables: a small end load against Timoshenko beam theory at the shipped 8
cells per depth (and closer at finer cells), the large load to k = P L^2 /
(E I) = 10 against Reissner's extensible, shear-deformable beam and the
inextensible elastica, and 1 rank = 2 ranks."""
import os
import sys

import numpy as np
import pytest

from helpers import MPIEXEC, ROOT

sys.path.insert(0, os.path.join(ROOT, "scripts"))
import cantilever_validation as cv  # noqa: E402

pytestmark = pytest.mark.skipif(MPIEXEC is None, reason="mpiexec not found")


def test_small_load_matches_timoshenko_within_2_percent_and_converges(tmp_path):
    coarse, shipped = (cv.small_load(n, 1, str(tmp_path)) for n in (4, 8))
    assert abs(shipped["error"]) < 0.02            # measured -0.83% (4 cells: -1.85%, 16: -0.46%)
    assert abs(shipped["error"]) < 0.6 * abs(coarse["error"])
    # the shear term is resolved: bending alone would be further from the answer at 8 cells
    assert abs(shipped["deflection"] - shipped["timoshenko"]) < abs(shipped["deflection"] - shipped["bending_only"]) \
        or abs(shipped["error"]) < 0.01


@pytest.mark.slow
def test_large_load_follows_the_reissner_beam_to_k_10(tmp_path):
    """4 cells per depth (the shipped input at half its resolution): within
    1.5% of Reissner's beam at every k (measured at most +0.9% vertical,
    +1.6% horizontal at 8 cells; the coarse run is closer by cancellation),
    and more flexible than the inextensible elastica by about what Reissner's
    axial and shear flexibility add (1.5% at k = 10)."""
    result = cv.large_load(4, 1, str(tmp_path))
    rows = result["rows"]
    assert [r["k"] for r in rows] == list(range(1, 11))
    for r in rows:
        assert abs(r["vertical_vs_reissner"]) < 0.015, r
        assert abs(r["horizontal_vs_reissner"]) < 0.03, r
    last = rows[-1]
    assert last["vertical"] > last["elastica_tip"][0]
    assert last["reissner"][0] / last["elastica_tip"][0] - 1.0 == pytest.approx(0.0147, abs=0.001)


def test_cantilever_same_on_1_and_2_ranks(tmp_path):
    histories = [cv.run(4, n, False, str(tmp_path), extra=["time.end_time=0.2"])[0] for n in (1, 2)]
    assert len(histories[0]) == len(histories[1])
    for column in ("tip_displacement_x", "tip_displacement_y", "tip_force_y"):
        np.testing.assert_allclose(histories[1][column], histories[0][column], rtol=1e-8, atol=1e-12)
