"""Tool surfaces from meshes: the oriented facets a rigid tool of any shape
meets the material through (:mod:`pimpm.terms.contact`), packed for the
contact kernels' signed distance (:func:`pimpm.kernels.contact.tool_distance`,
kind MESH).

Two sources:

* a surface mesh (``geometry: {type: surface, file: ...}``): line segments
  in 2D, triangles (quadrilaterals are split in two) in 3D, read with
  meshio. Orientation: each facet's normal points out of the tool, which
  in 2D lies on the left of each segment as it runs from its first to its
  second point (a counter-clockwise outline; the outward normal is the
  direction turned clockwise), and in 3D on the side from which the
  triangle's points do not run counter-clockwise (the normal is
  (b - a) x (c - a)). ``flip_normals: true`` reverses every facet. The
  surface may be open (a die profile, a ramp): its inside is then the side
  the normals point away from, as far as its nearest facet decides;
* the boundary of a rigid volume mesh (``geometry: {type: mesh, ...}`` with
  ``contact: frictionless`` or ``friction``): the facets of one element
  only, each turned to point away from its element.

Every facet is checked (no zero length or area) and so is the orientation
of the whole surface: two facets that share a vertex (2D) or an edge (3D)
must run through it in opposite directions, and no more than two facets may
share it. Problems raise :class:`pimpm.meshes.GeometryFileError`.
"""
import os

import numpy as np

from . import meshes
from .kernels.contact import MESH_HEADER, NODE

#: the last packed tool's params (:func:`surface_params`)
_PACKED = {}
#: surface cells read per grid dimension (meshio's names)
SURFACE_CELLS = {2: ("line",), 3: ("triangle", "quad")}


def read_surface(path, dim):
    """(points (n, dim), facets (m, dim) int) of a surface mesh file."""
    meshes.check_file(path)
    return meshes.cached(("surface", dim), path, lambda: _read_surface(path, dim))


def _read_surface(path, dim):
    mesh = meshes.meshio_read(path, "a surface mesh file (Gmsh .msh, VTK .vtk/.vtu, STL, ...)")
    points = np.asarray(mesh.points, dtype=float)
    wanted = " and ".join(SURFACE_CELLS[dim])
    if points.ndim != 2 or points.shape[0] == 0:
        raise meshes.GeometryFileError(f"has no points: expected {wanted} cells")
    if not np.all(np.isfinite(points)):
        raise meshes.GeometryFileError("has non-finite point coordinates")
    if points.shape[1] < dim:
        raise meshes.GeometryFileError(f"has {points.shape[1]}D points: expected {dim}D")
    if dim == 2 and points.shape[1] == 3:
        extent = float(np.max(np.ptp(points[:, :2], axis=0)))
        z = float(np.max(np.abs(points[:, 2])))
        if z > meshes.PLANAR_TOLERANCE * max(extent, 1e-300):
            raise meshes.GeometryFileError(f"has points with z up to {z:.6g}: expected a planar "
                                           f"surface in the z = 0 plane for a 2D grid")
    facets = []
    for block in mesh.cells:
        if block.type not in SURFACE_CELLS[dim]:
            continue
        conn = np.asarray(block.data, dtype=np.int64)
        if conn.size and (conn.min() < 0 or conn.max() >= len(points)):
            raise meshes.GeometryFileError(f"has {block.type} cells that refer to missing points")
        if block.type == "quad":
            conn = np.concatenate([conn[:, [0, 1, 2]], conn[:, [0, 2, 3]]])
        facets.append(conn)
    if not facets or not sum(len(f) for f in facets):
        found = ", ".join(f"{len(b.data)} {b.type}" for b in mesh.cells) or "no cells"
        raise meshes.GeometryFileError(f"has {found}: expected {wanted} cells (the tool's surface) "
                                       f"for a {dim}D grid")
    return np.ascontiguousarray(points[:, :dim]), np.concatenate(facets)


def mesh_boundary(mesh):
    """(points, facets) of a volume mesh's boundary (:class:`pimpm.meshes.Mesh`),
    each facet turned to point away from its element (quadrilateral faces of
    hexahedra split in two)."""
    points = mesh.points
    dim = points.shape[1]
    facets = []
    for block, element, local in _grouped(mesh):
        cell_type, conn = mesh.blocks[block]
        for fi in np.unique(local):
            rows = element[local == fi]
            facet = conn[rows][:, meshes.FACETS[cell_type][fi]]
            centroid = points[conn[rows]].mean(axis=1)
            parts = [facet] if facet.shape[1] == dim else [facet[:, [0, 1, 2]], facet[:, [0, 2, 3]]]
            for part in parts:
                normal = _normals(points, part)
                inward = np.einsum("ij,ij->i", normal, points[part].mean(axis=1) - centroid) < 0.0
                part = part.copy()
                part[inward] = part[inward][:, ::-1]
                facets.append(part)
    return points, np.concatenate(facets)


def _grouped(mesh):
    """The boundary facets by element block: (block, elements, local facet indices)."""
    owners = meshes.boundary_facets(mesh.blocks)
    for block in np.unique(owners[:, 0]):
        mine = owners[owners[:, 0] == block]
        yield int(block), mine[:, 1], mine[:, 2]


def _normals(points, facets):
    """Each facet's normal, not normalized (its length: the facet's length
    in 2D, twice its area in 3D)."""
    corners = points[facets]
    if facets.shape[1] == 2:
        t = corners[:, 1] - corners[:, 0]
        return np.stack([t[:, 1], -t[:, 0]], axis=1)
    return np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])


def check_surface(points, facets):
    """Raise GeometryFileError unless every facet has a length or area and
    the facets are consistently oriented and manifold."""
    dim = points.shape[1]
    size = np.linalg.norm(_normals(points, facets), axis=1)
    extent = float(np.max(np.ptp(points[np.unique(facets)], axis=0))) if len(facets) else 0.0
    bad = np.flatnonzero(~(size > 1e-12 * max(extent, 1e-300) ** (dim - 1)))
    if len(bad):
        what = "length" if dim == 2 else "area"
        raise meshes.GeometryFileError(f"has {len(bad)} degenerate facet(s) (zero {what}), the first "
                                       f"facet {int(bad[0])}: expected every facet to have a {what}")
    k = facets.shape[1]
    if dim == 2:                        # each point starts at most one segment and ends at most one
        for column, role in ((0, "start"), (1, "end")):
            points_used, counts = np.unique(facets[:, column], return_counts=True)
            if np.any(counts > 1):
                raise meshes.GeometryFileError(
                    f"has {int(np.sum(counts > 1))} point(s) where two segments {role}, the first "
                    f"point {int(points_used[counts > 1][0])}: expected a chain of segments running one "
                    f"way (the tool on their left), no branches")
        return
    directed = np.concatenate([facets[:, [i, (i + 1) % k]] for i in range(k)])
    _, counts = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
    if np.any(counts > 2):
        raise meshes.GeometryFileError(f"has {int(np.sum(counts > 2))} edge(s) shared by more than "
                                       f"two triangles: expected a manifold surface")
    _, counts = np.unique(directed, axis=0, return_counts=True)
    if np.any(counts > 1):
        raise meshes.GeometryFileError(
            f"has {int(np.sum(counts > 1))} edge(s) that two triangles run through in the same "
            f"direction: expected consistently oriented triangles (outward normals)")


def pack(points, facets, dim, edge_tolerance, leaf_size=4):
    """The kernel's params of a MESH tool (:data:`pimpm.kernels.contact.MESH_HEADER`):
    per facet its vertices, unit normal and vertex (and, in 3D, edge)
    pseudo-normals, and the facets' bounding-volume hierarchy
    (facets in its leaves' order; at most ``leaf_size`` facets a leaf).
    ``edge_tolerance``: params[11] (how far beyond a facet's edge a point
    still meets the facet)."""
    m, k = facets.shape
    normal = _normals(points, facets)
    size = np.linalg.norm(normal, axis=1)
    unit = normal / size[:, None]
    corners = points[facets]                                   # (m, k, dim)
    # vertex pseudo-normals: the incident facets' normals weighted by the facet's
    # angle at the vertex (3D; Baerentzen & Aanaes 2005), summed (2D)
    vertex_sum = np.zeros((len(points), dim))
    for i in range(k):
        if k == 2:
            weight = np.ones(m)
        else:
            e1 = corners[:, (i + 1) % k] - corners[:, i]
            e2 = corners[:, (i + 2) % k] - corners[:, i]
            cos = np.einsum("ij,ij->i", e1, e2) / (np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1))
            weight = np.arccos(np.clip(cos, -1.0, 1.0))
        np.add.at(vertex_sum, facets[:, i], weight[:, None] * unit)
    vertex_normal = _unit(vertex_sum)
    records = [_padded(corners.reshape(m, k, dim)), _padded(unit[:, None, :]), _padded(vertex_normal[facets])]
    if k == 3:                          # edge pseudo-normals: the mean of the two facets' normals
        edges = np.concatenate([np.sort(facets[:, [i, (i + 1) % 3]], axis=1) for i in range(3)])
        keys, inverse = np.unique(edges, axis=0, return_inverse=True)
        edge_sum = np.zeros((len(keys), 3))
        np.add.at(edge_sum, inverse.ravel(), np.tile(unit, (3, 1)))
        edge_normal = _unit(edge_sum)[inverse.ravel()].reshape(3, m, 3).transpose(1, 0, 2)
        records.append(_padded(edge_normal))
    body = np.concatenate(records, axis=1)
    order, nodes = _hierarchy(corners.min(axis=1), corners.max(axis=1), leaf_size)
    body = body[order]                          # the leaves' facets contiguous
    params = np.zeros(MESH_HEADER + body.size + nodes.size)
    params[11] = edge_tolerance
    params[12], params[13], params[14] = m, k, body.shape[1]
    params[15] = MESH_HEADER + body.size
    params[MESH_HEADER:MESH_HEADER + body.size] = body.ravel()
    params[MESH_HEADER + body.size:] = nodes.ravel()
    return params


def _hierarchy(lower, upper, leaf_size=4):
    """A bounding-volume hierarchy of boxes (m, dim): the order of the boxes
    and the nodes (n, NODE): box (lower, upper, 3 each), children (-1, -1
    for a leaf), first box and count. Each node splits its boxes at the
    median of their centres along its longest axis."""
    m, dim = lower.shape
    order = np.arange(m)
    centre = 0.5 * (lower + upper)
    nodes = []

    def build(first, end):
        boxes = order[first:end]
        node = len(nodes)
        low, high = np.zeros(3), np.zeros(3)
        low[:dim], high[:dim] = lower[boxes].min(axis=0), upper[boxes].max(axis=0)
        nodes.append(np.concatenate([low, high, [-1, -1, first, end - first]]))
        if end - first > leaf_size:
            axis = int(np.argmax(high - low))
            order[first:end] = boxes[np.argsort(centre[boxes, axis], kind="stable")]
            middle = (first + end) // 2
            nodes[node][6] = build(first, middle)
            nodes[node][7] = build(middle, end)
        return node
    build(0, m)
    nodes = np.array(nodes)
    assert nodes.shape[1] == NODE
    return order, nodes


def _padded(vectors):
    """(m, j, dim) -> (m, 3 j): each vector padded to 3 components."""
    m, j, dim = vectors.shape
    out = np.zeros((m, j, 3))
    out[..., :dim] = vectors
    return out.reshape(m, 3 * j)


def _unit(vectors):
    norm = np.linalg.norm(vectors, axis=1, keepdims=True)
    return np.divide(vectors, norm, out=np.zeros_like(vectors), where=norm > 0.0)


def surface_of(geometry, dim):
    """(points, facets) of a validated ``surface`` or ``mesh`` geometry,
    scaled, offset and oriented."""
    if geometry["type"] == "surface":
        points, facets = read_surface(geometry["file"], dim)
        if geometry.get("flip_normals"):
            facets = facets[:, ::-1]
    elif geometry["type"] == "mesh":
        points, facets = mesh_boundary(meshes.read_mesh(geometry["file"], dim))
    else:
        raise ValueError(f"no surface for a {geometry['type']} geometry")
    points = points * geometry.get("scale", 1.0) + np.asarray(geometry.get("offset", [0.0] * dim), float)
    return np.ascontiguousarray(points), np.ascontiguousarray(facets)


def surface_params(geometry, dim, edge_tolerance):
    """The kernel's params of a ``surface`` or ``mesh`` tool. Packed once per
    file (its size and modification time) and placement: seeding asks
    1 + 2 dim times (the particles, then each face's neighbours) and the
    contact term once more, and packing 40,000 segments takes 0.4 s."""
    status = os.stat(geometry["file"])
    key = (os.path.realpath(geometry["file"]), status.st_size, status.st_mtime_ns, geometry["type"], dim,
           float(geometry.get("scale", 1.0)), tuple(geometry.get("offset", ())), bool(geometry.get("flip_normals")))
    if key not in _PACKED:
        _PACKED.clear()                 # one tool at a time is plenty
        _PACKED[key] = pack(*surface_of(geometry, dim), dim, 0.0)
    params = _PACKED[key].copy()
    params[11] = edge_tolerance
    return params
