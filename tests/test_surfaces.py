"""Tools of any shape (pimpm.surfaces; kind MESH of pimpm.kernels.contact):
the signed distance of a surface mesh, its gradient and Hessian, the
orientation checks, the boundary of a volume mesh, and whole runs against
the same tool given analytically."""
import csv
import itertools
import os
import subprocess
import sys

import numpy as np
import pytest

from pimpm import meshes, surfaces
from pimpm.kernels import contact as kernels

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(HERE, "mpi"))
from surface_shapes import ball_polygon, ball_polyhedron, write_surface  # noqa: E402


def _cube_triangles():
    """The unit cube's 12 triangles, outward (point index 4x + 2y + z)."""
    points = np.array(list(itertools.product([0, 1], [0, 1], [0, 1])), float)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return points, np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])


def _distance(kind, params, y, dim, face=-1):
    n, H = np.empty(3), np.empty((3, 3))
    point = np.zeros(3)
    point[:dim] = y
    phi = kernels.tool_distance(kind, params, point, dim, n, H, face)
    return phi, n[:dim].copy(), H[:dim, :dim].copy()


@pytest.mark.parametrize("dim", [2, 3])
def test_a_box_as_a_surface_mesh_is_the_box(dim):
    """Distance, normal and Hessian of a square's outline (a cube's
    triangles) equal the analytic box's at random points inside and out:
    faces, edges and corners, with and without the face a point meets."""
    if dim == 2:
        points = np.array([[0.0, 1.0], [1.0, 1.0], [1.0, 2.0], [0.0, 2.0]])
        facets = np.array([[0, 1], [1, 2], [2, 3], [3, 0]])
        lower, upper = [0.0, 1.0], [1.0, 2.0]
    else:
        points, facets = _cube_triangles()
        lower, upper = [0.0] * 3, [1.0] * 3
    surfaces.check_surface(points, facets)
    mesh = surfaces.pack(points, facets, dim, 1e-3)
    box = np.zeros(12)
    box[:dim], box[3:3 + dim], box[11] = lower, upper, 1e-3
    rng = np.random.default_rng(1)
    worst = 0.0
    for y in rng.uniform(-1.0, 3.0, (3000, dim)):
        for a, b in zip(_distance(kernels.MESH, mesh, y, dim), _distance(kernels.BOX, box, y, dim)):
            worst = max(worst, float(np.max(np.abs(np.asarray(a) - b))))
    assert worst < 1e-14
    # the face a particle meets the tool through: its bottom face, even where a point
    # just inside is nearer the side (the box tool's rule, contact_faces)
    x = np.array([[0.5] * (dim - 1) + [lower[-1] - 0.3], [0.999] * (dim - 1) + [lower[-1] - 0.3]])
    faces = {}
    for kind, params in ((kernels.MESH, mesh), (kernels.BOX, box)):
        found = np.empty(2, dtype=np.int64)
        kernels.contact_faces(kind, params, x, np.zeros(dim), found)
        faces[kind] = found
    assert np.all(faces[kernels.MESH] >= 0)
    corner = np.array([0.9999] * (dim - 1) + [lower[-1] + 0.0005])     # inside, nearer the side face
    for kind, params in ((kernels.MESH, mesh), (kernels.BOX, box)):
        phi, n, _ = _distance(kind, params, corner, dim, faces[kind][1])
        assert phi == pytest.approx(-0.0005, abs=1e-12) and n[-1] == -1.0
        phi_free, _, _ = _distance(kind, params, corner, dim)
        assert phi_free == pytest.approx(-0.0001, abs=1e-12)          # the side, without the face


@pytest.mark.parametrize("dim", [2, 3])
def test_the_gradient_and_hessian_of_a_curved_mesh_are_its_distance_derivatives(dim):
    """On a ball's polygon (polyhedron: faces, edges, vertices) and a
    non-convex L-shaped outline, the normal is the gradient of the signed
    distance and the Hessian the gradient of the normal (central
    differences), wherever the nearest feature does not change within the
    stencil (all but a few of the random points), inside and out; the sign
    is that of the exact shape's distance."""
    rng = np.random.default_rng(2)
    shapes = []
    if dim == 2:
        shapes.append(ball_polygon([0.5, 0.5], 0.4, 12))
        shapes.append((np.array([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]], float),
                       np.array([[0, 1], [1, 2], [2, 3], [3, 4], [4, 5], [5, 0]])))
    else:
        shapes.append(ball_polyhedron([0.5, 0.5, 0.5], 0.4, 1))
    for points, facets in shapes:
        surfaces.check_surface(points, facets)
        params = surfaces.pack(points, facets, dim, 1e-3)
        h = 1e-6
        errors, sign_errors = [], 0
        for y in rng.uniform(points.min(axis=0) - 0.5, points.max(axis=0) + 0.5, (800, dim)):
            phi, n, H = _distance(kernels.MESH, params, y, dim)
            dphi, dn = np.empty(dim), np.empty((dim, dim))
            for a in range(dim):
                e = np.zeros(dim)
                e[a] = h
                plus, minus = _distance(kernels.MESH, params, y + e, dim), _distance(kernels.MESH, params, y - e, dim)
                dphi[a] = (plus[0] - minus[0]) / (2 * h)
                dn[:, a] = (plus[1] - minus[1]) / (2 * h)
            errors.append(max(np.max(np.abs(dphi - n)), np.max(np.abs(dn - H)) * min(abs(phi), 1.0)))
            if len(points) == 6 and dim == 2:   # the L: inside when in the unit squares
                inside = (0 < y[0] < 2 and 0 < y[1] < 1) or (0 < y[0] < 1 and 0 < y[1] < 2)
                sign_errors += inside != (phi < 0.0)
            else:                               # inside the inscribed ball; outside the ball
                r = np.linalg.norm(y - 0.5)
                sign_errors += (r < 0.2 and phi >= 0.0) or (r > 0.4 and phi <= 0.0)
        errors = np.array(errors)
        assert sign_errors == 0
        assert np.mean(errors < 1e-5) > 0.97, np.sort(errors)[-30:]


def test_orientation_and_shape_of_a_surface_are_checked():
    """Degenerate facets, segments that run both ways, branches, triangles
    that run an edge the same way, non-manifold edges: each one message."""
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    cases = [
        (square, [[0, 1], [1, 1]], "degenerate facet"),
        (square, [[0, 1], [2, 1]], "two segments end"),
        (square, [[0, 1], [0, 2]], "two segments start"),
    ]
    cube, triangles = _cube_triangles()
    flipped = triangles.copy()
    flipped[0] = flipped[0][::-1]
    cases.append((cube, flipped, "in the same direction"))
    fin = np.vstack([triangles, [[0, 3, 1]], [[3, 0, 7]]])       # a third triangle on edge 0-3
    cases.append((cube, fin, "more than two triangles"))
    for points, facets, message in cases:
        with pytest.raises(meshes.GeometryFileError, match=message):
            surfaces.check_surface(points, np.asarray(facets))
    surfaces.check_surface(cube, triangles)


def test_the_boundary_of_a_volume_mesh_points_out(tmp_path):
    """A rigid volume mesh's contact surface is its boundary, each facet
    turned away from its element: the distance of the plate-with-a-hole
    mesh is negative inside its elements and positive in the hole and
    outside; a tetrahedral cube's boundary is the cube's."""
    mesh = meshes.read_mesh(os.path.join(REPO, "inputs", "plate_with_hole.msh"), 2)
    points, facets = surfaces.mesh_boundary(mesh)
    surfaces.check_surface(points, facets)
    params = surfaces.pack(points, facets, 2, 1e-3)
    seeds = meshes.seed_mesh(mesh, 2)
    inside = np.empty(len(seeds.x))
    kernels.point_distances(kernels.MESH, params, seeds.x, inside)
    assert np.all(inside < 0.0)
    lower, upper = mesh.points.min(axis=0), mesh.points.max(axis=0)
    outside = np.array([upper + 0.1, lower - 0.1])
    beyond = np.empty(2)
    kernels.point_distances(kernels.MESH, params, outside, beyond)
    assert np.all(beyond > 0.0)
    # a cube of 6 tetrahedra (Kuhn): its boundary is the cube
    cube, _ = _cube_triangles()
    tets = np.array([[0, 4, 6, 7], [0, 4, 5, 7], [0, 1, 5, 7], [0, 1, 3, 7], [0, 2, 3, 7], [0, 2, 6, 7]])
    corners = cube[tets]
    volume = np.einsum("ij,ij->i", np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]),
                       corners[:, 3] - corners[:, 0])
    tets[volume < 0] = tets[volume < 0][:, [0, 2, 1, 3]]
    points, facets = surfaces.mesh_boundary(meshes.Mesh(cube, [("tetra", tets)]))
    assert len(facets) == 12
    surfaces.check_surface(points, facets)
    params = surfaces.pack(points, facets, 3, 1e-3)
    box = np.zeros(12)
    box[3:6] = 1.0
    for y in np.random.default_rng(4).uniform(-0.5, 1.5, (500, 3)):
        assert _distance(kernels.MESH, params, y, 3)[0] == pytest.approx(_distance(kernels.BOX, box, y, 3)[0],
                                                                        abs=1e-14)


# ----------------------------------------------------------------- whole runs
def _run(config_text, tmp_path, name, settings=()):
    """The history of a run of the input ``config_text`` (with ``--set`` settings)."""
    path = tmp_path / f"{name}.yaml"
    path.write_text(config_text)
    command = [sys.executable, "-m", "pimpm", str(path), "--output", str(tmp_path / name)]
    for setting in settings:
        command += ["--set", setting]
    proc = subprocess.run(command, capture_output=True, text=True, cwd=REPO)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    with open(tmp_path / name / "history.csv") as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0] if k != "wall_time"}


def test_an_inclined_ramp_as_a_line_is_the_half_space(tmp_path):
    """Benchmark 1's inclined ramp as a surface mesh
    (inputs/block_on_incline_surface.yaml, mu = 0.3: inputs/ramp_30.vtk, one
    segment across the grid, an open surface with the half-space's normal)
    against the half-space (inputs/block_on_incline.yaml): the block slides
    the same way, forces and energies within 1e-6 of the half-space's (the
    distance is computed from another point of the line: round-off, which
    the contact penalty and Newton's path amplify to 5e-7 in the forces and
    2e-8 in the energies here, with the inputs' contact_stiffness 30; 8e-9
    with the default 100). The first 50 ms, where the block has slid 3 mm."""
    texts = {}
    for name in ("block_on_incline", "block_on_incline_surface"):
        with open(os.path.join(REPO, "inputs", f"{name}.yaml")) as f:
            texts[name] = (f.read().replace("file: block_on_incline.csv", f"file: {REPO}/inputs/block_on_incline.csv")
                           .replace("file: ramp_30.vtk", f"file: {REPO}/inputs/ramp_30.vtk"))
    assert "type: surface" in texts["block_on_incline_surface"]
    half_space = _run(texts["block_on_incline"], tmp_path, "half_space", ["time.end_time=0.05"])
    line = _run(texts["block_on_incline_surface"], tmp_path, "line", ["time.end_time=0.05"])
    assert len(line["step"]) == len(half_space["step"])
    for key in ("ramp_force_x", "ramp_force_y", "ramp_tangential_force", "kinetic_energy", "frictional_dissipation"):
        scale = np.max(np.abs(half_space[key]))
        assert np.max(np.abs(line[key] - half_space[key])) <= 1e-6 * scale, key


def test_the_plate_as_an_outline_a_quad_mesh_or_an_open_line_lets_go_like_the_box(tmp_path):
    """The rigid plate that lets go (inputs/plate_release.yaml: press 25%,
    withdraw) with its plate given as a closed outline (surface), as a
    one-quad volume mesh, and as its bottom edge alone (an open line, drawn
    the wrong way and turned with flip_normals): the same history as the
    box, to round-off, loading and release."""
    with open(os.path.join(REPO, "inputs", "plate_release.yaml")) as f:
        text = f.read()
    box = "geometry: {type: box, lower: [0.0, 0.8], upper: [1.0, 0.9]}"
    assert box in text
    corners = np.array([[0.0, 0.8], [1.0, 0.8], [1.0, 0.9], [0.0, 0.9]])
    write_surface(str(tmp_path / "outline.vtk"), corners, np.array([[0, 1], [1, 2], [2, 3], [3, 0]]))
    write_surface(str(tmp_path / "bottom.vtk"), corners[[1, 0]], np.array([[0, 1]]))
    import meshio
    meshio.write_points_cells(str(tmp_path / "quad.vtk"), np.pad(corners, ((0, 0), (0, 1))),
                              [("quad", np.array([[0, 1, 2, 3]]))])
    reference = _run(text, tmp_path, "box")
    variants = {
        "outline": f"geometry: {{type: surface, file: {tmp_path / 'outline.vtk'}}}",
        "bottom": f"geometry: {{type: surface, file: {tmp_path / 'bottom.vtk'}, flip_normals: true}}",
        "quad": f"geometry: {{type: mesh, file: {tmp_path / 'quad.vtk'}, particles_per_element: 2}}",
    }
    for name, geometry in variants.items():
        changed = text.replace(box, geometry)
        if name == "quad":
            changed = changed.replace(geometry + "\n    particles_per_cell: 2", geometry)
        history = _run(changed, tmp_path, name)
        for key in ("plate_force_y", "plate_normal_force", "plate_contact_area", "strain_energy"):
            scale = np.max(np.abs(reference[key]))
            assert np.max(np.abs(history[key] - reference[key])) <= 1e-9 * scale, (name, key)
    # it pressed (the exact -291.7 kPa over 0.8 m at 25%) and let go
    assert np.min(reference["plate_force_y"]) < -2.0e5 and reference["plate_force_y"][-1] == 0.0


# ----------------------------------------------------------------- input
def _plate_raw():
    import yaml
    with open(os.path.join(REPO, "inputs", "plate_release.yaml")) as f:
        return yaml.safe_load(f)


def test_bad_surface_input_is_one_clear_message(tmp_path):
    """A surface on a deformable body, contact with a particle file, a
    surface file without segments, one with a branch, a non-boolean
    flip_normals, a missing file: each names the key, the value and what
    was expected (the CLI turns ConfigError into exit status 2, one line)."""
    from pimpm.config import ConfigError, validate
    import meshio
    corners = np.array([[0.0, 0.8], [1.0, 0.8], [1.0, 0.9], [0.0, 0.9]])
    write_surface(str(tmp_path / "outline.vtk"), corners, np.array([[0, 1], [1, 2], [2, 3], [3, 0]]))
    write_surface(str(tmp_path / "branch.vtk"), corners, np.array([[0, 1], [0, 2]]))
    meshio.write_points_cells(str(tmp_path / "quad.vtk"), np.pad(corners, ((0, 0), (0, 1))),
                              [("quad", np.array([[0, 1, 2, 3]]))])
    particles = tmp_path / "points.csv"
    particles.write_text("x,y,volume\n0.5,0.85,0.01\n")
    outline = {"type": "surface", "file": str(tmp_path / "outline.vtk")}
    cases = [
        (0, {"geometry": outline}, "bodies[0].geometry.type = 'surface': expected a surface only on a rigid body"),
        (1, {"geometry": {"type": "particles", "file": str(particles)}, "particles_per_cell": None},
         "bodies[1].contact = 'frictionless': expected bonded with a particles geometry"),
        (1, {"geometry": {"type": "surface", "file": str(tmp_path / "quad.vtk")}},
         "has 1 quad: expected line cells (the tool's surface) for a 2D grid"),
        (1, {"geometry": {"type": "surface", "file": str(tmp_path / "branch.vtk")}},
         "where two segments start"),
        (1, {"geometry": dict(outline, flip_normals="yes")},
         "bodies[1].geometry.flip_normals = 'yes': expected true or false"),
        (1, {"geometry": {"type": "surface", "file": str(tmp_path / "none.vtk")}},
         "bodies[1].geometry.file = "),
    ]
    for index, change, message in cases:
        raw = _plate_raw()
        raw["bodies"][index].update(change)
        raw["bodies"][index] = {k: v for k, v in raw["bodies"][index].items() if v is not None}
        with pytest.raises(ConfigError) as err:
            validate(raw)
        assert message in str(err.value), str(err.value)
    raw = _plate_raw()
    raw["bodies"][1].update(geometry=outline)
    body = validate(raw)["bodies"][1]
    assert body["geometry"]["facets"] == 4
    # its particles (for show) are seeded within a cell of the surface, clipped to the grid
    assert body["geometry"]["lower"] == pytest.approx([0.0, 0.7]) and body["geometry"]["upper"] == pytest.approx([1.0, 1.0])


@pytest.mark.parametrize("dim", [2, 3])
def test_the_hierarchy_finds_the_nearest_facet(dim):
    """The walk down the bounding-volume hierarchy finds what looking at
    every facet finds (one leaf holding them all), near the surface and far
    from it, for a fine polygon (polyhedron) and one divided into long thin
    facets."""
    if dim == 2:
        shapes = [ball_polygon([0.5, 0.5], 0.4, 500)]
        xs = np.linspace(0.0, 39.0, 2001)         # the billet's platen, its bottom in 2000 segments
        points = np.concatenate([np.stack([xs, np.full_like(xs, 20.0)], axis=1), [[39.0, 20.5], [0.0, 20.5]]])
        shapes.append((points, np.stack([np.arange(len(points)), (np.arange(len(points)) + 1) % len(points)], axis=1)))
    else:
        shapes = [ball_polyhedron([0.5, 0.5, 0.5], 0.4, 4)]
    rng = np.random.default_rng(5)
    for points, facets in shapes:
        tree = surfaces.pack(points, facets, dim, 1e-3)
        flat = surfaces.pack(points, facets, dim, 1e-3, leaf_size=len(facets))
        assert tree[15] < len(tree) - 10 * kernels.NODE       # a hierarchy of many nodes
        lower, upper = points.min(axis=0), points.max(axis=0)
        extent = upper - lower
        for y in rng.uniform(lower - 2.0 * extent, upper + 2.0 * extent, (400, dim)):
            phi_tree, n_tree, _ = _distance(kernels.MESH, tree, y, dim)
            phi_flat, n_flat, _ = _distance(kernels.MESH, flat, y, dim)
            assert phi_tree == pytest.approx(phi_flat, rel=1e-13, abs=1e-15)


def test_the_explicit_step_meets_a_floor_line_as_the_half_space(tmp_path):
    """The explicit step's frictionless contact (the same corners and law):
    the block on the floor under tilted gravity (inputs/block_on_ramp.yaml,
    5 ms, about 490 steps) with the floor as a line gives the half-space's
    history to round-off."""
    with open(os.path.join(REPO, "inputs", "block_on_ramp.yaml")) as f:
        text = f.read()
    write_surface(str(tmp_path / "floor.vtk"), np.array([[0.07, 0.005], [-0.01, 0.005]]), np.array([[0, 1]]))
    explicit = ["time.integrator=explicit", "time.dt=null", "time.end_time=0.005", "bodies[1].contact=frictionless",
                "bodies[1].friction_coefficient=null", "output.every=1000"]
    half_space = _run(text, tmp_path, "half_space", explicit)
    line = _run(text, tmp_path, "line", explicit + [f"bodies[1].geometry={{type: surface, file: {tmp_path / 'floor.vtk'}}}"])
    assert len(line["step"]) == len(half_space["step"]) > 400
    for key in ("ramp_force_y", "ramp_normal_force", "kinetic_energy"):
        assert np.max(np.abs(line[key] - half_space[key])) <= 1e-12 * np.max(np.abs(half_space[key])), key
