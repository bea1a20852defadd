"""Checkpoints: the complete state of a run after a step, from which
``python -m pimpm INPUT --restart`` continues (docs/RELIABILITY.md).

``OUTDIR/checkpoint.h5`` holds every particle field of the material and
rigid particles (F, stress, history variables, velocities, accelerations,
reference volumes, ids, ...) as global arrays in rank order (each rank's
particles in their order, ``counts_per_rank`` beside), the DMDA's ownership
ranges, and as attributes the step, the time, the time-step controller's
state, the energy and work accumulators, the initial particle count and
mass, and the physical part of the input (grid, kinematics, materials,
bodies) as JSON, against which a restart is checked.

Written in parallel to ``checkpoint.h5.tmp``, closed on every rank, then
renamed by rank 0: there is never a half-written checkpoint, and a failure
while writing leaves the previous one. ``checkpoint.sha256`` beside it holds
the file's SHA-256 digest (and the previous checkpoint's, so that a stop
between the two renames leaves a pair that matches): a restart compares
them before HDF5 reads a byte, since a damaged HDF5 file can crash the
HDF5 library itself (issue 32's fuzzer found a segmentation fault). On the same number of ranks a
restart gets each rank's particles back in the same order and the same
ownership ranges, so the continued run equals the uninterrupted one bit
for bit; on another number of ranks the particles are redistributed.
"""
import hashlib
import json
import os

import numpy as np

from ..errors import OutputFailed
from .directory import CHECKPOINT_H5, CHECKPOINT_SUM
from .hdf5 import collective_transfer, write_slab
from .space import check_room

FORMAT = 1
#: the input sections a restart must not change (the rest: time, solver, output may)
PHYSICS_KEYS = ("dim", "grid", "kinematics", "materials", "bodies")


def physics_json(config):
    """The physical part of the input; its contact pairs too when it has
    some (so that checkpoints without pairs read as before)."""
    keys = PHYSICS_KEYS + (("contact",) if config.get("contact") else ())
    return json.dumps({k: config[k] for k in keys}, sort_keys=True, default=float)


def _open(path, mode, comm):
    import h5py    # the MPI or serial build is chosen at import time (PLATFORM.md)
    if comm.size > 1:
        return h5py.File(path, mode, driver="mpio", comm=comm)
    return h5py.File(path, mode)


def write_checkpoint(sim, control, directory):
    """Write the state of ``sim`` (after its last completed step) and of the
    step controller ``control``. Collective."""
    comm = sim.comm
    path = os.path.join(directory, CHECKPOINT_H5)
    tmp = path + ".tmp"
    if comm.rank == 0 and os.path.lexists(tmp):
        os.remove(tmp)                     # a leftover of an interrupted write (never a link's target)
    comm.Barrier()
    sets = {"particles": sim.particles, "rigid": sim.rigid}
    # agree on every size and field before any collective HDF5 call (a rank
    # with no particles still knows every field: rank 0's description rules)
    local = {name: (len(pset), {k: (tuple(v.shape[1:]), v.dtype.str) for k, v in pset.fields.items()})
             for name, pset in sets.items()}
    gathered = comm.allgather(local)
    counts = {name: np.array([g[name][0] for g in gathered], dtype=np.int64) for name in sets}
    fields = {name: dict(sorted(gathered[0][name][1].items())) for name in sets}
    nbytes = sum(int(counts[name].sum()) * int(np.prod(shape, dtype=np.int64)) * np.dtype(dtype).itemsize
                 for name in sets for shape, dtype in fields[name].values())
    check_room(comm, directory, nbytes, "the checkpoint")     # (the previous one is kept)
    dxpl = collective_transfer() if comm.size > 1 else None
    f = _open(tmp, "w", comm)
    try:
        f.attrs["format"] = FORMAT
        f.attrs["step"] = sim.step_index
        f.attrs["time"] = sim.time
        f.attrs["ranks"] = comm.size
        f.attrs["physics"] = physics_json(sim.config)
        f.attrs["control"] = json.dumps(control.state())
        f.attrs["work"] = json.dumps(sim.work.state())
        f.attrs["terms"] = json.dumps({term.name: term.state() for term in sim.terms})
        f.attrs["fields"] = json.dumps(sim.fields.state(sim.grid))
        # each load's total share as summed at the start (summed again after the particles
        # migrated, the last bit of the load's resultant would differ from the run's)
        f.attrs["loads"] = json.dumps({load.name: load.total_share for load in sim.loads})
        f.attrs["initial"] = json.dumps({"count": int(sim.count0), "rigid_count": int(sim.rigid_count0),
                                         "mass": float(sim.mass0)})
        ranges = f.create_group("ownership_ranges")
        for d, r in enumerate(sim.grid.da.getOwnershipRanges()):
            ranges.create_dataset(str(d), data=np.asarray(r, dtype=np.int64))
        ranges.attrs["proc_sizes"] = np.asarray(sim.grid.proc_sizes, dtype=np.int64)
        for name, pset in sets.items():
            group = f.create_group(name)
            group.attrs["counts_per_rank"] = counts[name]
            offset = int(counts[name][:comm.rank].sum())
            total = int(counts[name].sum())
            for field in fields[name]:
                shape, dtype = fields[name][field]
                dset = group.create_dataset(field, shape=(total,) + shape, dtype=dtype)
                if total:
                    data = np.asarray(pset[field]) if field in pset else np.zeros((0,) + shape, dtype)
                    write_slab(dset, (offset,) + (0,) * len(shape), data, dxpl)
    finally:
        f.close()
    comm.Barrier()
    problem = None
    if comm.rank == 0:
        try:
            _replace_with_digest(tmp, path)
        except OSError as err:
            problem = f"writing {path} failed ({err})"
    problem = comm.bcast(problem)
    if problem:
        raise OutputFailed(problem)


def file_digest(path):
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(2**22), b""):
            digest.update(block)
    return digest.hexdigest()


def _replace_with_digest(tmp, path):
    """Put the checkpoint ``tmp`` in place of ``path`` with its digest: first
    the digest file (the new digest and the one it replaces), then the file."""
    sums = os.path.join(os.path.dirname(path), CHECKPOINT_SUM)
    digests = [file_digest(tmp)]
    if os.path.isfile(sums):
        with open(sums) as f:
            digests += f.read().split()[:1]
    with open(sums + ".tmp", "w") as f:
        f.write("\n".join(digests) + "\n")
    os.replace(sums + ".tmp", sums)
    os.replace(tmp, path)


def digest_problem(directory):
    """Why ``directory``'s checkpoint.h5 does not match checkpoint.sha256, or
    None (also when there is no digest file: checkpoints of pimpm before it)."""
    sums = os.path.join(directory, CHECKPOINT_SUM)
    path = os.path.join(directory, CHECKPOINT_H5)
    if not os.path.exists(sums) or not os.path.isfile(path):
        return None
    try:
        with open(sums, "rb") as f:
            known = f.read(4096).decode("ascii", errors="replace").split()
        if file_digest(path) not in known:
            return f"{path} does not match its digest in {CHECKPOINT_SUM} (damaged since it was written?)"
    except OSError as err:
        return f"{path} or {CHECKPOINT_SUM} cannot be read ({err.strerror})"
    return None


class Checkpoint:
    """What :func:`read_checkpoint` returns: the attributes and, for each
    particle set, the fields of this rank (same rank count) or of all ranks."""

    def __init__(self, attrs, ranges, proc_sizes, sets, same_ranks):
        self.step = _integer(attrs["step"], "step", 0)
        self.time = _number(attrs["time"], "time", 0.0)
        self.ranks = _integer(attrs["ranks"], "ranks", 1)
        #: the physical part of the input (PHYSICS_KEYS), as read
        self.physics = _json_mapping(attrs["physics"], "physics")
        self.control = _json_mapping(attrs["control"], "control")
        for key in ("dt", "target", "initial"):
            if _key(self.control, key, "control") is not None:
                _number(self.control[key], f"control {key}", 0.0, positive=True)
        _integer(_key(self.control, "cuts", "control"), "control cuts", 0, 50)
        self.work = _json_mapping(attrs["work"], "work")
        _number(_key(self.work, "total", "work"), "work total")
        _key(self.work, "last_forces", "work")
        for key in ("last_forces", "displacements"):
            for name, vector in _mapping(self.work.get(key, {}), f"work {key}").items():
                _numbers(vector, f"work {key} of {name!r}")
        self.initial = _json_mapping(attrs["initial"], "initial")
        _integer(_key(self.initial, "count", "initial"), "initial count", 0)
        _integer(_key(self.initial, "rigid_count", "initial"), "initial rigid_count", 0)
        _number(_key(self.initial, "mass", "initial"), "initial mass", 0.0)
        #: each nodal term's state by name (contact tools: where the tool is)
        self.terms = _json_mapping(attrs.get("terms") or "{}", "terms")
        for name, state in self.terms.items():
            _mapping(state, f"terms {name!r}")
        #: the contact pairs' state (pimpm.fields: the frictional dissipation so far)
        self.fields = _json_mapping(attrs.get("fields") or "{}", "fields")
        #: each load's total share (pimpm.loads.Load.total_share)
        self.loads = _json_mapping(attrs.get("loads") or "{}", "loads")
        for name, total in self.loads.items():
            _number(total, f"loads {name!r}")
        if "dissipation" in self.fields:
            _number(self.fields["dissipation"], "fields dissipation", 0.0)
        self.ownership_ranges = ranges
        self.proc_sizes = proc_sizes
        self.sets = sets
        self.same_ranks = same_ranks


# A checkpoint is read as input (issue 32): every attribute, range and count
# is checked for its type and range before a restart uses it, so that a
# damaged file is one message (ValueError), not a traceback, a hang in a
# collective call or a kernel indexing memory it does not own.

def _key(mapping, key, name):
    if key not in mapping:
        raise ValueError(f"its {name} attribute has no {key!r}")
    return mapping[key]


def _integer(value, name, low, high=None):
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"its {name} is {value!r}: expected an integer")
    if value < low or (high is not None and value > high):
        raise ValueError(f"its {name} is {value}: expected an integer from {low}"
                         + (f" to {high}" if high is not None else " up"))
    return int(value)


def _number(value, name, low=None, positive=False):
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"its {name} is {value!r}: expected a number")
    value = float(value)
    if not np.isfinite(value) or (low is not None and value < low) or (positive and value <= 0.0):
        raise ValueError(f"its {name} is {value}: expected a finite number"
                         + (" > 0" if positive else f" >= {low}" if low is not None else ""))
    return value


def _numbers(values, name):
    if not isinstance(values, list) or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                               and np.isfinite(v) for v in values):
        raise ValueError(f"its {name} is {values!r}: expected a list of finite numbers")


def _mapping(value, name):
    if not isinstance(value, dict):
        raise ValueError(f"its {name} is {value!r}: expected a mapping")
    return value


def _json_mapping(value, name):
    if isinstance(value, bytes):
        value = value.decode("utf-8", errors="replace")
    if not isinstance(value, str):
        raise ValueError(f"its {name} attribute is {type(value).__name__}: expected JSON text")
    try:
        parsed = _mapping(json.loads(value), f"{name} attribute")
    except json.JSONDecodeError as err:
        raise ValueError(f"its {name} attribute is not JSON ({err})") from None
    _finite(parsed, f"{name} attribute")
    return parsed


def _finite(value, name):
    """Every number in a parsed JSON value finite (JSON's NaN and Infinity are not)."""
    if isinstance(value, dict):
        for v in value.values():
            _finite(v, name)
    elif isinstance(value, list):
        for v in value:
            _finite(v, name)
    elif isinstance(value, float) and not np.isfinite(value):
        raise ValueError(f"its {name} holds {value}: expected finite numbers")


def _check_layout(f, ranks):
    """The ownership ranges and particle counts of an open checkpoint file,
    checked (the same on every rank: they are attributes and small arrays)."""
    import h5py
    group = f["ownership_ranges"]
    proc_sizes = np.asarray(group.attrs["proc_sizes"])
    if proc_sizes.ndim != 1 or proc_sizes.dtype.kind not in "iu" or len(proc_sizes) != len(group) \
            or np.any(proc_sizes < 1) or int(np.prod(proc_sizes)) != ranks:
        raise ValueError(f"its process grid {proc_sizes.tolist()} is not one of {ranks} ranks")
    for d in range(len(group)):
        r = group[str(d)]
        if not isinstance(r, h5py.Dataset) or r.ndim != 1 or r.dtype.kind not in "iu" \
                or r.shape[0] != proc_sizes[d] or np.any(r[...] < 1):
            raise ValueError(f"its ownership ranges along axis {d} are not {proc_sizes[d]} positive counts")
    for name in ("particles", "rigid"):
        g = f[name]
        if not isinstance(g, h5py.Group):
            raise ValueError(f"its {name} are not a group")
        counts = np.asarray(g.attrs["counts_per_rank"])
        if counts.ndim != 1 or counts.dtype.kind not in "iu" or len(counts) != ranks or np.any(counts < 0):
            raise ValueError(f"its {name}' counts_per_rank are not {ranks} counts")
        for field, data in g.items():
            if not isinstance(data, h5py.Dataset) or data.dtype.kind not in "biuf" or data.ndim < 1 \
                    or data.shape[0] != counts.sum() or data.size > 2**40:
                raise ValueError(f"its {name}' {field} is not an array of numbers with one row for each "
                                 f"of its {counts.sum()} {name}")


def _check_values(sets):
    """A problem of the particle fields read by this rank (not finite), or None."""
    for name, fields in sets.items():
        for field, values in fields.items():
            if values.dtype.kind == "f" and not np.all(np.isfinite(values)):
                return f"its {name}' {field} are not all finite"
    return None


def read_checkpoint(directory, comm):
    """Read ``OUTDIR/checkpoint.h5``: each rank its own particles when the
    number of ranks is the one that wrote it, else every rank all of them
    (the caller keeps its own). Collective; OSError/KeyError if missing or
    unreadable."""
    path = os.path.join(directory, CHECKPOINT_H5)
    if os.path.islink(path):
        raise OSError(f"{path} is a symbolic link")
    if not os.path.isfile(path):
        raise OSError(f"there is no {path}")
    problem = comm.bcast(digest_problem(directory) if comm.rank == 0 else None)
    if problem:                            # before HDF5 opens it
        raise ValueError(problem)
    f = _open(path, "r", comm)
    try:
        attrs = {k: f.attrs[k] for k in ("format", "step", "time", "ranks", "physics", "control",
                                          "work", "initial")}
        attrs["terms"] = f.attrs.get("terms", "{}")
        attrs["fields"] = f.attrs.get("fields", "{}")
        attrs["loads"] = f.attrs.get("loads", "{}")
        if _integer(attrs["format"], "format", 0) != FORMAT:
            raise KeyError(f"checkpoint format {attrs['format']} (this pimpm reads {FORMAT})")
        physics = attrs["physics"]
        attrs["physics"] = physics.decode() if isinstance(physics, bytes) else str(physics)
        for k in ("control", "work", "initial", "terms", "fields", "loads"):
            v = attrs[k]
            attrs[k] = v.decode() if isinstance(v, bytes) else str(v)
        ranks = _integer(attrs["ranks"], "ranks", 1)
        _check_layout(f, ranks)
        group = f["ownership_ranges"]
        ranges = [np.asarray(group[str(d)][...]) for d in range(len(group))]
        proc_sizes = np.asarray(group.attrs["proc_sizes"])
        same = ranks == comm.size
        sets = {}
        for name in ("particles", "rigid"):
            g = f[name]
            counts = np.asarray(g.attrs["counts_per_rank"], dtype=np.int64)
            if same:
                start = int(counts[:comm.rank].sum())
                sel = slice(start, start + int(counts[comm.rank]))
            else:
                sel = slice(None)
            sets[name] = {field: np.asarray(g[field][sel]) for field in g}
    finally:
        f.close()
    problems = [p for p in comm.allgather(_check_values(sets)) if p]
    if problems:                                  # every rank raises: this rank's slice may be fine
        raise ValueError(problems[0])
    return Checkpoint(attrs, ranges, proc_sizes, sets, same)
