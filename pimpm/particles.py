"""Particle storage, seeding and migration between MPI ranks.

Particles are plain numpy arrays (one dict of fields per set) living on the
rank that owns their cell (see :mod:`pimpm.grid`). After every step they are
migrated with one ``Alltoallv`` that moves every field at once; the global
count and mass are checked by the caller.
"""
import numpy as np
from mpi4py import MPI


class ParticleSet:
    """A set of particles: ``fields[name]`` is an array whose first axis is the
    local particle index. All fields always have the same length."""

    def __init__(self, fields):
        self.fields = dict(fields)

    def __len__(self):
        return len(self.fields["x"])

    def __getitem__(self, name):
        return self.fields[name]

    def __setitem__(self, name, value):
        self.fields[name] = value

    def __contains__(self, name):
        return name in self.fields

    def take(self, index):
        """Reorder / select particles in every field."""
        self.fields = {k: v[index] for k, v in self.fields.items()}

    def global_count(self, comm):
        return comm.allreduce(len(self), op=MPI.SUM)

    def global_sum(self, comm, name):
        local = np.sum(self.fields[name], axis=0) if len(self) else np.zeros(
            self.fields[name].shape[1:])
        return comm.allreduce(local, op=MPI.SUM)


def _inside_geometry(points, geometry):
    if geometry["type"] == "box":
        lo, hi = np.asarray(geometry["lower"]), np.asarray(geometry["upper"])
        return np.all((points >= lo) & (points <= hi), axis=1)
    if geometry["type"] == "ball":
        c = np.asarray(geometry["center"])
        return np.sum((points - c) ** 2, axis=1) <= geometry["radius"] ** 2
    if geometry["type"] == "cylinder":
        lo, hi = np.asarray(geometry["lower"]), np.asarray(geometry["upper"])
        in_box = np.all((points >= lo) & (points <= hi), axis=1)
        radial = [d for d in range(points.shape[1]) if d != "xyz".index(geometry["axis"])]
        c = np.asarray(geometry["center"])[radial]
        return in_box & (np.sum((points[:, radial] - c) ** 2, axis=1) <= geometry["radius"] ** 2)
    raise ValueError(f"unknown geometry type {geometry['type']!r}")


def _bounding_box(geometry):
    if geometry["type"] in ("box", "cylinder"):
        return np.asarray(geometry["lower"], float), np.asarray(geometry["upper"], float)
    c, r = np.asarray(geometry["center"], float), float(geometry["radius"])
    return c - r, c + r


def seed_body(grid, geometry, particles_per_cell, body_index, id_offset):
    """Seed particles of one body in the cells this rank owns.

    Each cell overlapping the body's bounding box gets a regular lattice of
    ``particles_per_cell`` points per axis at sub-cell centres; points inside
    the geometry are kept. Returns ``(x, volume0, id)``; the id is a function of
    the global cell and sub-cell index only, so it does not depend on the
    number of ranks.
    """
    dim = grid.dim
    ppc = np.asarray(particles_per_cell, dtype=np.int64)
    n_sub = int(np.prod(ppc))
    lo, hi = _bounding_box(geometry)
    c_lo = np.clip(np.floor((lo - grid.lower) / grid.spacing).astype(np.int64), 0, grid.cells)
    c_hi = np.clip(np.ceil((hi - grid.lower) / grid.spacing).astype(np.int64), 0, grid.cells)
    c_lo = np.maximum(c_lo, grid.owned_cell_start)
    c_hi = np.minimum(c_hi, grid.owned_cell_end)
    if np.any(c_hi <= c_lo):
        return np.zeros((0, dim)), np.zeros(0), np.zeros(0, dtype=np.int64)
    cell_axes = [np.arange(a, b) for a, b in zip(c_lo, c_hi)]
    cells = np.stack([m.ravel() for m in np.meshgrid(*cell_axes, indexing="ij")], axis=1)
    sub_axes = [np.arange(p) for p in ppc]
    subs = np.stack([m.ravel() for m in np.meshgrid(*sub_axes, indexing="ij")], axis=1)
    # sub-cell linear index, x fastest
    sub_index = subs[:, -1].copy()
    for d in range(dim - 2, -1, -1):
        sub_index = sub_index * ppc[d] + subs[:, d]
    frac = (subs + 0.5) / ppc                                    # (n_sub, dim)
    x = grid.lower + (cells[:, None, :] + frac[None, :, :]) * grid.spacing
    pid = grid.global_cell_index(cells)[:, None] * n_sub + sub_index[None, :] + id_offset
    x = x.reshape(-1, dim)
    pid = pid.reshape(-1)
    keep = _inside_geometry(x, geometry)
    x, pid = x[keep], pid[keep]
    order = np.argsort(pid, kind="stable")
    volume0 = np.full(len(x), grid.cell_volume / n_sub)
    return x[order], volume0[order], pid[order]


def migrate(comm, particle_set, destination):
    """Send every particle to rank ``destination[p]`` with one Alltoallv.

    All fields are packed as float64 columns (integer fields are exact below
    2**53) and restored to their dtypes. Collective: every rank must call it.
    """
    size = comm.size
    names = sorted(particle_set.fields)
    arrays = [particle_set.fields[k] for k in names]
    n = len(particle_set)
    widths = [int(np.prod(a.shape[1:])) for a in arrays]
    ncol = sum(widths)
    order = np.argsort(destination, kind="stable")
    packed = np.empty((n, ncol))
    col = 0
    for a, w in zip(arrays, widths):
        packed[:, col:col + w] = a.reshape(n, w)[order]
        col += w
    send_counts = np.bincount(destination, minlength=size).astype(np.int64)
    recv_counts = np.empty(size, dtype=np.int64)
    comm.Alltoall(send_counts, recv_counts)
    n_new = int(recv_counts.sum())
    received = np.empty((n_new, ncol))
    send_displ = np.concatenate(([0], np.cumsum(send_counts)[:-1])) * ncol
    recv_displ = np.concatenate(([0], np.cumsum(recv_counts)[:-1])) * ncol
    comm.Alltoallv([packed, send_counts * ncol, send_displ, MPI.DOUBLE],
                   [received, recv_counts * ncol, recv_displ, MPI.DOUBLE])
    col = 0
    fields = {}
    for name, a, w in zip(names, arrays, widths):
        fields[name] = received[:, col:col + w].reshape((n_new,) + a.shape[1:]).astype(a.dtype)
        col += w
    particle_set.fields = fields
