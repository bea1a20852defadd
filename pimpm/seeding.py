"""Seeding: particles of every body on the cells each rank owns.

Bodies from mesh and particle files are seeded by :mod:`pimpm.meshes`
(:func:`seed_file_body`). For the others, each cell is divided into
``particles_per_cell`` sub-cells per axis. A body
is the intersection of an axis-aligned box (a box, or a cylinder's extent)
with, for balls and cylinders, a curved region. Every sub-cell that
overlaps the box is clipped to it: the particle sits at the centre of the
clipped sub-cell and carries its volume (and half its extent as GIMP
domain), so a box's particles fill exactly its volume and no particle sits
on its faces, wherever the faces fall in the lattice. The curved surface of
a ball or cylinder keeps the sub-cells whose centre lies strictly inside
it, with their whole volume, and then the volumes of all the body's
particles are scaled by one factor so that they sum to the body's exact
measure (:func:`scale_to_exact`; the sub-cell layer along the surface
weighed up to 1.3% too much or too little). (Weighting the cut
sub-cells by their inside share was tried: it puts small particles at
arbitrary distances from cell faces, and a stress-free disk translating
with Newmark no longer stayed stress-free in the velocity formulation,
tests/test_formulations.py.)
"""
import numpy as np

from .exact_volume import exact_measure
from .particles import ParticleSet, sort_by_footprint


def _signed_distance_curved(points, geometry):
    """Distance outside (positive) or inside (negative) the curved part of
    the geometry; None for a box (no curved part)."""
    if geometry["type"] == "ball":
        c = np.asarray(geometry["center"])
        return np.sqrt(np.sum((points - c) ** 2, axis=1)) - geometry["radius"]
    if geometry["type"] == "cylinder":
        radial = [d for d in range(points.shape[1]) if d != "xyz".index(geometry["axis"])]
        c = np.asarray(geometry["center"])[radial]
        return np.sqrt(np.sum((points[:, radial] - c) ** 2, axis=1)) - geometry["radius"]
    if geometry["type"] == "half_space":      # a plane, the normal pointing out of the body
        return (points - np.asarray(geometry["point"])) @ np.asarray(geometry["normal"])
    if geometry["type"] == "surface":         # a tool's surface mesh (pimpm.surfaces)
        from .kernels.contact import MESH, point_distances
        from .surfaces import surface_params
        out = np.empty(len(points))
        point_distances(MESH, surface_params(geometry, points.shape[1], 0.0),
                        np.ascontiguousarray(points, dtype=float), out)
        return out
    if geometry["type"] == "box":
        return None
    raise ValueError(f"unknown geometry type {geometry['type']!r}")


def _bounding_box(geometry):
    if geometry["type"] in ("box", "cylinder", "half_space", "surface"):   # a half-space: the grid's box
        return np.asarray(geometry["lower"], float), np.asarray(geometry["upper"], float)
    c, r = np.asarray(geometry["center"], float), float(geometry["radius"])
    return c - r, c + r


def seed_body(grid, geometry, particles_per_cell, body_index, id_offset, axisymmetric=False):
    """Seed particles of one body in the cells this rank owns.

    Returns ``(x, volume0, half_size, id, surface)``; the id is a function of
    the global cell and sub-cell index only, so it does not depend on the
    number of ranks; ``surface``: see :func:`_surface`.
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
        return (np.zeros((0, dim)), np.zeros(0), np.zeros((0, dim)), np.zeros(0, dtype=np.int64),
                np.zeros((0, 2 * dim)))
    cell_axes = [np.arange(a, b) for a, b in zip(c_lo, c_hi)]
    cells = np.stack([m.ravel() for m in np.meshgrid(*cell_axes, indexing="ij")], axis=1)
    sub_axes = [np.arange(p) for p in ppc]
    subs = np.stack([m.ravel() for m in np.meshgrid(*sub_axes, indexing="ij")], axis=1)
    # sub-cell linear index, x fastest
    sub_index = subs[:, -1].copy()
    for d in range(dim - 2, -1, -1):
        sub_index = sub_index * ppc[d] + subs[:, d]
    frac = (subs + 0.5) / ppc                                    # (n_sub, dim)
    x = (grid.lower + (cells[:, None, :] + frac[None, :, :]) * grid.spacing).reshape(-1, dim)
    sub_lo = (grid.lower + (cells[:, None, :] + subs[None, :, :] / ppc) * grid.spacing).reshape(-1, dim)
    sub_hi = (grid.lower + (cells[:, None, :] + (subs[None, :, :] + 1) / ppc) * grid.spacing).reshape(-1, dim)
    pid = (grid.global_cell_index(cells)[:, None] * n_sub + sub_index[None, :] + id_offset).reshape(-1)
    half = np.broadcast_to(grid.spacing / (2.0 * ppc), x.shape).copy()
    volume0 = np.full(len(x), grid.cell_volume / n_sub)
    # clip the sub-cells to the geometry's box: centre and volume of the part inside
    # (faces that fall on sub-cell boundaries up to round-off clip nothing; a
    # ball has no flat faces: its bounding box only limits the cells searched)
    box_lo, box_hi = (lo, hi) if geometry["type"] != "ball" else (-np.inf, np.inf)
    clip_lo, clip_hi = np.maximum(sub_lo, box_lo), np.minimum(sub_hi, box_hi)
    tol = 1e-9 * grid.spacing / ppc
    overlap = np.all(clip_hi - clip_lo > tol, axis=1)
    clipped = overlap & np.any((clip_lo - sub_lo > tol) | (sub_hi - clip_hi > tol), axis=1)
    x[clipped] = 0.5 * (clip_lo[clipped] + clip_hi[clipped])
    half[clipped] = 0.5 * (clip_hi[clipped] - clip_lo[clipped])
    volume0[clipped] = np.prod(clip_hi[clipped] - clip_lo[clipped], axis=1)
    # the curved part (balls, cylinders): sub-cells whose centre is strictly inside
    distance = _signed_distance_curved(x, geometry)
    keep = overlap if distance is None else overlap & (distance < 0.0)
    order = np.argsort(pid[keep], kind="stable")
    lattice = (cells[:, None, :] * ppc + subs[None, :, :]).reshape(-1, dim)[keep][order]
    surface = _surface(grid, geometry, ppc, lattice, clip_lo[keep][order], clip_hi[keep][order],
                       axisymmetric)
    return x[keep][order], volume0[keep][order], half[keep][order], pid[keep][order], surface


def _member(grid, geometry, ppc, lattice):
    """Does the sub-cell at global lattice coordinates ``lattice`` (n, dim)
    hold a particle of the body? (the test seed_body applies)"""
    inside_grid = np.all((lattice >= 0) & (lattice < grid.cells * ppc), axis=1)
    sub_lo = grid.lower + lattice / ppc * grid.spacing
    sub_hi = grid.lower + (lattice + 1) / ppc * grid.spacing
    lo, hi = _bounding_box(geometry)
    box_lo, box_hi = (lo, hi) if geometry["type"] != "ball" else (-np.inf, np.inf)
    clip_lo, clip_hi = np.maximum(sub_lo, box_lo), np.minimum(sub_hi, box_hi)
    overlap = np.all(clip_hi - clip_lo > 1e-9 * grid.spacing / ppc, axis=1)
    distance = _signed_distance_curved(0.5 * (clip_lo + clip_hi), geometry)
    return inside_grid & (overlap if distance is None else overlap & (distance < 0.0))


def _surface(grid, geometry, ppc, lattice, clip_lo, clip_hi, axisymmetric):
    """(n, 2 dim): the area of each particle's domain face that lies on the
    body's surface, by outward normal (columns x-, x+, y-, y+(, z-, z+));
    a face is on the surface when the neighbouring sub-cell holds no
    particle. Areas per unit thickness in 2D; of revolution in axisymmetry."""
    n, dim = lattice.shape
    surface = np.zeros((n, 2 * dim))
    extent = clip_hi - clip_lo
    for d in range(dim):
        others = [e for e in range(dim) if e != d]
        for side, face in ((-1, clip_lo[:, d]), (1, clip_hi[:, d])):
            step = np.zeros(dim, dtype=np.int64)
            step[d] = side
            exposed = ~_member(grid, geometry, ppc, lattice + step)
            if axisymmetric:          # x is the radius: 2 pi r_face h, or an annulus
                area = (2.0 * np.pi * face * extent[:, 1] if d == 0
                        else np.pi * (clip_hi[:, 0] ** 2 - clip_lo[:, 0] ** 2))
            else:
                area = np.prod(extent[:, others], axis=1)
            surface[:, 2 * d + (side > 0)] = np.where(exposed, area, 0.0)
    return surface


def seed_file_body(grid, geometry, id_offset, axisymmetric=False):
    """Seed the particles of a mesh or particle-file body (pimpm.meshes) that
    lie in the cells this rank owns: ``(x, volume0, half_size, id, surface)``
    like :func:`seed_body`, and the number of ids the body uses."""
    from . import meshes
    dim = grid.dim
    if geometry["type"] == "mesh":
        mesh = meshes.read_mesh(geometry["file"], dim)
        seeds = meshes.seed_mesh(mesh, geometry["particles_per_element"], geometry["scale"],
                                 geometry["offset"], axisymmetric)
        x, volume, surface, local_id = seeds.x, seeds.volume, seeds.surface, seeds.local_id
        half = seeds.half_size
    else:
        x, volume = meshes.read_particle_file(geometry["file"], dim)
        x = x * geometry["scale"] + np.asarray(geometry["offset"])
        volume = volume * geometry["scale"] ** dim
        surface = np.zeros((len(x), 2 * dim))
        local_id = np.arange(len(x), dtype=np.int64)
        half = np.repeat(0.5 * volume[:, None] ** (1.0 / dim), dim, axis=1)
    # GIMP domains end on the grid's faces, as a box's clipped sub-cells do: a
    # domain across a face (a symmetry plane through the mesh) would lose part
    # of its shape functions, and with them the particle's share of the stress
    # (tests/test_plate_hole.py)
    half = np.minimum(half, np.maximum(np.minimum(x - grid.lower, grid.upper - x), 0.0))
    cells = grid.cell_of(x)
    mine = np.all((cells >= grid.owned_cell_start) & (cells < grid.owned_cell_end), axis=1)
    return (x[mine], volume[mine], half[mine], local_id[mine] + id_offset, surface[mine]), len(local_id)


def seed_bodies(config, grid, kinematics, densities, history_fields, comm=None):
    """Material and rigid particle sets of all bodies in ``config``, sorted
    by cell. ``densities``: body index -> density of its material (deformable
    bodies only); ``history_fields``: name -> (per-particle shape, initial value) of the
    materials' history variables (:attr:`pimpm.materials.Model.initial_history`).
    With ``comm`` (collective), the particle volumes of each ball or
    cylinder are scaled to sum to its exact measure (:func:`scale_to_exact`)."""
    dim = grid.dim
    mat = {k: [] for k in ("x", "volume0", "id", "body", "v", "density", "half_size", "surface")}
    rig = {k: [] for k in ("x", "id", "body", "v", "half_size")}
    id_offset = 0
    for i, b in enumerate(config["bodies"]):
        ppc = b["particles_per_cell"]
        axisymmetric = kinematics.name == "axisymmetric"
        if b["geometry"]["type"] in ("mesh", "particles"):
            (x, vol, half, pid, surface), ids = seed_file_body(grid, b["geometry"], id_offset,
                                                               axisymmetric)
            id_offset += ids
        else:
            x, vol, half, pid, surface = seed_body(grid, b["geometry"], ppc, i, id_offset,
                                                   axisymmetric)
            id_offset += int(np.prod(grid.cells)) * int(np.prod(ppc))
        target = rig if b.get("rigid", False) else mat
        target["x"].append(x)
        target["id"].append(pid)
        target["body"].append(np.full(len(x), i, dtype=np.int64))
        target["v"].append(np.tile(np.asarray(b.get("velocity", [0.0] * dim), float), (len(x), 1)))
        target["half_size"].append(half)             # GIMP's particle domain: h / (2 ppc), clipped
        if not b.get("rigid", False):
            target["volume0"].append(vol)
            target["density"].append(np.full(len(x), densities[i]))
            target["surface"].append(surface)
    cat = lambda lst, shape, dt=float: (np.concatenate(lst) if lst else np.zeros(shape, dtype=dt))
    x = cat(mat["x"], (0, dim))
    volume0 = kinematics.reference_volume(x, cat(mat["volume0"], (0,)))
    if comm is not None:
        scale_to_exact(config, grid, kinematics, volume0, cat(mat["body"], (0,), np.int64), comm)
    n = len(x)
    particles = ParticleSet({
        "x": x, "x0": x.copy(),
        "v": cat(mat["v"], (0, dim)), "a": np.zeros((n, dim)),
        "F": np.broadcast_to(np.eye(3), (n, 3, 3)).copy(),
        "stress": np.zeros((n, 3, 3)),
        "volume0": volume0, "mass": volume0 * cat(mat["density"], (0,)),
        "half_size": cat(mat["half_size"], (0, dim)),
        "body": cat(mat["body"], (0,), np.int64), "id": cat(mat["id"], (0,), np.int64),
        "surface": cat(mat["surface"], (0, 2 * dim)),
    })
    xr = cat(rig["x"], (0, dim))
    rigid = ParticleSet({
        "x": xr, "x0": xr.copy(), "v": cat(rig["v"], (0, dim)),
        "body": cat(rig["body"], (0,), np.int64), "id": cat(rig["id"], (0,), np.int64),
        "half_size": cat(rig["half_size"], (0, dim)),
    })
    for name, (shape, initial) in history_fields.items():
        particles["h_" + name] = np.zeros((n,) + tuple(shape)) + initial
    sort_by_footprint(particles, grid)
    sort_by_footprint(rigid, grid)
    return particles, rigid


def scale_to_exact(config, grid, kinematics, volume0, body, comm):
    """Scale, in place, the volumes of each deformable ball or cylinder so
    that they sum to the exact measure of its region in the grid
    (:func:`pimpm.exact_volume.exact_measure`). Whole sub-cells are kept
    along the curved surface, so the seeded volume misses it by up to a
    sub-cell layer (quarter cylinder of inputs/upsetting_3d.yaml: +1.3% at
    2 mm); one factor per body keeps every particle's share, so a stress-free
    body still translates stress-free. Collective."""
    axisymmetric = kinematics.name == "axisymmetric"
    for i, b in enumerate(config["bodies"]):
        if b.get("rigid", False):
            continue
        exact = exact_measure(b["geometry"], grid.lower, grid.upper, axisymmetric)
        if exact is None:
            continue
        mine = body == i
        seeded = comm.allreduce(float(np.sum(volume0[mine])))
        if seeded > 0.0 and exact > 0.0:
            volume0[mine] *= exact / seeded


#: the fields of every material particle (besides its material's history, h_*)
#: and of every rigid particle, as seeded: what a checkpoint must hold
MATERIAL_FIELDS = ("x", "x0", "v", "a", "F", "stress", "volume0", "mass", "half_size", "body", "id", "surface")
RIGID_FIELDS = ("x", "x0", "v", "body", "id", "half_size")


def inside_geometry(x, geometry, tolerance):
    """True for positions strictly inside a body's region (by more than
    ``tolerance`` per axis from its box faces; strictly inside a curved
    surface)."""
    if len(x) == 0 or geometry["type"] in ("mesh", "particles"):
        return np.zeros(len(x), dtype=bool)   # not checked for geometries from files
    lo, hi = _bounding_box(geometry)
    inside = np.all((x > lo + tolerance) & (x < hi - tolerance), axis=1)
    distance = _signed_distance_curved(x, geometry)
    return inside if distance is None else inside & (distance < 0.0)


def overlapping_bodies(config, particles, grid, comm):
    """(i, j, count): the first pair of deformable bodies where ``count``
    particles of body j lie inside body i's region, or None. Overlapping
    bodies would count the mass of the shared region twice. Collective."""
    bodies = [(i, b) for i, b in enumerate(config["bodies"]) if not b.get("rigid", False)]
    pairs = [(i, j) for i, a in bodies for j, b in bodies if i != j]
    if not pairs:
        return None
    tolerance = 1e-9 * grid.spacing
    counts = np.array([int(np.sum(inside_geometry(particles["x"][particles["body"] == j],
                                                  config["bodies"][i]["geometry"], tolerance)))
                       for i, j in pairs], dtype=np.int64)
    counts = comm.allreduce(counts)
    for (i, j), n in zip(pairs, counts):
        if n > 0:
            return i, j, int(n)
    return None


def particles_per_body(config, particles, rigid, comm):
    """Global number of particles of each body (collective)."""
    counts = np.zeros(len(config["bodies"]), dtype=np.int64)
    for pset in (particles, rigid):
        counts += np.bincount(pset["body"], minlength=len(counts)).astype(np.int64)
    return comm.allreduce(counts)


def body_volumes(config, particles, comm):
    """Global reference volume of each deformable body (the sum of its
    particles' volumes; 0 for rigid bodies). Collective."""
    volumes = np.zeros(len(config["bodies"]))
    np.add.at(volumes, particles["body"], particles["volume0"])
    return comm.allreduce(volumes)
