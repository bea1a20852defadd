"""The fuzzer of issue 32, end to end: whole runs of the command line.

* **Checkpoints.** A run's ``checkpoint.h5`` (the bar's, and with its puller
  a frictional contact tool) gets one of its attributes, one
  key of its JSON attributes or one of its datasets corrupted (deleted,
  replaced by a value of another type, a non-finite, negative or huge
  number, another shape, a row more or less) with ``checkpoint.sha256``
  made to match (as if a faulty writer had written it: what reads the
  file is fuzzed, not only the digest), or the file's bytes damaged (the
  digest's case); then ``--restart``. The items come from the checkpoint
  file itself, so a field or attribute added later is fuzzed with no new
  case.
* **Command lines.** pimpm's flags (with one dash and two), ``--set`` with
  the schema's keys and YAML traps, PETSc options from pimpm's own presets
  and ``-pimpm_*`` options with extreme values, in random order.

The contract (RELIABILITY.md): exit status 0, 1 or 2 (130/143 only for
signals, not sent here); no traceback; on status 2 exactly one
``pimpm: error:`` line and every file byte for byte as it was; on 0 or 1
the earlier results kept (the history's earlier rows unchanged).

Checkpoints are restarted in this process (``pimpm.__main__.main``: the
restart reads no PETSc option, and a restart in-process takes 0.1-0.3 s);
command lines run in a subprocess each (PETSc reads its options once per
process). ``PIMPM_FUZZ_EXAMPLES=N pytest -m slow tests/test_fuzz_runs.py``
runs N random cases of each kind."""
import contextlib
import io
import os
import shutil
import signal
import subprocess
import sys

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, event, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from helpers import ROOT, mpi_env  # noqa: E402

BAR = os.path.join(ROOT, "inputs", "bar_tension.yaml")
#: the runs whose checkpoints are fuzzed: the bar, and the bar pushed by its
#: puller as a frictional contact tool (its term's state and contact fields)
RUNS = {"bar": [BAR, "--set", "output.checkpoint_every=1"],
        "contact": [BAR, "--set", "output.checkpoint_every=1", "--set", "bodies[1].contact=friction",
                    "--set", "bodies[1].friction_coefficient=0.3", "--set", "bodies[1].constrain=null",
                    "--set", "bodies[1].velocity=[0.001, 0.0]"]}

from test_fuzz import LONG, long_run  # noqa: E402  (the long run's settings: PIMPM_FUZZ_EXAMPLES)

QUICK = settings(max_examples=200, derandomize=True, deadline=None, database=None,
                 suppress_health_check=list(HealthCheck))
CLI_QUICK = settings(QUICK, max_examples=12)


def _snapshot(directory):
    found = {}
    for root, dirs, files in os.walk(directory):
        for name in dirs + files:
            path = os.path.join(root, name)
            rel = os.path.relpath(path, directory)
            found[rel] = ("link", os.readlink(path)) if os.path.islink(path) else (
                open(path, "rb").read() if os.path.isfile(path) else "directory")
    return found


def _history_rows(directory):
    with open(os.path.join(directory, "history.csv")) as f:
        rows = [line.split(",") for line in f.read().splitlines()]
    wall = rows[0].index("wall_time")
    return [r[:wall] + r[wall + 1:] for r in rows]


def _check_contract(status, stderr, before, after, rows_before, rows_after):
    event(f"exit status {status}")
    assert status in (0, 1, 2), (status, stderr[-3000:])
    assert "Traceback" not in stderr, stderr[-3000:]
    if status == 2:
        errors = [line for line in stderr.splitlines() if line.startswith("pimpm: error:")]
        assert len(errors) == 1, stderr[-3000:]
        assert after == before, sorted(k for k in set(after) | set(before) if after.get(k) != before.get(k))
    else:
        assert rows_after[:len(rows_before)] == rows_before, stderr[-3000:]


@pytest.fixture(scope="module")
def checkpointed(tmp_path_factory):
    """Each of RUNS stopped after 5 of its 10 steps, a checkpoint of step 5: name -> directory."""
    out = {}
    for name, args in RUNS.items():
        base = tmp_path_factory.mktemp("checkpointed")
        proc = subprocess.run([sys.executable, "-m", "pimpm", *args, "--output", "o", "--set",
                               "time.end_time=5.17"],
                              cwd=base, env=mpi_env(), capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr[-2000:]
        out[name] = base / "o"
    return out


def _items(path):
    """Every attribute, JSON attribute key and dataset of the checkpoint."""
    import json

    import h5py
    items = []
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            for key in obj.attrs:
                items.append(("attribute", name, key))
            if isinstance(obj, h5py.Dataset):
                items.append(("dataset", name, None))
        for key, value in f.attrs.items():
            items.append(("attribute", "/", key))
            if isinstance(value, (str, bytes)):
                try:
                    parsed = json.loads(value)
                except ValueError:
                    continue
                if isinstance(parsed, dict):       # its keys, and their keys (a term's state)
                    items.extend(("json", key, (k,)) for k in parsed)
                    items.extend(("json", key, (k, k2)) for k, v in parsed.items() if isinstance(v, dict)
                                 for k2 in v)
        f.visititems(visit)
    return items


SCALARS = st.one_of(st.sampled_from([float("nan"), float("inf"), -float("inf"), -1, 0, -1e300, 1e300,
                                     2**63 - 1, -2**63, 0.5, "garbage", "", "{}", "[]", "null"]),
                    st.integers(-2**63, 2**63 - 1), st.floats(), st.text(max_size=20))
JSON_VALUES = st.sampled_from([None, float("nan"), float("inf"), -1, 0, 1e308, 10**30, "x", [], {}, [1.0],
                               [float("nan"), 0.0], {"a": 1}, True])


def _attribute_value(data):
    kind = data.draw(st.sampled_from(["scalar", "array", "bytes"]), label="attribute kind")
    if kind == "scalar":
        return data.draw(SCALARS, label="value")
    if kind == "bytes":
        return np.void(data.draw(st.binary(min_size=1, max_size=16), label="bytes"))
    shape = data.draw(st.lists(st.integers(0, 3), max_size=3), label="shape")
    return np.full(shape, data.draw(st.sampled_from([0, -1, 7, 2**40]), label="fill"), dtype=np.int64)


def _dataset_value(data, old):
    how = data.draw(st.sampled_from(["fill", "one", "fewer", "more", "shape", "strings", "group", "empty"]),
                    label="dataset corruption")
    value = np.array(old)
    if how == "fill":
        return np.full_like(value, data.draw(st.sampled_from([np.nan, np.inf, -1.0, 0.0, 1e300, -7]),
                                             label="fill"), dtype=float)
    if how == "one" and value.size:
        value = value.astype(float)
        value.flat[data.draw(st.integers(0, value.size - 1), label="at")] = data.draw(
            st.sampled_from([np.nan, -np.inf, -1.0, 1e300, 3.5, -0.0]), label="value")
        return value
    if how == "fewer":
        return value[:-1]
    if how == "more":
        return np.concatenate([value, value[:1]]) if len(value) else np.zeros((1,) + value.shape[1:])
    if how == "shape":
        return value.reshape(len(value), -1) if value.ndim > 1 else np.stack([value, value], axis=1)
    if how == "strings":
        return np.array([b"garbage"] * max(len(value), 1))
    if how == "group":
        return "group"
    return np.zeros((0,))


def _corrupt(data, path):
    import json

    import h5py
    what = data.draw(st.sampled_from(["item"] * 9 + ["bytes"]), label="what")
    if what == "bytes":
        content = bytearray(open(path, "rb").read())
        at = data.draw(st.integers(0, len(content) - 1), label="at")
        how = data.draw(st.sampled_from(["truncate", "flip"]), label="how")
        if how == "truncate":
            content = content[:at]
        else:
            for k in range(data.draw(st.integers(1, 64), label="bytes")):
                content[(at + 4099 * k) % len(content)] ^= 0xFF
        with open(path, "wb") as f:
            f.write(bytes(content))
        return f"bytes {how} at {at}"
    kind, name, key = data.draw(st.sampled_from(_items(path)), label="item")
    with h5py.File(path, "r+") as f:
        if kind == "attribute":
            owner = f[name]
            if data.draw(st.booleans(), label="delete"):
                del owner.attrs[key]
                return f"attribute {name} {key} deleted"
            value = _attribute_value(data)
            owner.attrs[key] = value
            return f"attribute {name} {key} = {value!r}"
        elif kind == "json":
            parsed = json.loads(f.attrs[name])
            owner = parsed
            for k in key[:-1]:
                owner = owner[k]
            if data.draw(st.booleans(), label="delete"):
                del owner[key[-1]]
            else:
                owner[key[-1]] = data.draw(JSON_VALUES, label="value")
            f.attrs[name] = json.dumps(parsed)
            return f"{name} {key}: {owner.get(key[-1], 'deleted')!r}"
        else:
            old = f[name][...]
            attrs = dict(f[name].attrs)
            del f[name]
            if data.draw(st.integers(0, 5), label="delete") == 0:
                return f"dataset {name} deleted"
            value = _dataset_value(data, old)
            if isinstance(value, str):
                f.create_group(name)
                return f"dataset {name} a group"
            f[name] = value
            f[name].attrs.update(attrs)
            return f"dataset {name} = {value!r}"[:300]


@contextlib.contextmanager
def _in_process(directory):
    """Run pimpm's main here: in ``directory``, its stderr captured, the
    signal handlers it installs put back afterwards."""
    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    cwd, err = os.getcwd(), io.StringIO()
    os.chdir(directory)
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            yield err
    finally:
        os.chdir(cwd)
        for s, h in handlers.items():
            signal.signal(s, h)


def _fuzz_checkpoint(data, checkpointed, work):
    from pimpm.__main__ import main
    run = data.draw(st.sampled_from(sorted(RUNS)), label="run")
    out = os.path.join(work, "o")
    shutil.rmtree(out, ignore_errors=True)
    shutil.copytree(checkpointed[run], out)
    done = _corrupt(data, os.path.join(out, "checkpoint.h5"))
    if not done.startswith("bytes"):       # as if written so: past checkpoint.sha256, to what reads it
        from pimpm.io.checkpoint import file_digest
        with open(os.path.join(out, "checkpoint.sha256"), "w") as f:
            f.write(file_digest(os.path.join(out, "checkpoint.h5")) + "\n")
    before, rows_before = _snapshot(out), _history_rows(out)
    if os.environ.get("PIMPM_FUZZ_LOG"):         # a case that kills the process is still on record
        with open(os.environ["PIMPM_FUZZ_LOG"], "a") as f:
            f.write(f"{done}\n")
    with _in_process(work) as err:
        try:
            status = main(RUNS[run] + ["--output", "o", "--restart"])
        except SystemExit as stop:        # (a restart's own exits come back as return values)
            status = stop.code
    if os.environ.get("PIMPM_FUZZ_LOG"):
        with open(os.environ["PIMPM_FUZZ_LOG"], "a") as f:
            f.write(f"  -> exit status {status}\n")
    _check_contract(status, err.getvalue(), before, _snapshot(out), rows_before,
                    _history_rows(out) if status != 2 else rows_before)


@QUICK
@given(data=st.data())
def test_a_restart_from_a_fuzzed_checkpoint_keeps_the_contract(data, checkpointed, tmp_path_factory):
    _fuzz_checkpoint(data, checkpointed, str(tmp_path_factory.mktemp("restart")))


@pytest.mark.slow
@long_run
@LONG
@given(data=st.data())
def test_a_restart_from_a_fuzzed_checkpoint_long_run(data, checkpointed, tmp_path_factory):
    _fuzz_checkpoint(data, checkpointed, str(tmp_path_factory.mktemp("restart")))


def test_the_checkpoint_fuzzer_reaches_every_item(checkpointed):
    """Every attribute, JSON key and dataset of both checkpoints is a case,
    the contact tool's state and fields among them."""
    items = _items(os.path.join(checkpointed["contact"], "checkpoint.h5"))
    kinds = {kind for kind, _, _ in items}
    assert kinds == {"attribute", "dataset", "json"}
    assert ("dataset", "particles/F", None) in items and ("json", "control", ("cuts",)) in items
    assert ("attribute", "particles", "counts_per_rank") in items
    assert ("json", "terms", ("puller", "offset")) in items
    assert any(kind == "dataset" and "contact" in name for kind, name, _ in items)


# -- command lines -------------------------------------------------------------

def _pimpm_options():
    from test_fuzz import OPTIONS
    return OPTIONS


PETSC_OPTIONS = ["-snes_rtol", "-snes_atol", "-snes_stol", "-snes_max_it", "-snes_linesearch_type",
                 "-snes_linesearch_damping", "-ksp_type", "-pc_type", "-ksp_rtol", "-ksp_max_it",
                 "-pc_factor_mat_solver_type", "-mat_mumps_icntl_14", "-snes_monitor", "-ksp_monitor",
                 "-snes_converged_reason", "-options_file", "-help", "-log_view", "-mat_mffd_err"]
VALUES = ["0", "-1", "1e400", "nan", "inf", "-inf", "abc", "", "1", "100000000000", "lu", "gmres", "none",
          "true", "false", "0x10", "1e-300", "-", "--", "/nonexistent", "o"]
SET_TEXTS = ["&a [*a]", "[" * 100 + "]" * 100, "{a: 1, a: 2}", "!!python/object:os.system x", "1e999",
             ".nan", "~", "'", "[1, 2", "-1", "0", "null", "[]", "{}"]


def _command_line(data):
    from test_fuzz import CASES
    argv = [BAR]
    for _ in range(data.draw(st.integers(1, 4), label="arguments")):
        kind = data.draw(st.sampled_from(["flag", "set", "petsc", "pimpm"]), label="kind")
        if kind == "flag":
            flag = data.draw(st.sampled_from(["--check", "--overwrite", "--restart", "--output", "-check",
                                              "-output", "-restart", "--help", "--frobnicate", "-set"]),
                             label="flag")
            argv.append(flag)
            if flag.endswith("output"):
                argv.append(data.draw(st.sampled_from(["o", "", " ", "o/sub", "/dev/null/x", "-x"]),
                                      label="directory"))
        elif kind == "set":
            path = data.draw(st.sampled_from([p for n, p in CASES if n == "bar_tension.yaml"]), label="key")
            key = "".join((f"[{k}]" if isinstance(k, int) else (f".{k}" if i else str(k)))
                          for i, k in enumerate(path))
            argv += ["--set", f"{key}={data.draw(st.sampled_from(SET_TEXTS + VALUES), label='value')}"]
        else:
            names = PETSC_OPTIONS if kind == "petsc" else _pimpm_options()
            argv.append(data.draw(st.sampled_from(names), label="option"))
            if data.draw(st.booleans(), label="with a value"):
                argv.append(data.draw(st.sampled_from(VALUES), label="value"))
    return argv


def _fuzz_command_line(data, checkpointed, work):
    """A random command line against a directory that holds an earlier run
    (the checkpointed bar): whatever it does, it keeps the contract."""
    argv = _command_line(data)
    out = os.path.join(work, "o")
    shutil.rmtree(out, ignore_errors=True)
    shutil.copytree(checkpointed["bar"], out)
    before, rows_before = _snapshot(work), _history_rows(out)
    proc = subprocess.run([sys.executable, "-m", "pimpm"] + argv, cwd=work, env=mpi_env(),
                          capture_output=True, text=True, timeout=300, stdin=subprocess.DEVNULL)
    after = _snapshot(work)
    overwritten = "--overwrite" in argv and proc.returncode != 2
    rows_after = rows_before if proc.returncode == 2 or overwritten or not os.path.exists(
        os.path.join(out, "history.csv")) else _history_rows(out)
    _check_contract(proc.returncode, proc.stderr, before, after, rows_before, rows_after)


@CLI_QUICK
@given(data=st.data())
def test_a_fuzzed_command_line_keeps_the_contract(data, checkpointed, tmp_path_factory):
    _fuzz_command_line(data, checkpointed, str(tmp_path_factory.mktemp("cli")))


@pytest.mark.slow
@long_run
@LONG
@given(data=st.data())
def test_a_fuzzed_command_line_long_run(data, checkpointed, tmp_path_factory):
    _fuzz_command_line(data, checkpointed, str(tmp_path_factory.mktemp("cli")))
