"""``python -m pimpm.plot OUTDIR``: the figures of a run's history.csv.

On a short, coarse billet on 2 ranks: four PNGs that are not blank; the
force-displacement panel picks the axis a body moves along; a history that
cannot be plotted is one error line and exit status 2."""
import os
import subprocess
import sys

import numpy as np
import pytest

from helpers import MPIEXEC, ROOT, run_pimpm
from test_cli import show

from pimpm.plot import FIGURES, PlotError, force_displacement_pairs, read_history

BILLET = os.path.join(ROOT, "inputs", "billet.yaml")


def plot_command(*args, cwd):
    return subprocess.run([sys.executable, "-m", "pimpm.plot", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, PYTHONPATH=ROOT))


@pytest.fixture(scope="module")
def billet(tmp_path_factory):
    directory = tmp_path_factory.mktemp("plot")
    proc = run_pimpm(2 if MPIEXEC else None,
                     [BILLET, "--output", "billet", "--set", "grid.cells=[40,21]",
                      "--set", "time.end_time=0.03"], cwd=directory, timeout=300)
    assert proc.returncode == 0, show(proc)
    return directory


def test_plot_writes_the_figures_of_the_billet(billet):
    import matplotlib.image
    proc = plot_command("billet", cwd=billet)
    assert proc.returncode == 0, show(proc)
    paths = sorted(proc.stdout.split())
    assert paths == sorted(os.path.join("billet", "plots", name) for name in FIGURES)
    for name in FIGURES:
        path = billet / "billet" / "plots" / name
        assert path.stat().st_size > 10_000, name
        image = matplotlib.image.imread(path)
        assert image.shape[0] > 300 and image.shape[1] > 400, name
        # not blank: many distinct colours (axes, text, curves)
        colours = np.unique(image.reshape(-1, image.shape[-1]), axis=0)
        assert len(colours) > 50, name
    assert not [n for n in os.listdir(billet / "billet" / "plots") if n not in FIGURES]


def test_plot_into_another_directory(billet, tmp_path):
    proc = plot_command(str(billet / "billet"), "--into", str(tmp_path / "figs"), cwd=tmp_path)
    assert proc.returncode == 0, show(proc)
    assert sorted(os.listdir(tmp_path / "figs")) == sorted(FIGURES)


def test_force_displacement_axis_is_the_one_the_platen_moves_along(billet):
    columns, data = read_history(billet / "billet" / "history.csv")
    pairs = force_displacement_pairs(columns, data)
    assert [(name, axis) for name, axis, _, _ in pairs] == [("platen", "y")]
    _, _, u, f = pairs[0]
    assert u == data["platen_displacement_y"] and f == data["platen_force_y"]
    assert u[-1] < 0 and f[-1] < 0  # compressed


def test_loads_and_bodies_with_underscores_in_their_names(tmp_path):
    path = tmp_path / "history.csv"
    path.write_text("step,time,dt,tip_load_force_x,tip_load_force_y,tip_load_displacement_x,"
                    "tip_load_displacement_y,wall_force_x,wall_force_y,wall_displacement_x,"
                    "wall_displacement_y\n"
                    "1,0.1,0.1,0,-5,0.01,-0.5,3,0,0,0\n"
                    "2,0.2,0.1,0,-10,0.02,-1.0,6,1,0,0\n")
    columns, data = read_history(path)
    pairs = force_displacement_pairs(columns, data)
    # the load moves most along y; the wall does not move: the axis of its largest force
    assert [(n, a) for n, a, _, _ in pairs] == [("tip_load", "y"), ("wall", "x")]


@pytest.mark.parametrize("text, wanted", [
    (None, "not found"),
    ("", "no header"),
    ("step,time,dt\n", "no steps yet"),
    ("step,time,dt\n1,0.1\n", "history.csv:2: 2 values: expected 3"),
    ("step,time,dt\n1,0.1,abc\n", "history.csv:2"),
])
def test_history_that_cannot_be_plotted(tmp_path, text, wanted):
    if text is not None:
        (tmp_path / "history.csv").write_text(text)
    with pytest.raises(PlotError, match=wanted.replace(".", r"\.")):
        read_history(tmp_path / "history.csv")
    proc = plot_command(str(tmp_path), cwd=tmp_path)
    assert proc.returncode == 2, show(proc)
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pimpm.plot: error:") and wanted in lines[0]
    assert "Traceback" not in proc.stderr and not (tmp_path / "plots").exists()
