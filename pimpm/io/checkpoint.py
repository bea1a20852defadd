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
while writing leaves the previous one. On the same number of ranks a
restart gets each rank's particles back in the same order and the same
ownership ranges, so the continued run equals the uninterrupted one bit
for bit; on another number of ranks the particles are redistributed.
"""
import json
import os

import numpy as np

from .directory import CHECKPOINT_H5
from .hdf5 import collective_transfer, write_slab
from .space import check_room

FORMAT = 1
#: the input sections a restart must not change (the rest: time, solver, output may)
PHYSICS_KEYS = ("dim", "grid", "kinematics", "materials", "bodies")


def physics_json(config):
    return json.dumps({k: config[k] for k in PHYSICS_KEYS}, sort_keys=True, default=float)


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
    if comm.rank == 0:
        os.replace(tmp, path)
    comm.Barrier()


class Checkpoint:
    """What :func:`read_checkpoint` returns: the attributes and, for each
    particle set, the fields of this rank (same rank count) or of all ranks."""

    def __init__(self, attrs, ranges, proc_sizes, sets, same_ranks):
        self.step = int(attrs["step"])
        self.time = float(attrs["time"])
        self.ranks = int(attrs["ranks"])
        if self.step < 0 or not np.isfinite(self.time) or self.ranks < 1:
            raise ValueError(f"a checkpoint of step {self.step}, time {self.time}, {self.ranks} ranks")
        self.physics = attrs["physics"]
        self.control = json.loads(attrs["control"])
        self.work = json.loads(attrs["work"])
        self.initial = json.loads(attrs["initial"])
        #: each nodal term's state by name (contact tools: where the tool is)
        self.terms = json.loads(attrs.get("terms") or "{}")
        self.ownership_ranges = ranges
        self.proc_sizes = proc_sizes
        self.sets = sets
        self.same_ranks = same_ranks


def read_checkpoint(directory, comm):
    """Read ``OUTDIR/checkpoint.h5``: each rank its own particles when the
    number of ranks is the one that wrote it, else every rank all of them
    (the caller keeps its own). Collective; OSError/KeyError if missing or
    unreadable."""
    path = os.path.join(directory, CHECKPOINT_H5)
    if os.path.islink(path):
        raise OSError(f"{path} is a symbolic link")
    f = _open(path, "r", comm)
    try:
        attrs = {k: f.attrs[k] for k in ("format", "step", "time", "ranks", "physics", "control",
                                          "work", "initial")}
        attrs["terms"] = f.attrs.get("terms", "{}")
        if int(attrs["format"]) != FORMAT:
            raise KeyError(f"checkpoint format {attrs['format']} (this pimpm reads {FORMAT})")
        physics = attrs["physics"]
        attrs["physics"] = physics.decode() if isinstance(physics, bytes) else str(physics)
        for k in ("control", "work", "initial", "terms"):
            v = attrs[k]
            attrs[k] = v.decode() if isinstance(v, bytes) else str(v)
        group = f["ownership_ranges"]
        ranges = [np.asarray(group[str(d)][...]) for d in range(len(group))]
        proc_sizes = np.asarray(group.attrs["proc_sizes"])
        same = int(attrs["ranks"]) == comm.size
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
    return Checkpoint(attrs, ranges, proc_sizes, sets, same)
