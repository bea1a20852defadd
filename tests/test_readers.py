"""The output opens in the readers users have: meshio's XDMF time-series
reader, and (when ``pvbatch`` is installed) ParaView's three XDMF readers
(Xdmf3ReaderS, Xdmf3ReaderT, the legacy XDMFReader), with the particles as
cells, the particle id as GlobalIds and a Threshold on ``body`` that keeps
the bar's particles. A 3-step bar on 2 ranks."""
import json
import os
import shutil
import subprocess
import time

import h5py
import numpy as np
import pytest

from helpers import MPIEXEC, ROOT, run_pimpm, write_yaml
from test_cli import bar, show

STEPS = 3


@pytest.fixture(scope="module")
def bar_output(tmp_path_factory):
    directory = tmp_path_factory.mktemp("readers")
    write_yaml(directory / "bar.yaml", bar(directory="out", end_time=STEPS * 1.034))
    proc = run_pimpm(2 if MPIEXEC else None, ["bar.yaml"], cwd=directory, timeout=120)
    assert proc.returncode == 0, show(proc)
    out = directory / "out"
    with h5py.File(out / "results.h5", "r") as f:
        steps = sorted(f["steps"].keys())
        expected = {name: dict(time=float(f["steps"][name].attrs["time"]),
                               position=f["steps"][name]["particles/position"][...],
                               id=f["steps"][name]["particles/id"][...],
                               body=f["steps"][name]["particles/body"][...])
                    for name in steps}
        nodes = [int(n) for n in f.attrs["nodes"]]
    return out, [expected[s] for s in steps], nodes


def test_meshio_reads_the_particle_time_series(bar_output):
    import meshio
    out, steps, _ = bar_output
    assert len(steps) == STEPS + 1
    with meshio.xdmf.TimeSeriesReader(str(out / "particles.xdmf")) as reader:
        points, cells = reader.read_points_cells()
        n = len(steps[0]["id"])
        assert points.shape == (n, 3)
        assert len(cells) == 1 and cells[0].type == "vertex"
        assert np.array_equal(np.asarray(cells[0].data).ravel(), np.arange(n))
        assert reader.num_steps == len(steps)
        for k, want in enumerate(steps):
            t, point_data, _ = reader.read_data(k)
            assert t == want["time"]
            assert np.array_equal(point_data["position"], want["position"])
            assert np.array_equal(point_data["id"], want["id"])
            assert np.array_equal(point_data["body"], want["body"])


def _display():
    """A DISPLAY for pvbatch (ParaView 5.11 aborts without an X server):
    the caller's, or a private Xvfb. Returns (env, process to stop)."""
    env = dict(os.environ)
    if env.get("DISPLAY"):
        return env, None
    if shutil.which("Xvfb") is None:
        pytest.skip("pvbatch needs an X server: no DISPLAY and no Xvfb")
    number = 90 + os.getpid() % 100
    xvfb = subprocess.Popen(["Xvfb", f":{number}", "-screen", "0", "640x480x24", "-noreset"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    time.sleep(1.0)
    env["DISPLAY"] = f":{number}"
    return env, xvfb


@pytest.fixture(scope="module")
def paraview(bar_output):
    if shutil.which("pvbatch") is None:
        pytest.skip("pvbatch not installed (apt-get install paraview)")
    out, _, _ = bar_output
    env, xvfb = _display()
    try:
        results = {}
        for name, by in (("particles.xdmf", "body"), ("grid.xdmf", None)):
            cmd = ["pvbatch", os.path.join(ROOT, "tests", "pv", "open_xdmf.py"),
                   str(out / name)] + ([by] if by else [])
            proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)
            lines = [l for l in proc.stdout.splitlines() if l.startswith("RESULT ")]
            assert proc.returncode == 0 and lines, show(proc)
            results[name] = json.loads(lines[-1][len("RESULT "):])
        return results
    finally:
        if xvfb is not None:
            xvfb.terminate()
            xvfb.wait()


def test_paraview_readers_see_particles_as_cells(paraview, bar_output):
    _, steps, _ = bar_output
    n = len(steps[0]["id"])
    in_bar = int((steps[-1]["body"] == 0).sum())
    assert 0 < in_bar < n
    for reader, got in paraview["particles.xdmf"].items():
        assert got["points"] == n and got["cells"] == n, (reader, got)
        assert got["steps"] == len(steps) and got["last_time"] == pytest.approx(steps[-1]["time"])
        assert got["global_ids"] == "id", (reader, got)
        assert got["threshold_cells"] == in_bar, (reader, got)
        assert {"position", "stress", "velocity", "body", "id"} <= set(got["arrays"])


def test_paraview_readers_see_the_grid(paraview, bar_output):
    _, steps, nodes = bar_output
    for reader, got in paraview["grid.xdmf"].items():
        assert got["points"] == int(np.prod(nodes)), (reader, got)
        assert got["cells"] == int(np.prod([n - 1 for n in nodes])), (reader, got)
        assert got["steps"] == len(steps)
        assert {"mass", "velocity"} <= set(got["arrays"])
