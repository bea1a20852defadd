"""The compiled kernels (pimpm.kernels, pimpm.materials) against their
numpy references in tests/reference/: the material points of every model
(materials.py), the plane-stress thickness solve (update.py), the fused
particle evaluation (kinematics, stress, internal force: kinematics.py),
the tangent blocks added into the pattern's values and the matrix-free
product and diagonal (kinematics.element_tangents), and the shape functions
(shape.py). Agreement to round-off (1e-12 relative; 1e-10 where a sum over
many particles enters), in 2D, plane stress, axisymmetric and 3D, for
linear, GIMP and B-spline shape functions, elastic and plastic."""
import numpy as np
import pytest

import petsc4py

petsc4py.init([])
from mpi4py import MPI  # noqa: E402

from reference import kinematics as RK  # noqa: E402
from reference import shape as reference_shape  # noqa: E402
from reference import materials as M  # noqa: E402
from reference.update import material_update, update_stress  # noqa: E402
from pimpm.config import validate  # noqa: E402
from pimpm.implicit.problem import ParticleEvaluation  # noqa: E402
from pimpm.kernels import material_point as mp  # noqa: E402
from pimpm.kernels import particle_step  # noqa: E402
from pimpm.steps import implicit as implicit_step  # noqa: E402
from pimpm.kinematics import PlaneStress  # noqa: E402
from pimpm.materials import MODELS as REGISTRY  # noqa: E402
from pimpm.materials.table import MaterialTable  # noqa: E402
from pimpm.simulation import Simulation  # noqa: E402
from pimpm.transfer import grid_to_particle  # noqa: E402

RNG = np.random.default_rng(7)
PLASTIC = dict(yield_stress=2.0e5, hardening_modulus=1.0e6)
SOFTENING = dict(yield_stress=2.0e5, hardening_modulus=1.0e6, softening_strain=0.01,
                 softening_modulus=5.0e5)
MODELS = [
    M.UncoupledNeoHookean(6e6, 6e7, 10.0), M.CompressibleNeoHookean(6e6, 6e7, 10.0),
    M.SmallStrainElastic(6e6, 6e7, 10.0), M.J2SmallStrain(6e6, 6e7, 10.0, **PLASTIC),
    M.J2SmallStrain(6e6, 6e7, 10.0, **SOFTENING), M.J2FiniteStrain(6e6, 6e7, 10.0, **PLASTIC),
    M.J2FiniteStrain(6e6, 6e7, 10.0, **SOFTENING), M.Hencky(6e6, 6e7, 10.0)]


def random_F(n, scale):
    F = np.eye(3) + scale * RNG.standard_normal((4 * n, 3, 3))
    return F[np.linalg.det(F) > 0.3][:n]


def random_history(material, n):
    """History values at t of the kind a run produces (tensors near 1 or 0,
    non-negative scalars), with some particles already plastic."""
    history = {}
    for name, shape in material.history.items():
        if name == "deformation_gradient":
            history[name] = random_F(n, 0.05)
        elif name == "elastic_left_cauchy_green":
            B = random_F(n, 0.03)
            history[name] = B @ np.swapaxes(B, 1, 2)
        elif shape == (3, 3):
            A = 0.01 * RNG.standard_normal((n, 3, 3))
            history[name] = 0.5 * (A + np.swapaxes(A, 1, 2))
        else:
            history[name] = np.abs(0.01 * RNG.standard_normal(n))
    return history


def relative(a, b):
    return np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300)


def compiled_points(material, F, history, plane_stress=False, F_inc=None):
    n = len(F)
    table = MaterialTable([(material, np.arange(n))], n)
    packed = table.pack(history)
    out = np.zeros_like(packed)
    sigma, c = np.zeros((n, 3, 3)), np.zeros((n, 3, 3, 3, 3))
    F = F.copy()
    F_inc = np.zeros((0, 3, 3)) if F_inc is None else F_inc.copy()
    mp.update_points(table.models, table.params, table.material_of, F, packed, out, sigma, c, True,
                     plane_stress, F_inc)
    return sigma, c, table.unpack(out, history), F, F_inc


@pytest.mark.parametrize("material", MODELS, ids=lambda m: f"{m.name}-{getattr(m, 'softening_strain', np.inf):g}")
def test_material_points_equal_the_numpy_models(material):
    n = 200
    F = random_F(n, 0.2)
    history = random_history(material, n)
    sigma, c, new = material.update(F.copy(), {k: v.copy() for k, v in history.items()}, True)
    sigma_k, c_k, new_k, _, _ = compiled_points(material, F, history)
    assert relative(sigma_k, sigma) < 1e-12
    assert relative(c_k, c) < 1e-12
    for name in material.history:
        assert relative(new_k[name], new[name]) < 1e-12, name
    if "eq_plastic_strain" in history:      # the plastic branch is exercised
        assert np.sum(new["eq_plastic_strain"] > history["eq_plastic_strain"]) > n // 2


@pytest.mark.parametrize("material", [MODELS[0], MODELS[3], MODELS[5], MODELS[7]], ids=lambda m: m.name)
def test_plane_stress_thickness_solve_equals_the_numpy_kinematics(material):
    n = 100
    F = np.zeros((n, 3, 3))
    F[:, :2, :2] = random_F(n, 0.1)[:, :2, :2]
    F[:, 2, 2] = 1.0
    F = F[np.linalg.det(F) > 0.3]
    n = len(F)
    F_inc = F.copy()
    history = random_history(material, n)
    if "deformation_gradient" in history:
        history["deformation_gradient"][:, :2, 2] = history["deformation_gradient"][:, 2, :2] = 0.0
    F_ref, F_inc_ref = F.copy(), F_inc.copy()
    sigma, c, _ = material_update(PlaneStress(), material, F_ref, history, True, F_inc_ref)
    sigma_k, c_k, _, F_k, F_inc_k = compiled_points(material, F, history, True, F_inc)
    # sigma33 = 0 to the solve's tolerance, 1e-13 (|c3333| + max |sigma|)
    assert np.all(np.abs(sigma_k[:, 2, 2]) <= 1e-13 * (np.abs(c_k[:, 2, 2, 2, 2]) + np.abs(sigma_k).max(axis=(1, 2))))
    assert relative(F_k, F_ref) < 1e-12 and relative(F_inc_k, F_inc_ref) < 1e-12
    assert relative(sigma_k, sigma) < 1e-10
    assert relative(c_k[:, :2, :2, :2, :2], c[:, :2, :2, :2, :2]) < 1e-10


def small_simulation(kinematics, shape, model, three_d=False):
    """A few particles of every kind on a small grid, one step taken so that
    F and the history are not trivial; returns the simulation and the
    state of its next step."""
    material = {"model": model, "shear_modulus": 6.0e6, "bulk_modulus": 6.0e7, "density": 10.0}
    if model.startswith("j2"):
        material.update(yield_stress=2.0e5, hardening_modulus=1.0e6)
    raw = {"grid": {"lower": [0.0, 0.0], "upper": [5.0, 4.0], "cells": [10, 8], "shape_functions": shape},
           "kinematics": kinematics,
           "materials": {"m": material},
           "bodies": [{"name": "a", "material": "m", "particles_per_cell": 2, "velocity": [1.0, 2.0],
                       "geometry": {"type": "box", "lower": [0.5, 0.5], "upper": [3.0, 2.5]}}],
           "time": {"integrator": "newmark", "dt": 0.01, "end_time": 1.0}}
    if three_d:
        raw["grid"].update(lower=[0.0, 0.0, 0.0], upper=[2.5, 2.0, 2.0], cells=[5, 4, 4])
        raw["bodies"][0].update(velocity=[1.0, 2.0, -1.0],
                                geometry={"type": "box", "lower": [0.5, 0.5, 0.5], "upper": [1.5, 1.5, 1.5]})
        raw.pop("kinematics")
    sim = Simulation(validate(raw), MPI.COMM_SELF)
    sim.advance(0.01)
    state, _ = implicit_step.prepare(sim, 0.01)
    return sim, state


CASES = [("plane_strain", "linear", "neo_hookean", False), ("plane_strain", "gimp", "j2_finite_strain", False),
         ("plane_strain", "bspline", "j2_small_strain", False), ("plane_stress", "linear", "j2_small_strain", False),
         ("axisymmetric", "gimp", "neo_hookean_compressible", False),
         ("axisymmetric", "linear", "j2_finite_strain", False),
         ("3d", "gimp", "neo_hookean", True), ("3d", "bspline", "j2_finite_strain", True)]


@pytest.mark.parametrize("kinematics,shape,model,three_d", CASES)
def test_particle_evaluation_and_tangent_blocks_equal_the_numpy_kernels(kinematics, shape, model, three_d):
    sim, st = small_simulation(kinematics, shape, model, three_d)
    grid, dim = sim.grid, sim.dim
    u = 0.01 * RNG.standard_normal((grid.n_local_nodes, dim))
    # numpy reference: kinematics, stress update, internal force, element blocks
    grad = RK.gradient(st.node_index, st.G, u)
    F_inc = RK.deformation_increment(st.kinematics, grad, st.radius,
                                     lambda: grid_to_particle(st.node_index, st.S, u))
    F = np.matmul(F_inc, st.F_n)
    sigma, c, history = update_stress(st.material_groups, st.kinematics, F, st.history, True, F_inc)
    pairs = RK.internal_force_pairs(st.kinematics, sigma, F_inc, st.G, st.S, st.volume_n, st.radius)
    force = RK.scatter_pairs(st.node_index, pairs, grid.n_local_nodes)
    dense = RK.dense_tangent(st.kinematics, sigma, c, F_inc, st.G, st.S, st.volume_n, st.radius, st.node_index,
                             grid.n_local_nodes)
    n, nn = st.S.shape
    # compiled
    sim.problem.begin(st)
    ev = ParticleEvaluation(st, grid.n_local_nodes, dim)
    assert shape != "gimp" or np.any(~st.active)       # inactive entries are skipped
    ev.evaluate(st, u, dim)
    assert ev.inverted == 0
    assert relative(ev.F_inc, F_inc) < 1e-12 and relative(ev.F, F) < 1e-12
    assert relative(ev.sigma, sigma) < 1e-10
    assert relative(ev.force, force) < 1e-10
    volume = st.volume_n * np.linalg.det(F_inc)
    assert relative(ev.tangent, volume[:, None, None, None, None]
                    * RK.spatial_tangent(sigma, c, dim)) < 1e-10
    # the matrix-free product and the diagonal of the same stiffness
    radius = st.radius if st.radius is not None else np.zeros(0)
    arguments = (st.kinematics.kernel_code, tuple(range(dim)), tuple(range(st.S.shape[1])), st.node_index,
                 st.active, st.S, st.G, radius, ev.F_inc, ev.tangent, ev.hoop)
    x = RNG.standard_normal((grid.n_local_nodes, dim))
    product = np.empty_like(x)
    particle_step.tangent_product(*arguments, x, product)
    assert relative(product.reshape(-1), dense @ x.reshape(-1)) < 1e-10
    diagonal = np.empty_like(x)
    particle_step.tangent_diagonal(*arguments, diagonal)
    assert relative(diagonal.reshape(-1), np.diag(dense)) < 1e-10
    new = st.committed_history(ev.history)
    for name in st.materials.groups[0][0].history:
        assert relative(new[name], history[name]) < 1e-10, name
    pattern = st.pattern
    values = np.empty(len(pattern.scalar_indices))
    symmetric_options = (False, True) if st.materials.groups[0][0].symmetric_tangent else (False,)
    for symmetric in symmetric_options:     # half the element matrix, mirrored, where it is symmetric
        particle_step.tangent_blocks(
            st.kinematics.kernel_code, tuple(range(dim)), tuple(range(nn)), symmetric, st.node_index, st.active, st.S,
            st.G, st.radius if st.radius is not None else np.zeros(0), ev.F_inc, ev.tangent, ev.hoop,
            grid.ghost_ijk, pattern.width, pattern.indptr, pattern.slot_position, values)
        compiled = np.zeros_like(dense)
        rows = np.repeat(np.arange(len(pattern.scalar_indptr) - 1), np.diff(pattern.scalar_indptr))
        np.add.at(compiled, (rows, pattern.scalar_indices), values)
        assert relative(compiled, dense) < 1e-10
    # the pattern holds every coupling and nothing but them (and the owned diagonals)
    coupled = RK.expected_couplings([[p] for p in range(n)], st.node_index, st.active, grid.owned_local_nodes,
                                    grid.n_local_nodes)
    assert np.array_equal(RK.pattern_couplings(pattern, grid.n_local_nodes), coupled)
    block_rows = np.repeat(np.arange(len(pattern.indptr) - 1), np.diff(pattern.indptr))
    assert np.all(np.diff(pattern.indices)[np.diff(block_rows) == 0] > 0)     # sorted rows
    # every owned node's diagonal block, where the nodal terms add theirs
    nodes = grid.owned_local_nodes
    positions = pattern.block_positions(nodes, dim)
    dofs = nodes[:, None] * dim + np.arange(dim)
    assert np.array_equal(pattern.scalar_rows[positions], np.broadcast_to(dofs[:, :, None], positions.shape))
    assert np.array_equal(pattern.scalar_indices[positions], np.broadcast_to(dofs[:, None, :], positions.shape))


def test_a_table_of_several_models_dispatches_each_particle_to_its_own():
    """Two bodies of different models: the particle kernel compiles every model
    in and dispatches per particle (MIXED); a table of one model compiles only
    that one. Both equal the numpy models."""
    raw = {"grid": {"lower": [0.0, 0.0], "upper": [5.0, 4.0], "cells": [10, 8]},
           "materials": {"soft": {"model": "neo_hookean", "shear_modulus": 6.0e6, "bulk_modulus": 6.0e7,
                                  "density": 10.0},
                         "metal": {"model": "j2_finite_strain", "shear_modulus": 6.0e6, "bulk_modulus": 6.0e7,
                                   "density": 10.0, "yield_stress": 2.0e5, "hardening_modulus": 1.0e6}},
           "bodies": [{"name": "a", "material": "soft", "particles_per_cell": 2, "velocity": [1.0, 2.0],
                       "geometry": {"type": "box", "lower": [0.5, 0.5], "upper": [2.0, 2.5]}},
                      {"name": "b", "material": "metal", "particles_per_cell": 2, "velocity": [-1.0, 2.0],
                       "geometry": {"type": "box", "lower": [2.5, 0.5], "upper": [4.0, 2.5]}}],
           "time": {"integrator": "newmark", "dt": 0.01, "end_time": 1.0}}
    sim = Simulation(validate(raw), MPI.COMM_SELF)
    sim.advance(0.01)
    st, _ = implicit_step.prepare(sim, 0.01)
    assert st.materials.only_model == mp.model_tag(mp.MIXED) == ()
    u = 0.05 * RNG.standard_normal((sim.grid.n_local_nodes, 2))
    grad = RK.gradient(st.node_index, st.G, u)
    F = np.matmul(RK.deformation_increment(st.kinematics, grad, st.radius, None), st.F_n)
    sigma, c, history = update_stress(st.material_groups, st.kinematics, F, st.history, True)
    sim.problem.begin(st)
    mixed = ParticleEvaluation(st, sim.grid.n_local_nodes, 2)
    mixed.evaluate(st, u, 2)
    volume = st.volume_n * np.linalg.det(F @ np.linalg.inv(st.F_n))
    assert relative(mixed.sigma, sigma) < 1e-10
    assert relative(mixed.tangent, volume[:, None, None, None, None] * RK.spatial_tangent(sigma, c, 2)) < 1e-10
    new = st.committed_history(mixed.history)
    assert relative(new["eq_plastic_strain"], history["eq_plastic_strain"]) < 1e-10
    assert np.sum(new["eq_plastic_strain"] > 0) > 0           # the plastic branch is exercised
    # the metal's particles alone, through the kernel compiled for its model only
    metal = st.material_groups[1][1]
    assert np.all(st.materials.models[st.materials.material_of[metal]] == REGISTRY["j2_finite_strain"].code)
    table = MaterialTable([(st.material_groups[1][0], np.arange(len(metal)))], len(metal))
    assert table.only_model == mp.model_tag(REGISTRY["j2_finite_strain"].code)
    out = [np.empty((len(metal), 3, 3)) for _ in range(3)]
    h_out = np.empty((len(metal), table.width))
    particle_step.evaluate_particles(
        st.kinematics.kernel_code, (0, 1), tuple(range(st.S.shape[1])), u, st.node_index[metal], st.active[metal], st.S[metal],
        st.G[metal], np.zeros(0), st.F_n[metal], st.volume_n[metal], table.only_model, table.models,
        table.params, table.material_of, st.history_packed[metal][:, :table.width], True, False,
        np.zeros(0, dtype=np.int64), 0, out[0], out[1], out[2], h_out, np.empty((sim.grid.n_local_nodes, 2)),
        np.empty((len(metal), 2, 2, 2, 2)), np.empty((0, 9)), np.empty((0, 3, 3)), np.empty(0), np.zeros(0), table.f_bar_alpha)
    assert np.array_equal(out[2], mixed.sigma[metal])


def test_a_particle_increment_that_inverts_is_counted():
    sim, st = small_simulation("plane_strain", "linear", "neo_hookean")
    sim.problem.begin(st)
    u = np.zeros((sim.grid.n_local_nodes, 2))
    ev = st.evaluation
    ev.evaluate(st, u, 2)
    assert ev.inverted == 0
    u[:, 0] = -3.0 * sim.grid.lower[0] - 3.0 * sim.grid.ghost_ijk[:, 0] * sim.grid.spacing[0]   # x -> -2x
    ev.evaluate(st, u, 2)
    assert ev.inverted == len(st.F_n)


@pytest.mark.parametrize("shape_name", ["linear", "gimp", "bspline"])
@pytest.mark.parametrize("dim", [2, 3])
def test_compiled_footprint_equals_the_numpy_shape_functions(shape_name, dim):
    """Positions everywhere in the grid, the boundary layers included."""
    from pimpm.grid import Grid
    from pimpm.shape import make_shape
    cells = [3, 4, 2][:dim]
    grid = Grid(MPI.COMM_SELF, [0.0] * dim, [1.5, 2.0, 1.0][:dim], cells, stencil_width=2)
    shape = make_shape(shape_name, dim)
    x = RNG.uniform(0.0, 1.0, (500, dim)) * (grid.upper - grid.lower) + grid.lower
    half = RNG.uniform(0.05, 0.5, (500, dim)) * grid.spacing
    nodes, S, G = reference_shape.evaluate(shape_name, x, grid.lower, grid.spacing, grid.cells, half)
    node_index, S_k, G_k = shape.footprint(x, grid, half)
    assert np.array_equal(node_index, grid.local_node_index(nodes))
    assert relative(S_k, S) < 1e-14 and relative(G_k, G) < 1e-14


def test_compiled_transfers_equal_numpy_sums():
    from pimpm.transfer import grid_to_particle, particle_to_grid
    n, nn, n_nodes, dim = 300, 9, 40, 2
    node_index = RNG.integers(0, n_nodes, (n, nn))
    S, G = RNG.random((n, nn)), RNG.standard_normal((n, nn, dim))
    q, nodal = RNG.standard_normal((n, 3)), RNG.standard_normal((n_nodes, 3))
    expected = np.zeros((n_nodes, 3))
    np.add.at(expected, node_index.ravel(), (S[:, :, None] * q[:, None, :]).reshape(-1, 3))
    assert relative(particle_to_grid(node_index, S, q, n_nodes), expected) < 1e-13
    assert relative(particle_to_grid(node_index, S, q[:, 0], n_nodes), expected[:, 0]) < 1e-13
    assert relative(grid_to_particle(node_index, S, nodal),
                    np.einsum("pk,pkc->pc", S, nodal[node_index])) < 1e-13


def test_compiled_take_equals_numpy_indexing():
    """Particle reordering (pimpm.particles.take): every field shape and dtype
    the particle sets hold, a permutation, a selection, nothing, and into a
    slice of a larger array (migration's merge)."""
    from pimpm.particles import take
    n = 50
    fields = [RNG.standard_normal(n), RNG.standard_normal((n, 2)), RNG.standard_normal((n, 3, 3)),
              RNG.integers(0, 9, n), RNG.integers(0, 9, (n, 4))]
    for index in (RNG.permutation(n), np.flatnonzero(RNG.random(n) < 0.5), np.zeros(0, dtype=np.int64)):
        for a in fields:
            out = take(a, index)
            assert out.dtype == a.dtype and np.array_equal(out, a[index])
    a = fields[2]
    merged = np.full((n + 5, 3, 3), -1.0)
    take(a, np.arange(n)[::-1], merged[:n])
    assert np.array_equal(merged[:n], a[::-1]) and np.all(merged[n:] == -1.0)


@pytest.mark.parametrize("kind", ["linear", "gimp", "bspline"])
def test_footprints_in_box_agrees_with_the_footprints(kind):
    """The explicit step's lazy migration keeps particles whose footprints
    lie in the rank's ghosted nodes (pimpm.kernels.transfer.footprints_in_box):
    the check agrees with the footprint kernel's own nodes, particle by
    particle, near the box's faces and the grid's."""
    from pimpm.kernels.transfer import footprint, footprints_in_box
    from pimpm.shape import make_shape
    shape = make_shape(kind, 2)
    lower, spacing, cells = np.zeros(2), np.array([0.5, 0.25]), np.array([12, 10])
    box_start, box_end = np.array([3, 0]), np.array([9, 11])
    x = RNG.uniform(0.0, 1.0, (400, 2)) * spacing * cells
    nn = shape.nodes_per_particle
    node_index, S, G = np.empty((1, nn), dtype=np.int64), np.empty((1, nn)), np.empty((1, nn, 2))
    half = np.full((1, 2), 0.1)
    inside = 0
    for p in range(len(x)):
        footprint(shape.kernel_kind, (0, 1), x[p:p + 1], lower, spacing, cells, half if kind == "gimp" else
                  np.zeros((0, 2)), np.zeros(2, dtype=np.int64), cells + 1, node_index, S, G)
        i, j = node_index[0] % (cells[0] + 1), node_index[0] // (cells[0] + 1)
        expected = bool(np.all((i >= box_start[0]) & (i < box_end[0]) & (j >= box_start[1]) & (j < box_end[1])))
        assert footprints_in_box(shape.kernel_kind, x[p:p + 1], lower, spacing, cells, box_start, box_end) == expected
        inside += expected
    assert 0 < inside < len(x)
    assert not footprints_in_box(shape.kernel_kind, np.array([[np.nan, 1.0]]), lower, spacing, cells,
                                 box_start, box_end)


def test_runs_of_staying_particles_copy_as_slices():
    """Migration copies the particles that stay as slices when they form few
    runs of consecutive rows (pimpm.particles._runs), as a gather otherwise:
    the runs cover the index exactly."""
    from pimpm.particles import MAX_RUNS, _runs
    for index in (np.array([0, 1, 2, 5, 6, 9]), np.arange(7, 40), np.array([3]), np.zeros(0, dtype=np.int64),
                  np.flatnonzero(RNG.random(200) < 0.97)):
        runs = _runs(index)
        if runs is None:
            assert np.count_nonzero(np.diff(index) != 1) >= MAX_RUNS
            continue
        covered = np.concatenate([np.arange(a, b) for a, b in runs] or [np.zeros(0, dtype=np.int64)])
        assert np.array_equal(covered, index) and len(runs) <= MAX_RUNS
    assert _runs(np.arange(0, 100, 2)) is None


def test_a_plane_stress_thickness_that_does_not_converge_is_counted():
    """The thickness Newton diverges for a nearly incompressible neo-Hookean
    point stretched ten times in both in-plane directions: reported (a step
    failure, pimpm.errors.THICKNESS_FAILURE), never silently kept. A
    moderate stretch converges."""
    from reference.compiled import Compiled
    from pimpm.materials import make_material
    m = Compiled(make_material({"model": "neo_hookean", "shear_modulus": 1.0, "bulk_modulus": 1e3,
                                "density": 1.0}), plane_stress=True)
    for stretch, failures in ((1.2, 0), (10.0, 1)):
        F = np.diag([stretch, stretch, 1.0])[None].copy()
        m.update(F, None, True, F.copy())
        assert m.unconverged == failures
