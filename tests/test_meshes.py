"""Bodies from mesh files (meshio) and particle files (issue 12, pimpm.meshes):
exact volumes and first moments for triangles, quads, tetrahedra and
hexahedra (distorted ones too), surface areas for tractions, one clear error
for each bad file, a mesh of a box that gives the box's results, and 1-rank
= 2-rank answers."""
import itertools
import os

import meshio
import numpy as np
import pytest
import yaml

import petsc4py

petsc4py.init([])
from mpi4py import MPI  # noqa: E402

from helpers import MPIEXEC, run_on_ranks  # noqa: E402
from pimpm import meshes  # noqa: E402
from pimpm.analysis import Analysis  # noqa: E402
from pimpm.config import ConfigError, load_config, validate  # noqa: E402
from pimpm.simulation import Simulation  # noqa: E402

E, NU = 1.0e4, 0.3


# --------------------------------------------------------------------------- meshes of a box

def box_mesh(lower, upper, cells, kind, jitter=0.0, seed=0):
    """Points and cells of a structured mesh of the box: 'quad' or 'triangle'
    (2D), 'hexahedron' or 'tetra' (3D; six Kuhn tetrahedra per hexahedron);
    ``jitter`` moves interior nodes by that fraction of a cell at random."""
    dim = len(lower)
    axes = [np.linspace(lo, hi, n + 1) for lo, hi, n in zip(lower, upper, cells)]
    grid = np.meshgrid(*axes, indexing="ij")
    points = np.stack([g.ravel() for g in grid], axis=1)
    h = (np.asarray(upper, float) - lower) / cells
    interior = np.all((points > np.asarray(lower) + 1e-12) & (points < np.asarray(upper) - 1e-12), axis=1)
    rng = np.random.default_rng(seed)
    points[interior] += jitter * h * rng.uniform(-1.0, 1.0, (interior.sum(), dim))
    shape = [n + 1 for n in cells]
    index = lambda c: np.ravel_multi_index(c, shape)
    corner_order = ([(0, 0), (1, 0), (1, 1), (0, 1)] if dim == 2 else
                    [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)])
    elements = []
    for c in itertools.product(*[range(n) for n in cells]):
        corner = {o: index(tuple(np.add(c, o))) for o in corner_order}
        if kind in ("quad", "hexahedron"):
            elements.append([corner[o] for o in corner_order])
        else:
            for order in itertools.permutations(range(dim)):
                p = [0] * dim
                simplex = [corner[tuple(p)]]
                for axis in order:
                    p[axis] = 1
                    simplex.append(corner[tuple(p)])
                elements.append(simplex)
    elements = np.array(elements)
    if kind in ("triangle", "tetra"):          # positive orientation
        P = points[elements]
        negative = np.linalg.det(P[:, 1:] - P[:, :1]) < 0
        elements[negative, 1], elements[negative, 2] = elements[negative, 2], elements[negative, 1].copy()
    return points, elements


def write_mesh(path, points, blocks):
    if points.shape[1] == 2:
        points = np.c_[points, np.zeros(len(points))]
    meshio.Mesh(points, blocks).write(str(path))
    return str(path)


KINDS = {2: ("triangle", "quad"), 3: ("tetra", "hexahedron")}


@pytest.mark.parametrize("dim, kind", [(2, "triangle"), (2, "quad"), (3, "tetra"), (3, "hexahedron")])
@pytest.mark.parametrize("n", [1, 2, 3])
def test_volume_first_moment_and_surface_of_a_distorted_mesh_are_exact(tmp_path, dim, kind, n):
    lower, upper = [0.0, 0.0, 0.0][:dim], [2.0, 1.0, 1.5][:dim]
    points, cells = box_mesh(lower, upper, [3, 2, 2][:dim], kind, jitter=0.25)
    mesh = meshes.read_mesh(write_mesh(tmp_path / "m.vtu", points, [(kind, cells)]), dim)
    seeds = meshes.seed_mesh(mesh, n)
    volume = np.prod(upper)
    assert len(seeds.x) == len(cells) * n ** dim
    assert seeds.volume.sum() == pytest.approx(volume, rel=1e-13)
    assert np.all(seeds.volume > 0)
    # first moment: the centroid of the box (interior nodes moved, boundary not)
    centroid = (seeds.x * seeds.volume[:, None]).sum(axis=0) / seeds.volume.sum()
    np.testing.assert_allclose(centroid, np.asarray(upper) / 2, rtol=1e-13, atol=1e-14)
    # each particle inside the box, and the surface: each face's area by normal
    assert np.all((seeds.x > 0) & (seeds.x < upper))
    faces = [volume / upper[d] for d in range(dim) for _ in (0, 1)]
    np.testing.assert_allclose(seeds.surface.sum(axis=0), faces, rtol=1e-13)
    # only particles near the boundary carry surface
    carried = seeds.surface.sum(axis=1) > 0
    h = min(np.asarray(upper) / [3, 2, 2][:dim])
    near = np.min(np.minimum(seeds.x, np.asarray(upper) - seeds.x), axis=1)
    assert np.all(near[carried] < 0.9 * h)


@pytest.mark.parametrize("kind", ["triangle", "quad"])
def test_axisymmetric_surface_areas_of_a_mesh_are_areas_of_revolution(tmp_path, kind):
    points, cells = box_mesh([0.0, 0.0], [1.5, 1.0], [3, 2], kind, jitter=0.2)
    mesh = meshes.read_mesh(write_mesh(tmp_path / "m.vtu", points, [(kind, cells)]), 2)
    seeds = meshes.seed_mesh(mesh, 2, axisymmetric=True)
    surface = seeds.surface.sum(axis=0)
    # x- lies on the axis (r = 0): no area; x+: 2 pi r h; y-, y+: pi r^2
    np.testing.assert_allclose(surface, [0.0, 2 * np.pi * 1.5, np.pi * 1.5 ** 2, np.pi * 1.5 ** 2],
                               rtol=1e-13, atol=1e-13)


def test_a_slanted_face_counts_with_its_projections(tmp_path):
    """A triangle with a slanted hypotenuse: its x+ and y+ columns hold the
    hypotenuse's projections; the vector areas of a closed surface add to 0."""
    points = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 1.0]])
    mesh = meshes.read_mesh(write_mesh(tmp_path / "t.vtu", points, [("triangle", np.array([[0, 1, 2]]))]), 2)
    s = meshes.seed_mesh(mesh, 3).surface.sum(axis=0)
    np.testing.assert_allclose(s, [1.0, 1.0, 2.0, 2.0], rtol=1e-14)


def test_mixed_triangles_and_quads_and_lines_are_ignored(tmp_path):
    points, quads = box_mesh([0.0, 0.0], [1.0, 1.0], [2, 2], "quad")
    lines = np.array([[0, 1], [1, 2]])
    points = np.vstack([points, [[-0.5, 0.75]]])
    tris = np.array([[1, 0, 9]])   # on the quads' edge (0, 0)-(0, 0.5), and a new node
    P = points[tris[0]]
    if np.linalg.det(P[1:] - P[:1]) < 0:
        tris = tris[:, [0, 2, 1]]
    path = write_mesh(tmp_path / "mixed.vtu", points, [("quad", quads), ("triangle", tris), ("line", lines)])
    mesh = meshes.read_mesh(path, 2)
    assert [t for t, _ in mesh.blocks] == ["quad", "triangle"]
    area = 1.0 + 0.5 * abs(np.linalg.det(points[tris[0]][1:] - points[tris[0]][:1]))
    assert meshes.seed_mesh(mesh, 2).volume.sum() == pytest.approx(area, rel=1e-14)


# --------------------------------------------------------------------------- bad files

def plain(dim=2, geometry=None, **body):
    raw = {"grid": {"lower": [0.0] * dim, "upper": [4.0] * dim, "cells": [8] * dim},
           "materials": {"m": {"model": "neo_hookean", "youngs_modulus": E, "poisson_ratio": NU,
                               "density": 1.0}},
           "bodies": [{"name": "part", "material": "m", "geometry": geometry, **body}],
           "time": {"integrator": "quasi_static", "dt": 0.1, "end_time": 0.2}}
    return raw


def load(tmp_path, raw):
    path = tmp_path / "input.yaml"
    path.write_text(yaml.safe_dump(raw))
    return load_config(path)


def bad_files(d):
    """name -> (dim, geometry, words of the message): the files are made in ``d``."""
    p2, q2 = box_mesh([0.5, 0.5], [1.5, 1.5], [2, 2], "quad")
    p3, t3 = box_mesh([0.5] * 3, [1.5] * 3, [1, 1, 1], "tetra")
    write_mesh(d / "tets.vtu", p3, [("tetra", t3)])
    write_mesh(d / "lines.vtu", p2, [("line", np.array([[0, 1], [1, 2]]))])
    write_mesh(d / "quad9.vtu", np.vstack([p2, p2[:1]]),
               [("quad9", np.array([[0, 1, 2, 3, 4, 5, 6, 7, 8]]))])
    inverted = q2.copy()
    inverted[2] = inverted[2, ::-1]
    write_mesh(d / "inverted.vtu", p2, [("quad", inverted)])
    write_mesh(d / "ok.vtu", p2, [("quad", q2)])
    bent = np.c_[p2, np.linspace(0.0, 0.1, len(p2))]
    meshio.Mesh(bent, [("quad", q2)]).write(str(d / "bent.vtu"))
    (d / "garbage.msh").write_text("this is not a mesh\n")
    (d / "cloud.csv").write_text("x,y,mass\n1,1,2\n")
    (d / "negative.csv").write_text("x,y,volume\n1,1,0.1\n1.2,1,-0.1\n")
    (d / "words.csv").write_text("x,y,volume\n1,1,abc\n")
    return {
        "missing file": (2, {"type": "mesh", "file": "nope.msh"}, ["bodies[0].geometry.file = 'nope.msh", "not found"]),
        "a directory": (2, {"type": "mesh", "file": "."}, ["not a regular file"]),
        "not a mesh": (2, {"type": "mesh", "file": "garbage.msh"}, ["garbage.msh", "meshio cannot read it"]),
        "a 3D mesh on a 2D grid": (2, {"type": "mesh", "file": "tets.vtu"},
                                   ["tets.vtu", "is a 3D mesh (6 tetra)", "triangle and quad for a 2D grid"]),
        "no volume cells": (2, {"type": "mesh", "file": "lines.vtu"}, ["has 2 line", "expected triangle and quad"]),
        "quadratic elements": (2, {"type": "mesh", "file": "quad9.vtu"}, ["quad9 not supported"]),
        "an inverted element": (2, {"type": "mesh", "file": "inverted.vtu"},
                                ["1 inverted or degenerate element(s), the first quad 2", "positive area"]),
        "a mesh outside the grid": (2, {"type": "mesh", "file": "ok.vtu", "offset": [3.0, 0.0]},
                                    ["bodies[0].geometry.file", "spans [3.5, 4.5] on axis x", "within the grid"]),
        "a 2D mesh out of its plane": (2, {"type": "mesh", "file": "bent.vtu"}, ["z up to 0.1", "z = 0 plane"]),
        "a 2D mesh on a 3D grid": (3, {"type": "mesh", "file": "ok.vtu"}, ["has 4 quad", "tetra and hexahedron"]),
        "zero particles per element": (2, {"type": "mesh", "file": "ok.vtu", "particles_per_element": 0},
                                       ["bodies[0].geometry.particles_per_element = 0", "integer >= 1"]),
        "a negative scale": (2, {"type": "mesh", "file": "ok.vtu", "scale": -1.0},
                             ["bodies[0].geometry.scale = -1.0", "positive"]),
        "a particle file without volumes": (2, {"type": "particles", "file": "cloud.csv"},
                                            ["cloud.csv", "missing volume"]),
        "a negative particle volume": (2, {"type": "particles", "file": "negative.csv"},
                                       ["particle 1: -0.1", "positive volumes"]),
        "a word for a number": (2, {"type": "particles", "file": "words.csv"}, ["not 3 numbers"]),
    }


def test_each_bad_geometry_file_is_named(tmp_path):
    for name, (dim, geometry, wanted) in bad_files(tmp_path).items():
        with pytest.raises(ConfigError) as info:
            load(tmp_path, plain(dim, geometry))
        message = str(info.value)
        assert "\n" not in message, name
        for text in wanted:
            assert text in message, (name, text, message)


def test_particles_per_cell_with_a_mesh_is_refused(tmp_path):
    bad_files(tmp_path)
    with pytest.raises(ConfigError, match=r"bodies\[0\]\.particles_per_cell = 2: expected no "
                                          r"particles_per_cell with a mesh geometry"):
        load(tmp_path, plain(2, {"type": "mesh", "file": "ok.vtu"}, particles_per_cell=2))


def test_traction_on_a_particle_cloud_is_refused(tmp_path):
    (tmp_path / "c.csv").write_text("x,y,volume\n1,1,0.1\n")
    raw = plain(2, {"type": "particles", "file": "c.csv"})
    raw["loads"] = [{"type": "traction", "body": "part", "normal": "x+", "traction": [1, 0]}]
    with pytest.raises(ConfigError, match="a particle cloud has no faces"):
        load(tmp_path, raw)


def test_relative_files_start_at_the_input_files_directory(tmp_path, monkeypatch):
    p2, q2 = box_mesh([0.5, 0.5], [1.5, 1.5], [2, 2], "quad")
    (tmp_path / "meshes").mkdir()
    write_mesh(tmp_path / "meshes" / "part.vtu", p2, [("quad", q2)])
    (tmp_path / "case").mkdir()
    monkeypatch.chdir(tmp_path / "case")
    config = load(tmp_path, plain(2, {"type": "mesh", "file": "meshes/part.vtu"}))
    geometry = config["bodies"][0]["geometry"]
    assert geometry["file"] == str(tmp_path / "meshes" / "part.vtu")
    assert geometry["volume"] == pytest.approx(1.0) and geometry["elements"] == 4
    assert geometry["particles"] == 16 and len(geometry["sha256"]) == 64


# --------------------------------------------------------------------------- simulations

def squeeze(geometry, dim=2, **body):
    """A block on a fixed floor pressed by a traction and its weight."""
    raw = plain(dim, geometry, **body)
    raw["grid"].update(cells=[16] * dim, boundary={"ymin": "fixed"})
    raw["functions"] = {"ramp": {"type": "ramp", "start": 0.0, "end": 0.2}}
    raw["loads"] = [{"name": "press", "type": "traction", "body": "part", "normal": "y+",
                     "traction": [0.0, -0.03 * E] + [0.0] * (dim - 2), "function": "ramp"},
                    {"name": "weight", "type": "body_force", "body": "part",
                     "acceleration": [20.0, -10.0] + [0.0] * (dim - 2)}]
    raw["time"].update(end_time=0.2, dt=0.05)
    return raw


def by_reference_position(particles):
    x0 = particles["position"] - particles["displacement"]
    order = np.lexsort(np.round(x0, 9).T[::-1])
    return {k: v[order] for k, v in particles.items()}


def run_in_process(raw):
    sim = Simulation(validate(raw), MPI.COMM_WORLD)
    assert Analysis(sim).run() == 0
    return sim


@pytest.mark.parametrize("dim", [2, 3])
def test_a_mesh_of_the_box_gives_the_boxs_answer(tmp_path, dim):
    """Elements = grid cells and 2 particles per element and axis: the same
    particles as the box with particles_per_cell 2, so the same answer."""
    lower, upper = [0.5, 0.0, 0.5][:dim], [2.0, 1.5, 1.25][:dim]
    kind = "quad" if dim == 2 else "hexahedron"
    cells = [int(round((u - l) / 0.25)) for l, u in zip(lower, upper)]
    points, elements = box_mesh(lower, upper, cells, kind)
    path = write_mesh(tmp_path / f"box.vtu", points, [(kind, elements)])
    raws = [squeeze({"type": "box", "lower": lower, "upper": upper}, dim),
            squeeze({"type": "mesh", "file": path, "particles_per_element": 2}, dim)]
    if dim == 3:
        for raw in raws:
            raw["grid"]["cells"] = [10] * dim
            raw["grid"]["upper"] = [2.5] * dim
            raw["time"].update(end_time=0.1)
    sims = [run_in_process(r) for r in raws]
    box, mesh = sims
    comm = MPI.COMM_WORLD
    assert box.particles.global_count(comm) == mesh.particles.global_count(comm)
    key = lambda s: np.lexsort(np.round(s.particles["x0"], 9).T[::-1])
    a, b = key(box), key(mesh)
    np.testing.assert_allclose(box.particles["x0"][a], mesh.particles["x0"][b], atol=1e-13)
    np.testing.assert_allclose(box.particles["volume0"][a], mesh.particles["volume0"][b], rtol=1e-12)
    np.testing.assert_allclose(box.particles["surface"][a], mesh.particles["surface"][b], atol=1e-12)
    scale = np.max(np.abs(box.particles["x"] - box.particles["x0"]))
    assert scale > 1e-3
    np.testing.assert_allclose(box.particles["x"][a], mesh.particles["x"][b], atol=1e-9 * scale)


def test_a_particle_file_gives_the_boxs_answer(tmp_path):
    raw = squeeze({"type": "box", "lower": [0.5, 0.0], "upper": [2.0, 1.5]})
    box = run_in_process(raw)
    x, v = box.particles["x0"], box.particles["volume0"]
    text = "# a particle cloud\nvolume,y,x\n" + "".join(f"{c!r},{b!r},{a!r}\n" for (a, b), c in zip(x, v))
    (tmp_path / "cloud.csv").write_text(text)
    # a spreadsheet's CSV starts with a byte-order mark (issue 32: "missing x")
    (tmp_path / "excel.csv").write_text("\ufeff" + text.split("\n", 1)[1], encoding="utf-8")
    import h5py
    with h5py.File(tmp_path / "cloud.h5", "w") as f:
        f["position"], f["volume"] = x, v
    for name in ("cloud.csv", "excel.csv", "cloud.h5"):
        raw = squeeze({"type": "particles", "file": str(tmp_path / name)})
        raw["loads"] = raw["loads"][1:]      # no traction on a cloud: the weight only
        cloud = run_in_process(raw)
        reference = squeeze({"type": "box", "lower": [0.5, 0.0], "upper": [2.0, 1.5]})
        reference["loads"] = reference["loads"][1:]
        ref = run_in_process(reference)
        key = lambda s: np.lexsort(np.round(s.particles["x0"], 9).T[::-1])
        a, b = key(ref), key(cloud)
        np.testing.assert_allclose(ref.particles["x"][a], cloud.particles["x"][b], rtol=0, atol=1e-12)


def test_a_particle_csv_that_the_csv_reader_refuses_is_one_clear_error(tmp_path):
    """A field of more than 131072 characters made Python's csv reader
    raise csv.Error, a traceback (issue 32's over-long lines; found by
    scripts/reliability_table.py)."""
    (tmp_path / "p.csv").write_text("x,y,volume\n0.5,0.1," + "1" * 200000 + "\n")
    with pytest.raises(meshes.GeometryFileError) as err:
        meshes._read_particle_file(str(tmp_path / "p.csv"), 2)
    assert "is not a CSV file of numbers" in str(err.value)


def test_a_rigid_body_from_a_mesh(tmp_path):
    """A meshed rigid die pushed into a block moves as told and reports a force."""
    points, tris = box_mesh([0.75, 1.6], [1.75, 1.85], [4, 1], "triangle")
    path = write_mesh(tmp_path / "die.vtu", points, [("triangle", tris)])
    raw = plain(2, {"type": "box", "lower": [0.5, 0.0], "upper": [2.0, 1.5]})
    raw["grid"].update(cells=[16, 16], boundary={"ymin": "fixed"})
    raw["bodies"].append({"name": "die", "rigid": True, "velocity": [0.0, -0.5],
                          "geometry": {"type": "mesh", "file": path, "particles_per_element": 2}})
    raw["time"].update(end_time=0.4, dt=0.1)
    sim = run_in_process(raw)
    assert sim.work.total > 0
    moved = sim.rigid["x"] - sim.rigid["x0"]
    np.testing.assert_allclose(moved, np.tile([0.0, -0.2], (len(moved), 1)), atol=1e-12)


@pytest.mark.skipif(MPIEXEC is None, reason="mpiexec not found")
def test_a_distorted_mixed_mesh_gives_the_same_answer_on_1_2_and_3_ranks(tmp_path):
    points, quads = box_mesh([0.5, 0.0], [2.5, 1.0], [4, 2], "quad", jitter=0.2, seed=3)
    tri_points, tris = box_mesh([2.5, 0.0], [3.5, 1.0], [2, 2], "triangle")
    # glue: the triangles' nodes after the quads' (the shared edge x = 2.5 duplicated
    # nodes would make a crack: merge them)
    all_points = np.vstack([points, tri_points])
    _, first, inverse = np.unique(np.round(all_points, 12), axis=0, return_index=True, return_inverse=True)
    merged = all_points[first]
    quads, tris = inverse[quads], inverse[tris + len(points)]
    path = write_mesh(tmp_path / "part.vtu", merged, [("quad", quads), ("triangle", tris)])
    raw = squeeze({"type": "mesh", "file": path, "particles_per_element": 4})
    raw["output"] = {"directory": "out"}
    (one, t1, h1), (two, t2, h2), (three, _, _) = run_on_ranks(tmp_path, raw, [1, 2, 3])
    assert t1 == t2
    np.testing.assert_array_equal(one["id"], two["id"])
    scale = np.max(np.abs(one["displacement"]))
    assert scale > 1e-4
    np.testing.assert_allclose(one["position"], two["position"], rtol=0, atol=1e-8 * scale)
    np.testing.assert_allclose(one["position"], three["position"], rtol=0, atol=1e-8 * scale)
    np.testing.assert_allclose(h1["press_force_y"], h2["press_force_y"], rtol=1e-12)
