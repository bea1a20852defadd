"""Shape functions: partition of unity, linear completeness and gradients
consistent with the weights (finite differences), in 2D and 3D, of the
compiled footprint (the code that runs) and of its numpy reference."""
import numpy as np
import pytest

from reference import shape as reference

IMPLEMENTATIONS = {"compiled": reference.compiled_evaluate, "reference": reference.evaluate}


class Shape:
    """The shape functions ``name`` through one implementation, with the
    interface the tests use."""

    def __init__(self, name, implementation="compiled"):
        self.name = name
        self.function = IMPLEMENTATIONS[implementation]

    def evaluate(self, x, lower, spacing, cells, half_size=None):
        return self.function(self.name, x, lower, spacing, cells, half_size)

    @staticmethod
    def weights_1d(xi, cells):
        return reference.bspline_weights_1d(xi, cells)


def make_shape(name, dim, implementation="compiled"):
    return Shape(name, implementation)


@pytest.mark.parametrize("implementation", list(IMPLEMENTATIONS))
@pytest.mark.parametrize("name", ["linear", "gimp", "bspline"])
@pytest.mark.parametrize("dim", [2, 3])
def test_partition_of_unity_and_gradient_consistency(name, dim, implementation):
    rng = np.random.default_rng(3)
    shape = make_shape(name, dim, implementation)
    cells = np.array([7, 5, 4][:dim])
    spacing = np.array([0.5, 0.25, 1.0][:dim])
    lower = np.array([-1.0, 2.0, 0.5][:dim])
    half = spacing / (2 * np.array([2, 3, 1][:dim]))
    n = 300
    # particle domains inside the grid (GIMP's requirement)
    x = lower + half + rng.random((n, dim)) * (cells * spacing - 2 * half)
    nodes, S, G = shape.evaluate(x, lower, spacing, cells, np.tile(half, (n, 1)))
    xi = lower + nodes * spacing                                     # node coordinates
    assert np.all(S >= -1e-15)
    np.testing.assert_allclose(S.sum(axis=1), 1.0, atol=1e-13)      # partition of unity
    np.testing.assert_allclose(np.einsum("pi,pid->pd", S, xi), x, atol=1e-12)   # sum S x_i = x
    np.testing.assert_allclose(G.sum(axis=1), 0.0, atol=1e-11)      # sum of gradients vanishes
    np.testing.assert_allclose(np.einsum("pia,pib->pab", xi, G),     # sum x_i (x) G_i = I
                               np.broadcast_to(np.eye(dim), (n, dim, dim)), atol=1e-11)
    # gradients are the derivatives of the weights (central differences)
    eps = 1e-7
    for d in range(dim):
        dx = np.zeros(dim)
        dx[d] = eps
        _, Sp, _ = shape.evaluate(x + dx, lower, spacing, cells, np.tile(half, (n, 1)))
        _, Sm, _ = shape.evaluate(x - dx, lower, spacing, cells, np.tile(half, (n, 1)))
        # the node sets can differ where a particle crosses a half-cell line; compare
        # only where they agree (almost everywhere)
        np_, _, _ = shape.evaluate(x + dx, lower, spacing, cells, np.tile(half, (n, 1)))
        nm, _, _ = shape.evaluate(x - dx, lower, spacing, cells, np.tile(half, (n, 1)))
        same = np.all((np_ == nodes) & (nm == nodes), axis=(1, 2))
        assert same.sum() > 0.95 * n
        fd = (Sp - Sm) / (2 * eps)
        np.testing.assert_allclose(G[same, :, d], fd[same], atol=1e-6 * np.abs(G).max())


def test_gimp_is_smooth_across_cell_boundaries():
    """Linear weights have a kink where a particle crosses a node line; GIMP
    weights and gradients are continuous there (less cell-crossing noise)."""
    shape = make_shape("gimp", 2)
    lower, spacing, cells = np.zeros(2), np.ones(2), np.array([4, 4])
    half = np.full((2, 2), 0.25)
    x = np.array([[2.0 - 1e-9, 1.5], [2.0 + 1e-9, 1.5]])
    nodes, S, G = shape.evaluate(x, lower, spacing, cells, half)
    weights = [{tuple(n): (s, g) for n, s, g in zip(nodes[k], S[k], G[k])} for k in range(2)]
    for node in set(weights[0]) | set(weights[1]):
        s0, g0 = weights[0].get(node, (0.0, np.zeros(2)))
        s1, g1 = weights[1].get(node, (0.0, np.zeros(2)))
        assert abs(s0 - s1) < 1e-8 and np.allclose(g0, g1, atol=1e-8)


@pytest.mark.parametrize("implementation", list(IMPLEMENTATIONS))
@pytest.mark.parametrize("dim", [2, 3])
def test_bspline_boundary_modification_up_to_the_faces(dim, implementation):
    """Within half a cell of a grid face the folded B-splines still give
    partition of unity, reproduce linear fields, stay non-negative, and
    interpolate at the face itself (N = 1 at a face node, so constraining
    a symmetry plane constrains exactly the face nodes)."""
    rng = np.random.default_rng(5)
    shape = make_shape("bspline", dim, implementation)
    cells = np.array([6, 4, 3][:dim])
    spacing = np.array([0.5, 0.25, 1.0][:dim])
    lower = np.array([-1.0, 2.0, 0.5][:dim])
    n = 400
    # every particle has at least one coordinate within half a cell of a face
    xi = rng.random((n, dim)) * cells
    axis = rng.integers(0, dim, n)
    at_top = rng.random(n) < 0.5
    edge = rng.random(n) * 0.5
    xi[np.arange(n), axis] = np.where(at_top, cells[axis] - edge, edge)
    x = lower + xi * spacing
    nodes, S, G = shape.evaluate(x, lower, spacing, cells)
    xn = lower + nodes * spacing
    assert nodes.min() >= 0 and np.all(nodes <= cells)
    assert np.all(S >= -1e-15)
    np.testing.assert_allclose(S.sum(axis=1), 1.0, atol=1e-13)
    np.testing.assert_allclose(np.einsum("pi,pid->pd", S, xn), x, atol=1e-12)
    np.testing.assert_allclose(np.einsum("pia,pib->pab", xn, G),
                               np.broadcast_to(np.eye(dim), (n, dim, dim)), atol=1e-11)
    # on a face: the face node carries everything along that axis
    w = shape.weights_1d(np.array([0.0, float(cells[0])]), int(cells[0]))[1]
    np.testing.assert_allclose(w, [[0.0, 1.0, 0.0], [0.0, 1.0, 0.0]], atol=1e-15)


def test_bspline_weights_and_gradients_are_continuous_everywhere():
    """C1 in 1D: weights and slopes of every node agree on both sides of cell
    lines, half-cell lines and the folded boundary layers, so particles
    crossing cells see no jump in their internal force (the cell-crossing
    error the papers blame for noise)."""
    shape = make_shape("bspline", 1)
    cells = 5
    jumps = np.array([0.5, 1.0, 1.5, 2.0, 2.5, 3.5, 4.0, 4.5])
    eps = 1e-9
    left = shape.weights_1d(jumps - eps, cells)
    right = shape.weights_1d(jumps + eps, cells)
    def per_node(values, k):          # clipped slots repeat a face node with zero weight
        out = {}
        for node, w, dw in zip(*(arr[k] for arr in values)):
            prev = out.get(int(node), np.zeros(2))
            out[int(node)] = prev + (w, dw)
        return out

    for k in range(len(jumps)):
        a, b = per_node(left, k), per_node(right, k)
        for node in set(a) | set(b):
            assert np.allclose(a.get(node, 0.0), b.get(node, 0.0), atol=1e-8), (jumps[k], node)
