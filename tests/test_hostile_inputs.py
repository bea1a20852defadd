"""Inputs that used to escape the input checks (issue 13's table; the
commands and messages are listed in docs/RELIABILITY.md): each gets one
clear message naming the key, raised before anything is allocated or
written. In-process here (the command line turns these errors into one
``pimpm: error:`` line and exit status 2: tests/test_cli.py checks that for
a few of them and for the ones only the command line sees)."""
import copy
import os

import numpy as np
import pytest
import yaml

import petsc4py

petsc4py.init([])
from mpi4py import MPI  # noqa: E402

from helpers import ROOT  # noqa: E402
from pimpm.config import ConfigError, load_config, validate  # noqa: E402
from pimpm.config.yaml_input import MAX_INPUT_BYTES  # noqa: E402
from pimpm.errors import SetupError  # noqa: E402
from pimpm.simulation import Simulation  # noqa: E402

with open(os.path.join(ROOT, "inputs", "bar_tension.yaml")) as _f:
    BAR = yaml.safe_load(_f)
BAR_TEXT = open(os.path.join(ROOT, "inputs", "bar_tension.yaml")).read()


def load_text(tmp_path, text, name="input.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return load_config(str(path))


def bomb(levels):
    """A billion-laughs alias bomb: each level an anchored list of 9 aliases
    of the level below."""
    lines = ["l0: &l0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    for i in range(1, levels + 1):
        lines.append(f"l{i}: &l{i} [" + ", ".join([f"*l{i - 1}"] * 9) + "]")
    return "\n".join(lines) + "\n"


YAML_CASES = {
    "self-referencing alias": ("title: &a [*a]\n", ["alias *a refers to the anchor it is inside of"]),
    "self-referencing alias under an unknown key": (BAR_TEXT + "extra: &x {k: *x}\n",
                                                    ["alias *x refers to the anchor"]),
    "self-referencing alias in cells": (BAR_TEXT.replace("cells:", "cells: &c [1, *c]\n  old_cells:", 1),
                                        ["alias *c refers to the anchor"]),
    "list nested 400 deep": ("title: " + "[" * 400 + "]" * 400 + "\n", ["nested more than 64 deep"]),
    "alias bomb of 9 levels": (bomb(9), ["values once aliases are expanded", "alias bomb"]),
    "alias bomb of 6 levels": (bomb(6), ["values once aliases are expanded"]),
}


@pytest.mark.parametrize("name", list(YAML_CASES))
def test_yaml_that_would_recurse_or_explode_is_refused_at_once(name, tmp_path):
    text, wanted = YAML_CASES[name]
    with pytest.raises(ConfigError) as err:
        load_text(tmp_path, text)
    assert all(w in str(err.value) for w in wanted), str(err.value)


def test_a_huge_input_file_is_refused_unread(tmp_path):
    path = tmp_path / "huge.yaml"
    with open(path, "wb") as f:             # 50 MB, sparse: nothing is read
        f.truncate(50 * 2**20)
    with pytest.raises(ConfigError) as err:
        load_config(str(path))
    assert f"at most {MAX_INPUT_BYTES} bytes" in str(err.value)


def test_a_fifo_or_a_device_is_not_read(tmp_path):
    fifo = tmp_path / "input.yaml"
    os.mkfifo(fifo)                          # opening it would block forever
    with pytest.raises(ConfigError) as err:
        load_config(str(fifo))
    assert "is a FIFO: expected a regular YAML input file" in str(err.value)
    with pytest.raises(ConfigError) as err:
        load_config("/dev/zero")
    assert "is a device" in str(err.value)


def edited(edit):
    raw = copy.deepcopy(BAR)
    edit(raw)
    return raw


MATERIAL = next(iter(BAR["materials"]))
VALUE_CASES = {
    "dt 1e-12 to end_time 1": (lambda r: r["time"].update(dt=1e-12, end_time=1.0),
                               ["time.end_time = 1.0", "at most 10,000,000 steps", "1e+12"]),
    "end_time 1e300": (lambda r: r["time"].update(end_time=1e300), ["time.end_time = 1e+300"]),
    "moduli 1e308": (lambda r: r["materials"][MATERIAL].update(youngs_modulus=1e308),
                     [f"materials.{MATERIAL}.youngs_modulus = 1e+308", "finite, normal number"]),
    "moduli 1e-300": (lambda r: r["materials"][MATERIAL].update(youngs_modulus=1e-300),
                      [f"materials.{MATERIAL}.youngs_modulus = 1e-300", "finite, normal number"]),
    # issue 32: the spacing, not the modulus, is what overflows here
    "grid 1e300 wide": (lambda r: r["grid"].update(upper=[1e300, 1e300]),
                        ["grid.upper = [1e+300, 1e+300]", "cell size h = 1.42857e+299", "units"]),
}


@pytest.mark.parametrize("name", list(VALUE_CASES))
def test_derived_quantities_that_overflow_are_refused(name):
    edit, wanted = VALUE_CASES[name]
    with pytest.raises(ConfigError) as err:
        validate(edited(edit))
    assert all(w in str(err.value) for w in wanted), str(err.value)


SIZE_CASES = {
    "a million cells per axis": (lambda r: r["grid"].update(cells=[1000000, 1000000]),
                                 ["grid.cells = [1000000, 1000000]", "PETSc's 32-bit indices"]),
    "30,000 cells per axis": (lambda r: r["grid"].update(cells=[30000, 30000]),
                              ["grid.cells = [30000, 30000]", "entries per rank", "32-bit"]),
    "3000 particles per cell": (lambda r: r["bodies"][0].update(particles_per_cell=3000),
                                ["bodies[0].particles_per_cell = [3000, 3000]", "fits in memory",
                                 "available"]),
}


@pytest.mark.parametrize("name", list(SIZE_CASES))
def test_problems_too_big_for_the_machine_are_refused_before_allocating(name):
    edit, wanted = SIZE_CASES[name]
    config = validate(edited(edit))
    with pytest.raises(SetupError) as err:
        Simulation(config, MPI.COMM_SELF)
    assert all(w in str(err.value) for w in wanted), str(err.value)


def test_overlapping_deformable_bodies_are_refused():
    with open(os.path.join(ROOT, "inputs", "colliding_disks.yaml")) as f:
        raw = yaml.safe_load(f)
    raw["bodies"][1]["geometry"]["center"] = [0.45, 0.45]
    with pytest.raises(SetupError) as err:
        Simulation(validate(raw), MPI.COMM_SELF)
    assert "bodies[1].geometry" in str(err.value) and "lie inside body 'lower_disk'" in str(err.value)
    # touching boxes do not overlap
    raw = copy.deepcopy(BAR)
    body = raw["bodies"][0]
    lower, upper = body["geometry"]["lower"], body["geometry"]["upper"]
    middle = 0.5 * (lower[0] + upper[0])
    left = dict(body, name="left", geometry={"type": "box", "lower": lower, "upper": [middle, upper[1]]})
    right = dict(body, name="right", geometry={"type": "box", "lower": [middle, lower[1]], "upper": upper})
    raw["bodies"][0:1] = [left, right]
    sim = Simulation(validate(raw), MPI.COMM_SELF)
    assert np.all(np.isin([0, 1], sim.particles["body"]))


def test_yaml_merge_keys_are_valid_input(tmp_path):
    """A mapping merged in with <<: *anchor and a key given beside it that
    overrides the merged one is valid YAML (issue 32: it was refused as a
    duplicated key); a key given twice beside a merge still is refused."""
    text = BAR_TEXT.replace(
        "  elastic: {model: neo_hookean, youngs_modulus: 1000.0, poisson_ratio: 0.3, density: 10.0}",
        "  base: &base {model: neo_hookean, youngs_modulus: 500.0, poisson_ratio: 0.3, density: 10.0}\n"
        "  elastic: {<<: *base, youngs_modulus: 1000.0}")
    assert "<<: *base" in text
    config = load_text(tmp_path, text)
    assert config["materials"]["elastic"]["youngs_modulus"] == 1000.0
    assert config["materials"]["elastic"]["density"] == 10.0
    with pytest.raises(ConfigError) as err:
        load_text(tmp_path, text.replace("{<<: *base, youngs_modulus: 1000.0}",
                                         "{<<: *base, youngs_modulus: 1000.0, youngs_modulus: 2.0}"),
                  name="twice.yaml")
    assert "materials.elastic.youngs_modulus is given twice" in str(err.value)


def _particle_file(path, kind):
    """An HDF5 particle file with one oddity (issue 32's escapes)."""
    import h5py
    with h5py.File(path, "w") as f:
        position = np.random.default_rng(0).random((20, 2)) * 0.3 + 0.4
        volume = np.full(20, 0.0045)
        if kind == "group":
            f.create_group("position")
        else:
            f["position"] = position
        if kind == "strings":
            f["volume"] = np.array([b"a"] * 20)
        elif kind == "dangling link":
            f["volume"] = h5py.SoftLink("/nowhere")
        elif kind == "compound":
            f["volume"] = np.zeros(20, dtype=[("a", "f8"), ("b", "i4")])
        elif kind == "absurd shape":
            f.create_dataset("volume", shape=(10**12,), dtype="f8")      # allocated late: a small file
        elif kind != "group":
            f["volume"] = volume
        if kind == "group":
            f["volume"] = volume


@pytest.mark.parametrize("kind,wanted", [("group", "group 'position'"), ("strings", "expected numbers"),
                                         ("dangling link", "not a readable HDF5 particle file"),
                                         ("compound", "expected numbers"), ("absurd shape", "shape (1000000000000,)")])
def test_odd_hdf5_particle_files_are_one_clear_error(tmp_path, kind, wanted):
    _particle_file(tmp_path / "particles.h5", kind)
    raw = edited(lambda r: r["bodies"][0].update(geometry={"type": "particles", "file": "particles.h5"}))
    with pytest.raises(ConfigError) as err:
        validate(raw, base_dir=str(tmp_path))
    message = str(err.value)
    assert "bodies[0].geometry" in message and wanted in message and "\n" not in message, message
