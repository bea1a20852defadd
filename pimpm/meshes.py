"""Bodies from volume meshes (read with meshio) and from particle files.

A mesh body (``geometry: {type: mesh, file: ...}``) is seeded element by
element: each element is divided into ``n^dim`` parts (``n`` =
``particles_per_element``) and each part becomes one particle at its
centroid carrying its exact volume, so the body's volume (and its first
moment) equals the mesh's to round-off:

* triangles and tetrahedra: the regular (Kuhn/Freudenthal) subdivision of the
  simplex into ``n^dim`` simplices of equal volume, each particle at its
  sub-simplex's centroid;
* quadrilaterals and hexahedra: ``n`` parametric slices per axis; volume and
  centroid of each part are integrated with 2 Gauss points per axis, exact
  for the bi-/trilinear map (det J has degree <= 2 per parametric axis).

The mesh's boundary facets (faces of one element only) give the particle
field ``surface`` used by traction loads: each facet is divided like its
element (``n^(dim-1)`` parts) and each part's vector area (its area times its
outward normal; 2 pi r times it in axisymmetry) goes to the particle of its
element nearest to it, split by normal direction into the columns
x-, x+, y-, y+(, z-, z+) (a slanted face counts with its projections).

A particle file (``geometry: {type: particles, file: ...}``) lists positions
and volumes: CSV with a header naming the columns ``x, y(, z), volume``
(any order, more columns ignored), or HDF5 with datasets ``position`` (n,
dim) and ``volume`` (n,).

Every problem raises :class:`GeometryFileError` with a message saying what
was expected; the input's validation turns it into a ConfigError naming the
key. Files are read once per process (cached by path, size and mtime).
"""
import csv
import hashlib
import itertools
import os

import numpy as np

#: element types seeded, per grid dimension (meshio's names)
SUPPORTED = {2: ("triangle", "quad"), 3: ("tetra", "hexahedron")}
#: topological dimension of meshio's cell types, by name prefix
_TOPOLOGY = (("vertex", 0), ("line", 1), ("triangle", 2), ("quad", 2), ("polygon", 2),
             ("tetra", 3), ("hexahedron", 3), ("wedge", 3), ("pyramid", 3))
#: facets of each element (meshio/VTK node order)
FACETS = {
    "triangle": ((0, 1), (1, 2), (2, 0)),
    "quad": ((0, 1), (1, 2), (2, 3), (3, 0)),
    "tetra": ((0, 1, 2), (0, 1, 3), (1, 2, 3), (0, 2, 3)),
    "hexahedron": ((0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6),
                   (3, 0, 4, 7)),
}
GAUSS2 = (np.array([-1.0, 1.0]) / np.sqrt(3.0), np.array([1.0, 1.0]))
#: a 2D mesh's z coordinates must be zero up to this fraction of its extent
PLANAR_TOLERANCE = 1e-9
_CACHE = {}


class GeometryFileError(Exception):
    """A geometry file that cannot be used (the message says why)."""


def topological_dimension(cell_type):
    for prefix, d in _TOPOLOGY:
        if cell_type.startswith(prefix):
            return d
    return None


def file_digest(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def check_file(path):
    if not os.path.exists(path):
        raise GeometryFileError("not found")
    if not os.path.isfile(path):
        raise GeometryFileError("is not a regular file")
    if not os.access(path, os.R_OK):
        raise GeometryFileError("is not readable")


def cached(kind, path, reader):
    st = os.stat(path)
    key = (kind, os.path.realpath(path), st.st_size, st.st_mtime_ns)
    if key not in _CACHE:
        _CACHE.clear()  # one file at a time is plenty
        _CACHE[key] = reader()
    return _CACHE[key]


# ----------------------------------------------------------------------------- meshes

class Mesh:
    """Points (n, dim) and element blocks [(meshio type, connectivity (m, k))]."""

    def __init__(self, points, blocks):
        self.points = points
        self.blocks = blocks

    @property
    def element_count(self):
        return sum(len(c) for _, c in self.blocks)

    def corners(self, cell_type, connectivity, scale=1.0, offset=0.0):
        return self.points[connectivity] * scale + offset


def read_mesh(path, dim):
    """The volume elements of the mesh file for a ``dim``-dimensional grid
    (lower-dimensional cells such as boundary lines are ignored)."""
    check_file(path)
    return cached(("mesh", dim), path, lambda: _read_mesh(path, dim))


def meshio_read(path, expected):
    """meshio's mesh of the file; GeometryFileError naming meshio's reason
    and the ``expected`` kind of file otherwise."""
    import meshio
    try:
        return meshio.read(path)
    except (Exception, SystemExit) as err:  # meshio calls sys.exit on some files
        text = str(err).strip().splitlines()
        reason = text[0] if text else type(err).__name__
        raise GeometryFileError(f"meshio cannot read it ({reason}): expected {expected}") from None


def _read_mesh(path, dim):
    mesh = meshio_read(path, "a volume mesh file (Gmsh .msh, VTK .vtk/.vtu, Abaqus .inp, ...)")
    points = np.asarray(mesh.points, dtype=float)
    if points.ndim != 2 or points.shape[0] == 0:
        raise GeometryFileError("has no points: expected a volume mesh")
    if not np.all(np.isfinite(points)):
        raise GeometryFileError("has non-finite point coordinates")
    found = {}
    for block in mesh.cells:
        found[block.type] = found.get(block.type, 0) + len(block.data)
    volume_types = {t: n for t, n in found.items() if topological_dimension(t) == dim}
    higher = {t: n for t, n in found.items()
              if topological_dimension(t) is not None and topological_dimension(t) > dim}
    listing = ", ".join(f"{n} {t}" for t, n in found.items()) or "no cells"
    wanted = " and ".join(SUPPORTED[dim])
    if higher:
        raise GeometryFileError(f"is a {max(topological_dimension(t) for t in higher)}D mesh "
                                f"({listing}): expected {wanted} for a {dim}D grid")
    unsupported = [t for t in volume_types if t not in SUPPORTED[dim]]
    if unsupported or not volume_types:
        raise GeometryFileError(f"has {listing}: expected {wanted} (linear elements) for a "
                                f"{dim}D grid" + (f"; {', '.join(unsupported)} not supported"
                                                 if unsupported else ""))
    if points.shape[1] < dim:
        raise GeometryFileError(f"has {points.shape[1]}D points: expected {dim}D")
    if dim == 2 and points.shape[1] == 3:
        extent = float(np.max(np.ptp(points[:, :2], axis=0)))
        z = float(np.max(np.abs(points[:, 2])))
        if z > PLANAR_TOLERANCE * max(extent, 1e-300):
            raise GeometryFileError(f"has points with z up to {z:.6g}: expected a planar mesh "
                                    f"in the z = 0 plane for a 2D grid")
    points = np.ascontiguousarray(points[:, :dim])
    blocks = []
    for block in mesh.cells:
        if block.type in SUPPORTED[dim]:
            conn = np.asarray(block.data, dtype=np.int64)
            if conn.size and (conn.min() < 0 or conn.max() >= len(points)):
                raise GeometryFileError(f"has {block.type} cells that refer to missing points")
            blocks.append((block.type, conn))
    return Mesh(points, blocks)


def _kuhn_parts(dim, n):
    """Barycentric-free description of the regular subdivision of the Kuhn
    simplex {1 >= u_1 >= ... >= u_dim >= 0} into n^dim simplices:
    (parts, dim + 1, dim) vertex coordinates in the unit cube."""
    parts = []
    for corner in itertools.product(range(n), repeat=dim):
        for order in itertools.permutations(range(dim)):
            path = [np.array(corner, float)]
            for axis in order:
                step = path[-1].copy()
                step[axis] += 1.0
                path.append(step)
            vertices = np.array(path) / n
            centre = vertices.mean(axis=0)
            if np.all(np.diff(centre) < 0.0):       # inside u_1 > u_2 > ... > u_dim
                parts.append(vertices)
    parts = np.array(parts)
    assert len(parts) == n ** dim
    return parts


def _simplex_map(corners, u):
    """x = v0 + u_1 (v1 - v0) + u_2 (v2 - v1) + ...: the affine map of the
    Kuhn simplex onto the element with vertices ``corners`` (m, dim+1, dim);
    ``u`` (k, dim) -> (m, k, dim)."""
    edges = np.diff(corners, axis=1)                         # (m, dim, dim): v_{i+1} - v_i
    return corners[:, None, 0, :] + np.einsum("kd,mdj->mkj", u, edges)


def _signed_simplex_volume(corners):
    dim = corners.shape[-1]
    edges = corners[:, 1:, :] - corners[:, :1, :]
    return np.linalg.det(edges) / (2.0 if dim == 2 else 6.0)


def _tensor_shape(dim, xi):
    """Bi-/trilinear shape functions and their derivatives at ``xi`` (k, dim)
    in meshio's quad/hexahedron node order: (k, nodes), (k, nodes, dim)."""
    if dim == 2:
        signs = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float)
    else:
        signs = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                          [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], float)
    factors = 1.0 + signs[None, :, :] * xi[:, None, :]       # (k, nodes, dim)
    N = np.prod(factors, axis=2) / 2 ** dim
    dN = np.empty(factors.shape)
    for d in range(dim):
        others = np.prod(np.delete(factors, d, axis=2), axis=2)
        dN[:, :, d] = signs[None, :, d] * others / 2 ** dim
    return N, dN


def _tensor_parts(corners, n):
    """Volumes (m, n^dim) and centroids (m, n^dim, dim) of the n^dim
    parametric slices of quads/hexahedra, and the smallest det J found at
    the corners and Gauss points of every element (m,)."""
    m, nodes, dim = corners.shape
    g, w = GAUSS2
    edges = np.linspace(-1.0, 1.0, n + 1)
    half = 1.0 / n
    lows = np.array(list(itertools.product(edges[:-1], repeat=dim)))[:, ::-1]  # x fastest
    gauss = np.array(list(itertools.product(range(2), repeat=dim)))
    xi = lows[:, None, :] + half * (1.0 + g[gauss][None, :, :])   # (parts, 2^dim, dim)
    weight = np.prod(w[gauss], axis=1) * half ** dim                # (2^dim,)
    N, dN = _tensor_shape(dim, xi.reshape(-1, dim))
    x = np.einsum("kn,mnd->mkd", N, corners)
    J = np.einsum("kna,mnd->mkda", dN, corners)
    detJ = np.linalg.det(J)                                         # (m, parts * 2^dim)
    wk = np.tile(weight, len(lows))
    vol = (detJ * wk).reshape(m, len(lows), -1).sum(axis=2)
    moment = (x * (detJ * wk)[..., None]).reshape(m, len(lows), -1, dim).sum(axis=2)
    corner_xi = np.array(list(itertools.product((-1.0, 1.0), repeat=dim)))
    _, dNc = _tensor_shape(dim, corner_xi)
    detc = np.linalg.det(np.einsum("kna,mnd->mkda", dNc, corners))
    smallest = np.minimum(detJ.min(axis=1), detc.min(axis=1))
    return vol, moment / vol[..., None], smallest


def element_parts(cell_type, corners, n):
    """(volumes (m, n^dim), centroids (m, n^dim, dim), smallest det J (m,)
    or signed volume for simplices) of the elements' parts."""
    m, _, dim = corners.shape
    if cell_type in ("triangle", "tetra"):
        parts = _kuhn_parts(dim, n)                              # (n^dim, dim+1, dim)
        centre = parts.mean(axis=1)
        signed = _signed_simplex_volume(corners)
        vol = np.repeat((signed / n ** dim)[:, None], len(parts), axis=1)
        return vol, _simplex_map(corners, centre), signed
    return _tensor_parts(corners, n)


def facet_parts(corners, n, axisymmetric):
    """Vector areas (f, n^(dim-1), dim) and centroids of the n^(dim-1) parts
    of boundary facets with vertices ``corners`` (f, k, dim), oriented by the
    vertex order (right-hand rule); in axisymmetry (2D, x = r) the areas of
    revolution."""
    f, k, dim = corners.shape
    if dim == 2:
        t = np.linspace(0.0, 1.0, n + 1)
        a = corners[:, None, 0, :] + t[None, :-1, None] * (corners[:, None, 1, :] - corners[:, None, 0, :])
        b = corners[:, None, 0, :] + t[None, 1:, None] * (corners[:, None, 1, :] - corners[:, None, 0, :])
        d = b - a
        area = np.stack([d[..., 1], -d[..., 0]], axis=-1)      # the edge's right-hand normal x length
        centre = 0.5 * (a + b)
        if axisymmetric:
            area = area * (2.0 * np.pi * centre[..., :1])        # exact for a straight edge
        return area, centre
    if k == 3:
        parts = _kuhn_parts(2, n)                                # (n^2, 3, 2)
        verts = _simplex_map(corners, parts.reshape(-1, 2)).reshape(f, len(parts), 3, 3)
        area = 0.5 * np.cross(verts[:, :, 1] - verts[:, :, 0], verts[:, :, 2] - verts[:, :, 0])
        # a Kuhn part may have the reversed orientation: align it with the facet's
        whole = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        sign = np.sign(np.einsum("fpd,fd->fp", area, whole))
        return area * sign[..., None], verts.mean(axis=2)
    # bilinear quadrilateral facet: n x n parametric parts, 2 x 2 Gauss points each
    g, w = GAUSS2
    edges = np.linspace(-1.0, 1.0, n + 1)
    half = 1.0 / n
    lows = np.array(list(itertools.product(edges[:-1], repeat=2)))[:, ::-1]
    gauss = np.array(list(itertools.product(range(2), repeat=2)))
    xi = (lows[:, None, :] + half * (1.0 + g[gauss][None, :, :])).reshape(-1, 2)
    weight = np.tile(np.prod(w[gauss], axis=1) * half ** 2, len(lows))
    N, dN = _tensor_shape(2, xi)
    x = np.einsum("kn,fnd->fkd", N, corners)
    tangents = np.einsum("kna,fnd->fkad", dN, corners)
    normal = np.cross(tangents[:, :, 0], tangents[:, :, 1]) * weight[None, :, None]
    area = normal.reshape(f, len(lows), -1, 3).sum(axis=2)
    centre = (x * np.linalg.norm(normal, axis=-1, keepdims=True)).reshape(f, len(lows), -1, 3).sum(axis=2)
    centre /= np.linalg.norm(normal, axis=-1).reshape(f, len(lows), -1).sum(axis=2)[..., None]
    return area, centre


def boundary_facets(blocks):
    """[(block index, element index (b,), local facet index (b,))] of the
    facets that belong to one element only."""
    keys, owners = [], []
    for bi, (cell_type, conn) in enumerate(blocks):
        for fi, local in enumerate(FACETS[cell_type]):
            nodes = np.sort(conn[:, local], axis=1)
            width = nodes.shape[1]
            keys.append(np.pad(nodes, ((0, 0), (0, 4 - width)), constant_values=-1))
            owners.append(np.stack([np.full(len(conn), bi), np.arange(len(conn)),
                                    np.full(len(conn), fi)], axis=1))
    keys, owners = np.concatenate(keys), np.concatenate(owners)
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    single = counts[inverse.ravel()] == 1
    return owners[single]


class MeshSeeds:
    """Every particle of a mesh body (all ranks compute all; the caller keeps
    its own): x (n, dim), volume (n,), surface (n, 2 dim), id (n,) (element
    order), half_size (n, dim)."""

    def __init__(self, x, volume, surface, local_id):
        self.x, self.volume, self.surface, self.local_id = x, volume, surface, local_id
        self.half_size = np.repeat(0.5 * volume[:, None] ** (1.0 / x.shape[1]), x.shape[1], axis=1)


def check_orientation(mesh, n):
    """(element index, type, smallest det J or signed volume, how many) of
    the first inverted or degenerate element, or None."""
    offset = 0
    for cell_type, conn in mesh.blocks:
        _, _, smallest = element_parts(cell_type, mesh.points[conn], 1)
        bad = np.flatnonzero(smallest <= 0.0)
        if len(bad):
            return offset + int(bad[0]), cell_type, float(smallest[bad[0]]), len(bad)
        offset += len(conn)
    return None


def seed_mesh(mesh, n, scale=1.0, offset=0.0, axisymmetric=False):
    """The particles of a mesh body: ``MeshSeeds``."""
    dim = mesh.points.shape[1]
    points = mesh.points * scale + np.asarray(offset, float)
    xs, vols, ids, surfaces = [], [], [], []
    per = n ** dim
    first = 0
    block_first = []
    for cell_type, conn in mesh.blocks:
        corners = points[conn]
        vol, centre, _ = element_parts(cell_type, corners, n)
        xs.append(centre.reshape(-1, dim))
        vols.append(vol.reshape(-1))
        ids.append(first * per + np.arange(len(conn) * per))
        block_first.append(first)
        first += len(conn)
    x, volume, local_id = np.concatenate(xs), np.concatenate(vols), np.concatenate(ids)
    surface = np.zeros((len(x), 2 * dim))
    boundary = boundary_facets(mesh.blocks)
    for bi, (cell_type, conn) in enumerate(mesh.blocks):
        owners = boundary[boundary[:, 0] == bi]
        if not len(owners):
            continue
        elements, facets = owners[:, 1], owners[:, 2]
        local = np.array(FACETS[cell_type])[facets]             # (b, k)
        corners = points[conn[elements[:, None], local]]          # (b, k, dim)
        area, centre = facet_parts(corners, n, axisymmetric)      # (b, parts, dim)
        # outward: away from the element's centroid
        middle = points[conn[elements]].mean(axis=1)
        outward = np.sign(np.einsum("bpd,bd->bp", area, corners.mean(axis=1) - middle))
        area = area * outward[..., None]
        # the nearest particle of the same element
        rows = (block_first[bi] + elements)[:, None] * per + np.arange(per)[None, :]  # (b, per)
        candidates = x[rows]                                       # (b, per, dim)
        distance = np.linalg.norm(centre[:, :, None, :] - candidates[:, None, :, :], axis=-1)
        target = np.take_along_axis(rows, np.argmin(distance, axis=2), axis=1)  # (b, parts)
        for d in range(dim):
            np.add.at(surface[:, 2 * d], target.ravel(), np.maximum(-area[..., d], 0.0).ravel())
            np.add.at(surface[:, 2 * d + 1], target.ravel(), np.maximum(area[..., d], 0.0).ravel())
    return MeshSeeds(x, volume, surface, local_id)


def mesh_summary(mesh, n, scale=1.0, offset=0.0):
    """(elements, particles, volume, lower, upper) after scale and offset."""
    points = mesh.points * scale + np.asarray(offset, float)
    dim = points.shape[1]
    used = np.unique(np.concatenate([c.ravel() for _, c in mesh.blocks]))
    volume = 0.0
    for cell_type, conn in mesh.blocks:
        vol, _, _ = element_parts(cell_type, points[conn], 1)
        volume += float(vol.sum())
    return (mesh.element_count, mesh.element_count * n ** dim, volume,
            points[used].min(axis=0), points[used].max(axis=0))


# ----------------------------------------------------------------------------- particle files

def read_particle_file(path, dim):
    """(positions (n, dim), volumes (n,)) from a CSV or HDF5 particle file."""
    check_file(path)
    return cached(("particles", dim), path, lambda: _read_particle_file(path, dim))


#: the most particles a particle file may declare (an absurd declared shape is
#: refused before anything is read)
MAX_FILE_PARTICLES = 10**8


def _read_hdf5_particles(path, dim):
    """'position' (n, dim) and 'volume' (n,) of an HDF5 particle file; a
    GeometryFileError for anything else: groups, links to nowhere, strings
    or compound types where numbers belong, absurd declared shapes, a file
    h5py cannot read (issue 32: these were tracebacks)."""
    import h5py
    out = {}
    try:
        with h5py.File(path, "r") as f:
            for name, ndim in (("position", 2), ("volume", 1)):
                if name not in f:
                    raise GeometryFileError(f"has {sorted(f.keys())}: expected the datasets 'position' "
                                            f"(n, {dim}) and 'volume' (n,)")
                obj = f[name]
                if not isinstance(obj, h5py.Dataset):
                    raise GeometryFileError(f"has a {type(obj).__name__.lower()} '{name}': expected a "
                                            f"dataset of numbers")
                if obj.dtype.kind not in "iuf":
                    raise GeometryFileError(f"has '{name}' of type {obj.dtype}: expected numbers")
                if obj.ndim != ndim or (obj.shape[0] if obj.ndim else 0) > MAX_FILE_PARTICLES:
                    raise GeometryFileError(f"has '{name}' of shape {obj.shape}: expected "
                                            f"{'(n, %d)' % dim if ndim == 2 else '(n,)'} with n <= "
                                            f"{MAX_FILE_PARTICLES}")
                out[name] = np.asarray(obj[...], dtype=float)
    except GeometryFileError:
        raise
    except (OSError, RuntimeError, KeyError, ValueError, TypeError) as err:
        detail = " ".join(str(err).split())
        raise GeometryFileError(f"is not a readable HDF5 particle file ({type(err).__name__}: {detail})") from None
    return out["position"], out["volume"]


def _read_particle_file(path, dim):
    axes = "xyz"[:dim]
    if path.lower().endswith((".h5", ".hdf5", ".hdf")):
        x, volume = _read_hdf5_particles(path, dim)
        if x.ndim != 2 or x.shape[1] != dim or volume.shape != (len(x),):
            raise GeometryFileError(f"has position {x.shape} and volume {volume.shape}: expected "
                                    f"(n, {dim}) and (n,)")
    else:
        try:
            with open(path, newline="", encoding="utf-8-sig") as f:   # (a byte-order mark is not a column)
                rows = [r for r in csv.reader(f) if r and not r[0].lstrip().startswith("#")]
        except (OSError, UnicodeDecodeError) as err:
            raise GeometryFileError(f"cannot be read ({err})") from None
        except csv.Error as err:           # a field of more than 131072 characters, a NUL byte
            raise GeometryFileError(f"is not a CSV file of numbers ({err})") from None
        if not rows:
            raise GeometryFileError(f"is empty: expected a CSV header {', '.join(axes)}, volume")
        header = [h.strip().lower() for h in rows[0]]
        missing = [c for c in (*axes, "volume") if c not in header]
        if missing:
            raise GeometryFileError(f"has the columns {', '.join(header)}: expected a CSV header "
                                    f"with {', '.join(axes)}, volume (missing {', '.join(missing)})")
        columns = [header.index(c) for c in (*axes, "volume")]
        try:
            data = np.array([[float(r[c]) for c in columns] for r in rows[1:]], dtype=float)
        except (ValueError, IndexError) as err:
            raise GeometryFileError(f"has a row that is not {len(header)} numbers ({err})") from None
        data = data.reshape(-1, dim + 1)
        x, volume = data[:, :dim], data[:, dim]
    if len(x) == 0:
        raise GeometryFileError("lists no particles")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(volume))):
        raise GeometryFileError("has non-finite positions or volumes")
    if np.any(volume <= 0.0):
        i = int(np.flatnonzero(volume <= 0.0)[0])
        raise GeometryFileError(f"has a volume <= 0 (particle {i}: {volume[i]:g}): expected "
                                f"positive volumes")
    return np.ascontiguousarray(x), np.ascontiguousarray(volume)
