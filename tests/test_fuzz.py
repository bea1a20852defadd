"""A property-based fuzzer of the input (issue 32), with Hypothesis: every
key the schema knows (pimpm.config.schema's key tuples, so that keys added
later are fuzzed without a new case) and every key of several shipped
inputs gets wrong types, extreme and non-finite numbers, huge integers,
control characters, empty and oversized containers; ``--set`` gets random
text. The contract: validation either accepts the input or raises one
ConfigError whose message is one line (the CLI prints it and exits 2,
nothing written: tests/test_cli.py); any other exception is an escape.

The default run is derandomized (the same cases in CI every time) and
takes a few seconds; ``PIMPM_FUZZ_EXAMPLES=20000 pytest -m slow tests/test_fuzz.py``
runs that many random cases of each kind. How many
cases each kind gets is in docs/RELIABILITY.md."""
import copy
import math
import os

import pytest
import yaml

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from helpers import ROOT  # noqa: E402
from pimpm.config import ConfigError, apply_overrides, validate  # noqa: E402
from pimpm.config import schema  # noqa: E402

# meshio warns about the corrupted meshes it is given
pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")

#: inputs whose keys are fuzzed: plain elastic, plastic, frictional contact, a mesh
#: body, loads and functions, explicit
BASES = ["bar_tension.yaml", "bar_plastic.yaml", "block_on_incline.yaml", "plate_with_hole.yaml",
         "cantilever.yaml", "billet_explicit.yaml", "upsetting_3d.yaml"]


def _load(name):
    with open(os.path.join(ROOT, "inputs", name)) as f:
        raw = yaml.safe_load(f)
    raw.pop("output", None)
    return raw


RAW = {name: _load(name) for name in BASES}


def _paths(node, prefix=()):
    """Every key path (tuples of keys and list indices) in a raw input."""
    out = []
    if isinstance(node, dict):
        for k, v in node.items():
            out.append(prefix + (k,))
            out += _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out.append(prefix + (i,))
            out += _paths(v, prefix + (i,))
    return out


def _schema_paths(raw):
    """The schema's keys placed where they belong in ``raw`` (present or not)."""
    out = [(k,) for k in schema.TOP_KEYS]
    out += [("grid", k) for k in schema.GRID_KEYS] + [("time", k) for k in schema.TIME_KEYS]
    out += [("solver", k) for k in schema.SOLVER_KEYS] + [("parallel", k) for k in schema.PARALLEL_KEYS]
    out += [("solver", "convergence", k) for k in schema.CONVERGENCE_KEYS]
    out += [("output", k) for k in schema.OUTPUT_KEYS]
    for name in raw.get("materials", {}):
        out += [("materials", name, k) for k in schema.MATERIAL_KEYS]
    for i, body in enumerate(raw.get("bodies", [])):
        out += [("bodies", i, k) for k in schema.BODY_KEYS]
        kind = body.get("geometry", {}).get("type") if isinstance(body.get("geometry"), dict) else None
        out += [("bodies", i, "geometry", k) for k in schema.GEOMETRY_KEYS.get(kind, ())]
    return out


CASES = sorted({(name, path) for name, raw in RAW.items() for path in _paths(raw) + _schema_paths(raw)},
               key=repr)

#: values of every kind: wrong types, extremes, non-finite, huge, odd strings, containers
scalars = st.one_of(
    st.none(), st.booleans(),
    st.integers(min_value=-10**30, max_value=10**30), st.sampled_from([10**400, -10**400, 2**63, -2**63 - 1]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 5e-324, 1e-300, 1e308, -1e308, math.nan, math.inf, -math.inf]),
    st.text(max_size=20), st.sampled_from(["", " ", "\n", "a\x00b", "é" * 5, "x" * 5000, "nan", "-1", "[1,2]"]))
values = st.recursive(scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=8), inner, max_size=3)), max_leaves=8)
values = st.one_of(values, st.sampled_from([[], {}, [[]], [0.0] * 2000, {"x": {}}]))


def _set(raw, path, value):
    node = raw
    for key in path[:-1]:
        node = node[key] if not isinstance(node, dict) else node.setdefault(key, {})
        if not isinstance(node, (dict, list)):
            return False
    last = path[-1]
    if isinstance(node, dict):
        node[last] = value
    elif isinstance(node, list) and isinstance(last, int) and last < len(node):
        node[last] = value
    else:
        return False
    return True


def _contract(call):
    try:
        call()
    except ConfigError as err:
        message = str(err)
        assert message and "\n" not in message, message
        assert "Traceback" not in message


def _fuzz_keys(data):
    name, path = data.draw(st.sampled_from(CASES), label="key")
    raw = copy.deepcopy(RAW[name])
    value = data.draw(values, label="value")
    if not _set(raw, path, value):
        return
    _contract(lambda: validate(raw, base_dir=os.path.join(ROOT, "inputs")))


def _fuzz_set(data):
    name = data.draw(st.sampled_from(BASES), label="input")
    raw = copy.deepcopy(RAW[name])
    path = data.draw(st.sampled_from([p for n, p in CASES if n == name]), label="key")
    key = "".join((f"[{k}]" if isinstance(k, int) else (f".{k}" if i else str(k))) for i, k in enumerate(path))
    text = data.draw(st.one_of(st.text(max_size=40), st.sampled_from(
        ["&a [*a]", "[" * 100 + "]" * 100, "{a: 1, a: 2}", "!!python/object:os.system x", "1e999", "0x10",
         ".nan", "~", "'", "[1, 2", "{<<: {a: 1}}"])), label="value")

    def call():
        apply_overrides(raw, [f"{key}={text}"])
        validate(raw, base_dir=os.path.join(ROOT, "inputs"))
    _contract(call)


QUICK = settings(max_examples=400, derandomize=True, deadline=None, database=None,
                 suppress_health_check=list(HealthCheck))
#: the long run: PIMPM_FUZZ_EXAMPLES=20000 pytest -m slow -k fuzz tests/test_fuzz.py (random cases each time)
LONG_EXAMPLES = int(os.environ.get("PIMPM_FUZZ_EXAMPLES", "0"))
LONG = settings(max_examples=max(LONG_EXAMPLES, 1), deadline=None, database=None,
                suppress_health_check=list(HealthCheck))
long_run = pytest.mark.skipif(LONG_EXAMPLES <= 0, reason="set PIMPM_FUZZ_EXAMPLES for the long run")


@QUICK
@given(st.data())
def test_fuzzed_input_keys_are_accepted_or_one_clear_error(data):
    _fuzz_keys(data)


@QUICK
@given(st.data())
def test_fuzzed_set_overrides_are_accepted_or_one_clear_error(data):
    _fuzz_set(data)


@pytest.mark.slow
@long_run
@LONG
@given(st.data())
def test_fuzzed_input_keys_long_run(data):
    _fuzz_keys(data)


@pytest.mark.slow
@long_run
@LONG
@given(st.data())
def test_fuzzed_set_overrides_long_run(data):
    _fuzz_set(data)


def test_the_fuzzer_reaches_every_schema_key():
    keys = {p[-1] for _, p in CASES}
    for group in (schema.TOP_KEYS, schema.GRID_KEYS, schema.TIME_KEYS, schema.SOLVER_KEYS, schema.MATERIAL_KEYS,
                  schema.BODY_KEYS, schema.OUTPUT_KEYS, schema.PARALLEL_KEYS, schema.CONVERGENCE_KEYS):
        assert set(group) <= keys, set(group) - keys


def _pimpm_options():
    """Every -pimpm_* option named in pimpm's sources (new ones are fuzzed
    without a new case)."""
    import re
    names = set()
    package = os.path.join(ROOT, "pimpm")
    for folder, _, files in os.walk(package):
        for f in files:
            if f.endswith(".py"):
                with open(os.path.join(folder, f)) as fh:
                    names |= set(re.findall(r"\"(pimpm_[a-z_]*[a-z])\"", fh.read()))
    return sorted(names - {schema.DEFAULT_OUTPUT_DIRECTORY})


OPTIONS = _pimpm_options()
option_values = st.one_of(st.text(max_size=20), st.sampled_from(
    ["", "nan", "inf", "-inf", "-1", "0", "1e400", "true", "false", "yes", "maybe", "mumps", "gmres-gamg",
     "matrix-free", "petsc", "guilkey_weiss", "shell", "1e-300", "2.5", "x" * 300]))


def _fuzz_options(data):
    import petsc4py
    petsc4py.init([])
    from petsc4py import PETSc
    from pimpm import presets
    from pimpm.options import with_command_line
    name = data.draw(st.sampled_from(OPTIONS), label="option")
    text = data.draw(option_values, label="value")
    config = validate(copy.deepcopy(RAW[data.draw(st.sampled_from(BASES), label="input")]),
                      base_dir=os.path.join(ROOT, "inputs"))
    db = PETSc.Options()
    db.setValue(name, text)
    try:
        try:
            effective = with_command_line(config)
            presets.resolve(effective["solver"], {name: text}, symmetric=data.draw(st.booleans()),
                            dim=config["dim"], assembles_on_pattern=True, coo=True, asymmetry="a test")
        except ValueError as err:
            message = str(err)
            assert message and "\n" not in message and f"-{name}" in message, message
    finally:
        db.delValue(name)


@QUICK
@given(st.data())
def test_fuzzed_pimpm_options_are_accepted_or_one_clear_error(data):
    _fuzz_options(data)


@pytest.mark.slow
@long_run
@LONG
@given(st.data())
def test_fuzzed_pimpm_options_long_run(data):
    _fuzz_options(data)


#: the files the shipped inputs read (a particle cloud, a Gmsh mesh) and an
#: HDF5 particle file made here: corrupted by truncation, flipped bytes and
#: inserted garbage
FILE_BASES = {"block_on_incline.yaml": "block_on_incline.csv", "plate_with_hole.yaml": "plate_with_hole.msh"}


def _hdf5_particles(path):
    import h5py
    import numpy as np
    with h5py.File(path, "w") as f:
        f["position"] = np.random.default_rng(0).random((20, 2)) * 0.3 + 0.4
        f["volume"] = np.full(20, 0.0045)


def _fuzz_files(data, tmp_dir):
    name = data.draw(st.sampled_from(sorted(FILE_BASES) + ["h5"]), label="input")
    if name == "h5":
        raw = copy.deepcopy(RAW["bar_tension.yaml"])
        source = os.path.join(tmp_dir, "particles.h5")
        _hdf5_particles(source)
        raw["bodies"][0]["geometry"] = {"type": "particles", "file": "particles.h5"}
    else:
        raw = copy.deepcopy(RAW[name]) if name in RAW else _load(name)
        source = os.path.join(ROOT, "inputs", FILE_BASES[name])
        for body in raw["bodies"]:
            if isinstance(body.get("geometry"), dict) and "file" in body["geometry"]:
                body["geometry"]["file"] = os.path.basename(source)
    with open(source, "rb") as f:
        content = bytearray(f.read())
    how = data.draw(st.sampled_from(["truncate", "flip", "insert", "empty"]), label="corruption")
    at = data.draw(st.integers(0, max(len(content) - 1, 0)), label="at")
    if how == "truncate":
        content = content[:at]
    elif how == "flip":
        for k in range(data.draw(st.integers(1, 16), label="bytes")):
            i = (at + 97 * k) % max(len(content), 1)
            content[i] = data.draw(st.integers(0, 255))
    elif how == "insert":
        content[at:at] = data.draw(st.binary(min_size=1, max_size=64), label="garbage")
    else:
        content = bytearray()
    target = os.path.join(tmp_dir, os.path.basename(source))
    with open(target, "wb") as f:
        f.write(bytes(content))
    _contract(lambda: validate(raw, base_dir=tmp_dir))


FILES_QUICK = settings(max_examples=150, derandomize=True, deadline=None, database=None,
                       suppress_health_check=list(HealthCheck))


@FILES_QUICK
@given(data=st.data())
def test_fuzzed_particle_and_mesh_files_are_accepted_or_one_clear_error(data, tmp_path_factory):
    _fuzz_files(data, str(tmp_path_factory.mktemp("files")))


@pytest.mark.slow
@long_run
@LONG
@given(data=st.data())
def test_fuzzed_particle_and_mesh_files_long_run(data, tmp_path_factory):
    _fuzz_files(data, str(tmp_path_factory.mktemp("files")))
