"""The memory a run is estimated to need (pimpm/resources.py) against what
it uses: the nodes the material reaches, counted as the footprints reach
them, and the start-up estimate within 20% of the run's peak resident
memory, which the run's last line prints beside it."""
import os
import re

import numpy as np
import pytest
from mpi4py import MPI

from pimpm import resources
from pimpm.config import load_config
from pimpm.errors import SetupError
from pimpm.simulation import Simulation

from helpers import run_pimpm

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

UNITS = {"kB": 2**10, "MB": 2**20, "GB": 2**30, "TB": 2**40}


def _bytes(number, unit):
    return float(number) * UNITS[unit]


def memory_line(stdout):
    """(peak, estimate) in bytes from a run's ``pimpm: memory`` line."""
    line = [ln for ln in stdout.splitlines() if ln.startswith("pimpm: memory")][-1]
    m = re.search(r"peak ([\d.]+) (kB|MB|GB|TB) resident.*estimated ([\d.]+) (kB|MB|GB|TB)", line)
    assert m, line
    return _bytes(*m.group(1, 2)), _bytes(*m.group(3, 4))


@pytest.mark.parametrize("path", ["inputs/billet.yaml", "inputs/upsetting_3d.yaml"])
def test_reached_nodes_are_the_footprints_nodes(path, monkeypatch):
    """The count the tangent's and the factors' estimate rest on is the
    number of distinct nodes with a nonzero weight in some material
    particle's footprint (evaluated in chunks: the chunk made small here)."""
    monkeypatch.setattr(resources, "FOOTPRINT_CHUNK", 1000)
    sim = Simulation(load_config(f"{REPO}/{path}"), MPI.COMM_SELF)
    node_index, S, _ = sim.footprint()
    expected = np.unique(node_index[S > 0.0]).size
    assert len(sim.particles) > 1000
    assert resources.reached_nodes(sim) == expected


def test_a_run_that_cannot_fit_is_refused_before_it_starts(monkeypatch):
    """A run whose estimate exceeds the memory available is refused when it
    is set up, before any output, naming the key to change: the solver when
    the direct solver's factors are what does not fit (with the iterative
    preset to try), else the grid."""
    config = load_config(f"{REPO}/inputs/upsetting_3d.yaml")
    config["grid"]["cells"] = [24, 24, 18]
    sim = Simulation(config, MPI.COMM_SELF)
    need, parts = sim.memory_estimate, sim.memory_parts
    factors = parts["direct solver's factors"] * (1.0 + resources.DEFORMATION_GROWTH)
    assert need == pytest.approx(sum(parts.values())) and factors > 0.0
    for have, key in ((need - 0.5 * factors, "solver.preset = 'mumps'"),
                      (0.95 * (need - factors), "grid.cells = [24, 24, 18]")):
        monkeypatch.setattr(resources, "available_memory", lambda: have)
        assert resources.check(config, 1, 32) is None          # the bound before allocation passes
        with pytest.raises(SetupError) as err:
            Simulation(config, MPI.COMM_SELF)
        message = str(err.value)
        assert message.startswith(key + ": expected a run that fits in memory"), message
        assert ("gmres-gamg" in message) == key.startswith("solver"), message


def test_factor_estimate_grows_with_the_unknowns_and_the_ranks():
    for dim in (2, 3):
        small, large = (resources.factor_bytes(n, dim, 2) for n in (1000, 10000))
        assert 5 * small < large < 20 * small
        assert resources.factor_bytes(10000, dim, 1) < large < resources.factor_bytes(10000, dim, 4)
    # a 3D factorization grows faster than a 2D one of the same size
    assert resources.factor_bytes(30000, 3, 2) > 5 * resources.factor_bytes(30000, 2, 2)


@pytest.mark.mpi
@pytest.mark.parametrize("ranks, args", [
    (1, ["inputs/billet.yaml", "--set", "time.end_time=0.05"]),
    (2, ["inputs/billet.yaml", "--set", "time.end_time=0.05"]),
    (2, ["inputs/billet_explicit.yaml", "--set", "time.end_time=2e-4"]),
    (2, ["inputs/upsetting_3d.yaml", "--set", "time.end_time=3e-3"]),
], ids=["billet-1", "billet-2", "explicit-2", "upsetting3d-2"])
def test_start_up_estimate_is_within_20_percent_of_the_peak(tmp_path, ranks, args):
    """Issue 31: the memory estimate printed at start-up (the summary's
    ``memory`` line) is within 20% of the run's peak resident memory (all
    ranks), as the run's last line reports them."""
    proc = run_pimpm(ranks, [f"{REPO}/{args[0]}"] + args[1:] + ["--output", str(tmp_path / "out")],
                     cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    peak, estimate = memory_line(proc.stdout)
    assert 0.8 <= estimate / peak <= 1.2, (estimate, peak)
