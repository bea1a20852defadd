"""The extension of weakly supported nodes (pimpm/weak_nodes.py): the folded
basis keeps partition of unity and reproduces linear fields exactly, the
weak nodes keep no weight, the tangent stays the exact derivative of the
residual (finite differences on 1 and 2 ranks), and the thin cantilever
that stalled Newton without it now bends to large rotations."""
import re

import numpy as np
import pytest

import petsc4py

petsc4py.init([])
from mpi4py import MPI  # noqa: E402

from helpers import HERE, MPIEXEC, run_mpi  # noqa: E402
from pimpm import weak_nodes  # noqa: E402
from pimpm.grid import Grid  # noqa: E402
from pimpm.kernels import transfer as transfer_kernels  # noqa: E402
from pimpm.shape import make_shape  # noqa: E402


def _box_of_particles(shape_name, dim, h, lo, hi):
    """A grid of cells h (10 x 9 x 8) and a box [lo, hi] of particles on a
    lattice, 4 per cell and axis, whose GIMP domains tile it: the grid, the
    shape, the positions, their footprint and the nodes' support."""
    cells = [10, 9, 8][:dim]
    grid = Grid(MPI.COMM_SELF, [0.0] * dim, list(np.array(cells) * h), cells, stencil_width=2)
    shape = make_shape(shape_name, dim)
    n = np.round((hi - lo) / (h / 4)).astype(int)
    axes = [lo[d] + (np.arange(n[d]) + 0.5) * (hi[d] - lo[d]) / n[d] for d in range(dim)]
    x = np.stack([a.ravel() for a in np.meshgrid(*axes, indexing="ij")], axis=1)
    volume = np.full(len(x), np.prod(hi - lo) / len(x))
    half = np.broadcast_to((hi - lo) / n / 2.0, x.shape).copy()
    node_index, S, G = shape.footprint(x, grid, half)
    return grid, shape, x, node_index, S, G, weak_nodes.support_fraction(grid, node_index, S, volume)


@pytest.mark.parametrize("shape_name", ["gimp", "bspline"])
@pytest.mark.parametrize("dim", [2, 3])
def test_folded_basis_reproduces_linear_fields_and_empties_weak_nodes(shape_name, dim):
    """A box of particles on a lattice (4 per cell and axis, GIMP domains
    tiling it) whose faces lie 0.1 cell beyond grid lines: the nodes just
    outside it are weak (support 0.1 x 0.1 / 2 of a cell or less, below 0.05);
    after folding they keep no weight (corners too: folded along x, then y),
    and the basis still has partition of unity and reproduces x (and its
    gradient the identity) exactly."""
    h = 0.25
    lo = np.array([2, 2, 2][:dim]) * h - 0.1 * h
    hi = np.array([6, 5, 4][:dim]) * h + 0.1 * h
    grid, shape, x, node_index, S, G, support = _box_of_particles(shape_name, dim, h, lo, hi)
    nodes = weak_nodes.WeakNodes(grid, support, np.zeros(len(support), bool), 0.05)
    weak, receives = nodes.weak, nodes.receives
    S0, G0 = S.copy(), G.copy()
    folded = weak_nodes.extend(shape, grid, node_index, S, G, nodes)
    assert folded > 50 and weak.sum() > 5
    # ghosted-local node coordinates
    ijk = np.stack(np.unravel_index(np.arange(grid.n_local_nodes), grid.ghost_shape[::-1])[::-1],
                   axis=1) + grid.ghost_start
    X = grid.lower + ijk * grid.spacing
    for weights, gradients in ((S0, G0), (S, G)):
        np.testing.assert_allclose(weights.sum(axis=1), 1.0, atol=1e-13)           # partition of unity
        np.testing.assert_allclose(np.einsum("pk,pkd->pd", weights, X[node_index]), x, atol=1e-13)
        np.testing.assert_allclose(gradients.sum(axis=1), 0.0, atol=1e-11)
        np.testing.assert_allclose(np.einsum("pke,pkd->ped", gradients, X[node_index]),
                                   np.broadcast_to(np.eye(dim), (len(x), dim, dim)), atol=1e-11)
    on_weak = weak[node_index]
    assert (on_weak & (S0 != 0)).sum() > 0
    assert np.all(S[on_weak] == 0.0) and np.all(G[on_weak] == 0.0)
    # only weak nodes lost weight; receiving nodes gained it
    assert np.array_equal(S[~on_weak & ~receives[node_index]], S0[~on_weak & ~receives[node_index]])


@pytest.mark.parametrize("dim", [2, 3])
def test_a_weak_node_on_a_symmetry_plane_folds_along_the_plane(dim):
    """A box of particles against the symmetry plane x = 0 (x prescribed
    there), its other faces 0.1 cell beyond grid lines: the weak nodes on
    the plane fold too (the 3D upsetting at 0.5 mm stalled on one that
    Newton pushed by metres), but only onto nodes of the plane, so each
    particle's weight on the plane, and its gradient, are as before (the
    prescribed x displacement reaches the particles unchanged); linear
    fields stay exact; a node held by a tool neither folds nor takes
    weight."""
    h = 0.25
    lo = np.array([0.0, 2 * h - 0.1 * h, 2 * h - 0.1 * h][:dim])
    hi = np.array([4, 5, 4][:dim]) * h + 0.1 * h
    grid, shape, x, node_index, S, G, support = _box_of_particles("gimp", dim, h, lo, hi)
    ijk = np.stack(np.unravel_index(np.arange(grid.n_local_nodes), grid.ghost_shape[::-1])[::-1],
                   axis=1) + grid.ghost_start
    owned = np.stack(np.unravel_index(np.arange(grid.n_owned_nodes), grid.owned_shape[::-1])[::-1],
                     axis=1) + grid.owned_start
    prescribed = np.zeros((grid.n_owned_nodes, dim), bool)
    prescribed[owned[:, 0] == 0, 0] = True                                 # symmetry x = 0
    held = np.zeros_like(prescribed)
    tool = (owned[:, 0] == 0) & (owned[:, 1] == 1)                          # one node row held by a tool
    held[tool] = True
    nodes = weak_nodes.WeakNodes(grid, support, prescribed.reshape(-1), 0.05, held.reshape(-1))
    on_plane = ijk[:, 0] == 0
    assert (nodes.weak & on_plane).sum() >= 1 and np.all(nodes.mask[on_plane & ~nodes.weak & (ijk[:, 1] != 1)] == 1)
    assert not nodes.weak[(ijk[:, 0] == 0) & (ijk[:, 1] == 1)].any()
    S0, G0 = S.copy(), G.copy()
    weak_nodes.extend(shape, grid, node_index, S, G, nodes)
    on_weak = nodes.weak[node_index]
    assert np.all(S[on_weak] == 0.0) and np.all(G[on_weak] == 0.0)
    assert (on_weak & on_plane[node_index] & (S0 != 0)).any()
    plane = on_plane[node_index]
    np.testing.assert_allclose((S * plane).sum(axis=1), (S0 * plane).sum(axis=1), atol=1e-13)
    np.testing.assert_allclose((G * plane[..., None]).sum(axis=1), (G0 * plane[..., None]).sum(axis=1),
                               atol=1e-11)
    held_slots = nodes.mask[node_index] < 0
    assert np.array_equal(S[held_slots], S0[held_slots])
    X = grid.lower + ijk * grid.spacing
    np.testing.assert_allclose(S.sum(axis=1), 1.0, atol=1e-13)
    np.testing.assert_allclose(np.einsum("pk,pkd->pd", S, X[node_index]), x, atol=1e-13)
    np.testing.assert_allclose(np.einsum("pke,pkd->ped", G, X[node_index]),
                               np.broadcast_to(np.eye(dim), (len(x), dim, dim)), atol=1e-11)


@pytest.mark.skipif(MPIEXEC is None, reason="mpiexec not found")
@pytest.mark.parametrize("nranks, shape", [(1, "gimp"), (2, "gimp"), (2, "bspline")])
def test_tangent_of_the_extended_basis_matches_finite_differences(nranks, shape):
    """The Jacobian check of tests/mpi/jacobian_check.py with a weak-node
    fraction large enough that nodes are folded in the checked step."""
    proc = run_mpi(nranks, [f"{HERE}/mpi/jacobian_check.py", "quasi_static", "2d", shape, "elastic",
                            "weak=0.3"], timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert int(re.search(r"weak_pairs=(\d+)", proc.stdout).group(1)) > 0
    assert float(re.search(r" relative_error=(\S+)", proc.stdout).group(1)) < 1e-6


@pytest.mark.parametrize("dim", [2, 3])
def test_a_weak_node_in_the_middle_of_a_stencil_folds_onto_parallelograms(dim):
    """A lone particle whose nearest node is weak (a fold of the surface
    against a tool: the 3D upsetting at 0.5 mm stalled on one) has no
    node two steps inward inside its stencil. Its weight goes to the
    parallelograms one step away along two axes whose nodes are strong
    (u_I = u_{I-a} + u_{I-b} - u_{I-a-b}): the basis keeps partition of
    unity and reproduces x exactly, the weak node keeps nothing, and only
    strong nodes take weight. With no strong parallelogram nothing
    changes."""
    h = 0.5
    cells = [8] * dim
    grid = Grid(MPI.COMM_SELF, [0.0] * dim, [c * h for c in cells], cells, stencil_width=2)
    shape = make_shape("gimp", dim)
    centre = np.array([4] * dim)                          # the weak node's grid index
    x = ((centre + np.array([0.2, -0.15, 0.1][:dim])) * h).reshape(1, dim)
    node_index, S, G = shape.footprint(x, grid, np.full((1, dim), h / 6))
    ijk = np.stack(np.unravel_index(np.arange(grid.n_local_nodes), grid.ghost_shape[::-1])[::-1],
                   axis=1) + grid.ghost_start
    X = grid.lower + ijk * grid.spacing
    offset = ijk - centre
    weak = np.all(offset == 0, axis=1)
    # strong: the nodes below the weak one along x and y (a concave corner); the
    # rest of the stencil is empty (receives, no support) or prescribed
    strong = np.all(offset[:, :2] <= 0, axis=1) & ~weak
    if dim == 3:
        strong &= offset[:, 2] <= 0
    receives = ~weak & (strong | np.any(offset > 0, axis=1))
    mask = np.where(receives | weak, 0, -1)            # -1: held by a tool
    middle = int(np.nonzero(weak[node_index[0]])[0][0])
    assert all((middle // 3 ** d) % 3 == 1 for d in range(dim))
    S0, G0 = S.copy(), G.copy()
    folded = transfer_kernels.fold_weak_nodes(tuple(range(dim)), 3, node_index, S, G, weak, mask,
                                              strong, grid.ghost_start, grid.ghost_shape)
    assert folded == 1
    assert S[0, middle] == 0.0 and np.all(G[0, middle] == 0.0)
    changed = np.nonzero(S[0] != S0[0])[0]
    assert set(changed) - {middle} and all(strong[node_index[0, t]] for t in changed if t != middle)
    # pairs of axes x sides with a strong parallelogram: (x-, y-) in 2D; in 3D
    # (x-, y-), (x-, z-), (y-, z-): the weight is shared equally among them
    pairs = 1 if dim == 2 else 3
    np.testing.assert_allclose(S[0] - S0[0], _parallelogram_weights(node_index[0], weak, offset, S0[0, middle],
                                                                  pairs, dim), atol=1e-15)
    for weights, gradients in ((S0, G0), (S, G)):
        np.testing.assert_allclose(weights.sum(axis=1), 1.0, atol=1e-13)
        np.testing.assert_allclose(np.einsum("pk,pkd->pd", weights, X[node_index]), x, atol=1e-13)
        np.testing.assert_allclose(gradients.sum(axis=1), 0.0, atol=1e-11)
        np.testing.assert_allclose(np.einsum("pke,pkd->ped", gradients, X[node_index]),
                                   np.eye(dim)[None], atol=1e-11)
    # no strong parallelogram: untouched
    S1, G1 = S0.copy(), G0.copy()
    lone = np.zeros_like(strong)
    assert transfer_kernels.fold_weak_nodes(tuple(range(dim)), 3, node_index, S1, G1, weak, mask, lone,
                                            grid.ghost_start, grid.ghost_shape) == 0
    assert np.array_equal(S1, S0) and np.array_equal(G1, G0)


def _parallelogram_weights(nodes, weak, offset, w, pairs, dim):
    """The change of a stencil's weights when the weak node's weight ``w``
    goes, shared by ``pairs``, to the (-1, -1) parallelograms of every pair
    of axes: +1 on each one-step node, -1 on the diagonal one."""
    change = np.zeros(len(nodes))
    for t, node in enumerate(nodes):
        o = offset[node]
        if weak[node]:
            change[t] = -w
        elif np.all(o <= 0) and -o.sum() == 1:          # one step along one axis
            change[t] = w * (dim - 1) / pairs           # in (dim - 1) of the pairs
        elif np.all(o <= 0) and -o.sum() == 2 and np.count_nonzero(o) == 2:
            change[t] = -w / pairs
    return change
