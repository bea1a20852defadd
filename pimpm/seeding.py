"""Seeding: particles of every body on the cells each rank owns, a regular
lattice of ``particles_per_cell`` points per axis at sub-cell centres, kept
where they fall inside the body's geometry (box, ball, cylinder).
"""
import numpy as np

from .particles import ParticleSet, sort_by_cell


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


def seed_bodies(config, grid, kinematics, densities, history_fields):
    """Material and rigid particle sets of all bodies in ``config``, sorted
    by cell. ``densities``: body index -> density of its material (deformable
    bodies only); ``history_fields``: name -> per-particle shape of the
    materials' history variables (identity-initialised where a tensor)."""
    dim = grid.dim
    mat = {k: [] for k in ("x", "volume0", "id", "body", "v", "density", "half_size")}
    rig = {k: [] for k in ("x", "id", "body", "v", "half_size")}
    id_offset = 0
    for i, b in enumerate(config["bodies"]):
        ppc = b["particles_per_cell"]
        x, vol, pid = seed_body(grid, b["geometry"], ppc, i, id_offset)
        id_offset += int(np.prod(grid.cells)) * int(np.prod(ppc))
        target = rig if b.get("rigid", False) else mat
        target["x"].append(x)
        target["id"].append(pid)
        target["body"].append(np.full(len(x), i, dtype=np.int64))
        target["v"].append(np.tile(np.asarray(b.get("velocity", [0.0] * dim), float), (len(x), 1)))
        # particle domain half size (used by GIMP): h / (2 ppc) per axis
        half = grid.spacing / (2.0 * np.asarray(ppc, dtype=float))
        target["half_size"].append(np.tile(half, (len(x), 1)))
        if not b.get("rigid", False):
            target["volume0"].append(vol)
            target["density"].append(np.full(len(x), densities[i]))
    cat = lambda lst, shape, dt=float: (np.concatenate(lst) if lst else np.zeros(shape, dtype=dt))
    x = cat(mat["x"], (0, dim))
    volume0 = kinematics.reference_volume(x, cat(mat["volume0"], (0,)))
    n = len(x)
    particles = ParticleSet({
        "x": x, "x0": x.copy(),
        "v": cat(mat["v"], (0, dim)), "a": np.zeros((n, dim)),
        "F": np.broadcast_to(np.eye(3), (n, 3, 3)).copy(),
        "stress": np.zeros((n, 3, 3)),
        "volume0": volume0, "mass": volume0 * cat(mat["density"], (0,)),
        "half_size": cat(mat["half_size"], (0, dim)),
        "body": cat(mat["body"], (0,), np.int64), "id": cat(mat["id"], (0,), np.int64),
    })
    xr = cat(rig["x"], (0, dim))
    rigid = ParticleSet({
        "x": xr, "x0": xr.copy(), "v": cat(rig["v"], (0, dim)),
        "body": cat(rig["body"], (0,), np.int64), "id": cat(rig["id"], (0,), np.int64),
        "half_size": cat(rig["half_size"], (0, dim)),
    })
    for name, shape in history_fields.items():
        identity = name in ("deformation_gradient", "elastic_left_cauchy_green")
        initial = np.broadcast_to(np.eye(3), (n, 3, 3)) if identity else 0.0
        particles["h_" + name] = np.zeros((n,) + tuple(shape)) + initial
    sort_by_cell(particles, grid)
    sort_by_cell(rigid, grid)
    return particles, rigid


def particles_per_body(config, particles, rigid, comm):
    """Global number of particles of each body (collective)."""
    counts = np.zeros(len(config["bodies"]), dtype=np.int64)
    for pset in (particles, rigid):
        counts += np.bincount(pset["body"], minlength=len(counts)).astype(np.int64)
    return comm.allreduce(counts)
