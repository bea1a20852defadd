"""A restart is a transaction: everything it will continue (``results.h5``,
``history.csv``, the XDMF files, the checkpoint) is read and checked before
any of them is opened for writing, so that a damaged or foreign file is one
clear message and every file stays exactly as it was (issue "Nothing lost,
nothing silent")."""
import csv
import math
import os

from .directory import ALL_NAMES, HISTORY_CSV, write_problem
from .hdf5 import same_grid, step_records
from .layout import H5_NAME


def check_restart_files(comm, directory, grid, history_columns, step, time):
    """Check, as a restart will read them, the output files of ``directory``
    that it continues: none is a symbolic link (a fresh run refuses them
    too); ``results.h5`` (if there) describes ``grid``'s nodes and its steps
    are readable; ``history.csv`` (if there) has ``history_columns`` and a
    row of numbers per step, among them the checkpoint's ``step`` at its
    ``time`` (a checkpoint that disagrees with the history it continues
    would drop or rewrite rows the history holds). Collective: ValueError on
    every rank, naming the file and what is wrong."""
    problem = None
    if comm.rank == 0:
        try:
            _check(directory, grid, history_columns, step, time)
        except (OSError, KeyError, ValueError, TypeError) as err:
            problem = str(err)
    problem = comm.bcast(problem)
    if problem:
        raise ValueError(problem)


def _check(directory, grid, history_columns, step, time):
    problem = write_problem(directory)
    if problem:
        raise ValueError(problem)
    for name in ALL_NAMES:
        path = os.path.join(directory, name)
        if os.path.islink(path):
            raise ValueError(f"{path!r} is a symbolic link: expected pimpm's output files not to be links "
                             "(a restart writes them in place; remove it)")
    results = os.path.join(directory, H5_NAME)
    if os.path.exists(results):
        _check_results(results, grid)
    history = os.path.join(directory, HISTORY_CSV)
    if os.path.exists(history):
        _check_history(history, history_columns, step, time)


def _check_results(path, grid):
    import h5py   # (serial reads on rank 0 work with either build)
    try:
        f = h5py.File(path, "r")
    except OSError as err:
        raise ValueError(f"{path!r} is not a readable HDF5 file ({err})") from None
    with f:
        try:
            # what ResultWriter(append=True) reads of it
            if "dim" in f.attrs and not same_grid(f.attrs, grid.dim, grid.nodes, grid.lower, grid.spacing):
                raise ValueError(f"{path!r} describes another grid than the input's")
            records = step_records(f["steps"]) if "steps" in f else {}
        except (KeyError, TypeError, AttributeError, OSError) as err:
            raise ValueError(f"{path!r} is not pimpm's results file or is damaged ({err})") from None
    for record in records.values():
        if record["step"] < 0 or not math.isfinite(record["time"]):
            raise ValueError(f"{path!r}: step {record['name']} has step {record['step']}, time {record['time']}")


def _check_history(path, columns, checkpoint_step, checkpoint_time):
    with open(path, newline="") as f:
        try:
            rows = list(csv.reader(f))
        except (csv.Error, UnicodeDecodeError) as err:
            raise ValueError(f"{path!r} is not a CSV file ({err})") from None
    if not rows or rows[0] != list(columns):
        raise ValueError(f"{path!r} has other columns than this run writes (its first line: "
                         f"{','.join(rows[0])[:80] if rows else 'none'})")
    found = None                               # the time of the checkpoint's step's row
    for number, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        try:
            if len(row) != len(columns):
                raise ValueError
            step = int(row[0])
            values = [float(v) for v in row[1:]]
        except ValueError:
            raise ValueError(f"{path!r} line {number} is not a row of {len(columns)} numbers") from None
        if step < 0 or not math.isfinite(values[0]):
            raise ValueError(f"{path!r} line {number}: step {row[0]}, time {row[1]}")
        if step == checkpoint_step:
            found = values[0]
    if checkpoint_step == 0:
        found = 0.0
    if found is None or not math.isclose(found, checkpoint_time, rel_tol=1e-12, abs_tol=1e-300):
        raise ValueError(f"{path!r} has no row of the checkpoint's step {checkpoint_step} at its time "
                         f"{checkpoint_time:.9g}: expected the history of the run that wrote the checkpoint")
