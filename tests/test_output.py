"""Tests for pimpm.io.ResultWriter (HDF5 + XDMF result files).

The parallel cases run tests/mpi/output_check.py under mpiexec with 1, 2 and 3 ranks
(3 ranks oversubscribe the 2-core machines); the script checks every written value.
The serial cases call the writer in this process (comm = COMM_WORLD of size 1, so
the plain serial h5py file is used).
"""
import importlib.util
import os
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
CHECK = os.path.join(HERE, "mpi", "output_check.py")
MPIEXEC = shutil.which("mpiexec")


def _mpi_env():
    env = dict(os.environ)
    env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    return env


@pytest.mark.skipif(MPIEXEC is None, reason="mpiexec not found")
@pytest.mark.parametrize("nranks", [1, 2, 3])
def test_output_under_mpiexec(nranks, tmp_path):
    cmd = [MPIEXEC, "-n", str(nranks)]
    if nranks > 2:
        cmd.append("--oversubscribe")
    cmd += [sys.executable, CHECK, str(tmp_path)]
    try:
        proc = subprocess.run(cmd, env=_mpi_env(), capture_output=True, text=True, timeout=120)
    except subprocess.TimeoutExpired as exc:
        pytest.fail("output_check hung with %d ranks:\n%s\n%s" % (nranks, exc.stdout, exc.stderr))
    assert proc.returncode == 0, "rc=%d\nstdout:\n%s\nstderr:\n%s" % (
        proc.returncode, proc.stdout, proc.stderr)
    assert "output_check OK (%d ranks)" % nranks in proc.stdout


# ---------------------------------------------------------------- serial, in process
@pytest.fixture(scope="module")
def comm():
    MPI = pytest.importorskip("mpi4py.MPI")
    c = MPI.COMM_WORLD
    if c.Get_size() != 1:
        pytest.skip("serial tests need a communicator of size 1")
    return c


@pytest.fixture(scope="module")
def check_module():
    spec = importlib.util.spec_from_file_location("output_check", CHECK)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_serial_roundtrip(comm, check_module, tmp_path):
    """Same write-and-verify as under mpiexec, with the serial h5py fallback."""
    assert check_module.run(comm, str(tmp_path)) == []


def _grid(nodes, k=0.0):
    I, J = np.meshgrid(np.arange(nodes[0]), np.arange(nodes[1]), indexing="ij")
    return {"mass": I + 10.0 * J + k, "velocity": np.stack([I, J], axis=-1) * 1.0}


def _particles(n, dim=2, start=0):
    ids = np.arange(start, start + n, dtype=np.int64)
    return {"position": np.tile(ids[:, None], (1, dim)) * 0.1, "id": ids}


def _xdmf_times(path):
    root = ET.parse(path).getroot()
    return [float(g.find("Time").get("Value")) for g in root.find("Domain/Grid").findall("Grid")]


def test_serial_zero_particles_append_and_overwrite(comm, tmp_path):
    import h5py
    from pimpm.io import ResultWriter

    nodes = (4, 3)
    box = ((0, 0), nodes)
    w = ResultWriter(comm, str(tmp_path), 2, (0.0, 0.0), (1.0, 1.0), nodes)
    # a step with no particles at all: stored (shape (0, 3)), left out of particles.xdmf
    w.write_step(0, 0.0, {"position": np.zeros((0, 2)), "id": np.zeros(0, np.int64)},
                 _grid(nodes), box)
    assert not (tmp_path / "particles.xdmf").exists()
    assert _xdmf_times(tmp_path / "grid.xdmf") == [0.0]
    w.write_step(1, 0.5, _particles(3), _grid(nodes, 1.0), box)
    assert _xdmf_times(tmp_path / "particles.xdmf") == [0.5]
    assert _xdmf_times(tmp_path / "grid.xdmf") == [0.0, 0.5]
    w.close()
    w.close()  # idempotent

    with h5py.File(tmp_path / "results.h5", "r") as f:
        assert f["steps/000000/particles/position"].shape == (0, 3)
        assert f["steps/000001/particles/position"].shape == (3, 3)
        np.testing.assert_array_equal(f["steps/000001/grid/mass"][...], _grid(nodes, 1.0)["mass"].T)

    # restart: append mode keeps steps 0 and 1, rewriting step 1 replaces it
    with ResultWriter(comm, str(tmp_path), 2, (0.0, 0.0), (1.0, 1.0), nodes, append=True) as w:
        assert _xdmf_times(tmp_path / "grid.xdmf") == [0.0, 0.5]  # untouched until a write
        w.write_step(1, 0.5, _particles(5), _grid(nodes, 2.0), box)
        w.write_step(2, 1.0, _particles(2, start=10), _grid(nodes, 3.0), box)
    assert _xdmf_times(tmp_path / "grid.xdmf") == [0.0, 0.5, 1.0]
    assert _xdmf_times(tmp_path / "particles.xdmf") == [0.5, 1.0]
    root = ET.parse(tmp_path / "particles.xdmf").getroot()
    counts = [int(g.find("Topology").get("NumberOfElements"))
              for g in root.find("Domain/Grid").findall("Grid")]
    assert counts == [5, 2]
    with h5py.File(tmp_path / "results.h5", "r") as f:
        assert sorted(f["steps"]) == ["000000", "000001", "000002"]
        np.testing.assert_array_equal(f["steps/000001/particles/id"][...], np.arange(5))
        np.testing.assert_array_equal(f["steps/000001/grid/mass"][...], _grid(nodes, 2.0)["mass"].T)
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".tmp")]
    with pytest.raises(ValueError, match="different grid"):
        ResultWriter(comm, str(tmp_path), 2, (0.0, 0.0), (1.0, 1.0), (5, 3), append=True)


def test_serial_xdmf_is_built_once_per_step_and_follows_a_rewritten_step(comm, tmp_path):
    """The XDMF files keep each step's XML (pimpm.io.xdmf.XdmfFiles): a step
    written again within the same run (a retried step) shows its new
    particles, and the files equal what a fresh writer makes of results.h5."""
    from pimpm.io import ResultWriter

    nodes = (4, 3)
    box = ((0, 0), nodes)
    with ResultWriter(comm, str(tmp_path), 2, (0.0, 0.0), (1.0, 1.0), nodes) as w:
        for step in range(3):
            w.write_step(step, 0.5 * step, _particles(3), _grid(nodes, 1.0), box)
        w.write_step(2, 1.0, _particles(4), _grid(nodes, 2.0), box)
        kept = (tmp_path / "particles.xdmf").read_text(), (tmp_path / "grid.xdmf").read_text()
    root = ET.parse(tmp_path / "particles.xdmf").getroot()
    assert [int(g.find("Topology").get("NumberOfElements"))
            for g in root.find("Domain/Grid").findall("Grid")] == [3, 3, 4]
    with ResultWriter(comm, str(tmp_path), 2, (0.0, 0.0), (1.0, 1.0), nodes, append=True) as w:
        w.write_step(2, 1.0, _particles(4), _grid(nodes, 2.0), box)       # rebuilt from the file
    assert ((tmp_path / "particles.xdmf").read_text(), (tmp_path / "grid.xdmf").read_text()) == kept


@pytest.mark.parametrize("case", ["length", "no_position", "box_shape", "not_tiling", "dtype"])
def test_serial_bad_input_raises_and_writer_survives(comm, tmp_path, case):
    from pimpm.io import ResultWriter

    nodes = (4, 3)
    box = ((0, 0), nodes)
    particles, grid = _particles(4), _grid(nodes)
    if case == "length":
        particles["J"] = np.ones(3)
    elif case == "no_position":
        del particles["position"]
    elif case == "box_shape":
        grid["mass"] = np.zeros((3, 3))
    elif case == "not_tiling":
        box = ((0, 0), (3, 3))
        grid = {k: v[:3] for k, v in grid.items()}
    elif case == "dtype":
        particles["name"] = np.array(["a"] * 4)
    with ResultWriter(comm, str(tmp_path), 2, (0.0, 0.0), (1.0, 1.0), nodes) as w:
        with pytest.raises(ValueError):
            w.write_step(0, 0.0, particles, grid, box)
        # the failed call touched nothing: a good step still works
        w.write_step(0, 0.0, _particles(4), _grid(nodes), ((0, 0), nodes))
    assert _xdmf_times(tmp_path / "grid.xdmf") == [0.0]


def test_serial_3d_layout(comm, tmp_path):
    """3-D grid: x fastest in the file, per-node tensors padded to 9 components."""
    import h5py
    from pimpm.io import ResultWriter

    nodes = (3, 2, 4)
    I, J, K = np.meshgrid(*[np.arange(n) for n in nodes], indexing="ij")
    val = I + 10.0 * J + 100.0 * K
    with ResultWriter(comm, str(tmp_path), 3, (1.0, 2.0, 3.0), (0.1, 0.2, 0.3), nodes) as w:
        w.write_step(5, 2.5, {"position": np.ones((2, 3))},
                     {"m": val, "s": val[..., None, None] * np.ones((3, 3))},
                     ((0, 0, 0), nodes))
    with h5py.File(tmp_path / "results.h5", "r") as f:
        m = f["steps/000005/grid/m"][...]
        assert m.shape == (4, 2, 3)
        assert m[3, 1, 2] == val[2, 1, 3]
        assert f["steps/000005/grid/s"].shape == (4, 2, 3, 9)
    root = ET.parse(tmp_path / "grid.xdmf").getroot()
    g = root.find("Domain/Grid/Grid")
    assert g.find("Topology").get("Dimensions") == "4 2 3"
    origin, spacing = [d.text.split() for d in g.find("Geometry").findall("DataItem")]
    assert [float(x) for x in origin] == [3.0, 2.0, 1.0]
    assert [float(x) for x in spacing] == [0.3, 0.2, 0.1]
