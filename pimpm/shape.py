"""Grid shape functions evaluated at particles.

A shape-function object maps particle positions to the grid nodes they touch,
the weights ``S_ip`` and the gradients ``G_ip`` (MPM intro eq. 2-6), computed
by the compiled kernel :func:`pimpm.kernels.transfer.footprint` (numpy
reference: tests/reference/shape.py). Every object exposes the same
interface (linear tents, GIMP, quadratic B-splines); the wider ones need a
DMDA ``stencil_width`` of 2.
"""
import itertools

import numpy as np

from .kernels import transfer as kernels


class TensorProductShape:
    """Shape functions that are products of 1D functions, each particle
    touching ``nodes_per_axis`` consecutive nodes per axis."""

    nodes_per_axis = 2

    def __init__(self, dim):
        self.dim = dim
        # node offsets from the first node touched, x fastest: (nodes_per_particle, dim)
        self.offsets = np.array([o[::-1] for o in itertools.product(range(self.nodes_per_axis),
                                                                     repeat=dim)], dtype=np.int64)
        self.nodes_per_particle = len(self.offsets)

    def footprint(self, x, grid, half_size=None):
        """``(node_index, S, G)`` at positions ``x`` (n, dim) in the grid's
        ghosted-local numbering: node_index (n, nn) ghosted-local nodes,
        S (n, nn) weights, G (n, nn, dim) gradients in physical units."""
        n, nn = len(x), self.nodes_per_particle
        node_index = np.empty((n, nn), dtype=np.int64)
        S = np.empty((n, nn))
        G = np.empty((n, nn, self.dim))
        half = np.zeros((0, self.dim)) if half_size is None else np.ascontiguousarray(half_size, dtype=float)
        kernels.footprint(self.kernel_kind, tuple(range(self.dim)), np.ascontiguousarray(x, dtype=float),
                          grid.lower, grid.spacing, grid.cells, half, grid.ghost_start,
                          grid.ghost_shape, node_index, S, G)
        return node_index, S, G

    def evaluate(self, x, lower, spacing, cells, half_size=None):
        """The same on a whole grid box (``lower``, ``spacing``, ``cells``),
        in global node multi-indices: ``(nodes, S, G)`` with nodes (n, nn,
        dim), x fastest. For scripts and tests that have no DMDA."""
        cells = np.asarray(cells, dtype=np.int64)
        n, nn = len(x), self.nodes_per_particle
        node_index = np.empty((n, nn), dtype=np.int64)
        S, G = np.empty((n, nn)), np.empty((n, nn, self.dim))
        half = np.zeros((0, self.dim)) if half_size is None else np.ascontiguousarray(half_size, dtype=float)
        kernels.footprint(self.kernel_kind, tuple(range(self.dim)), np.ascontiguousarray(x, dtype=float),
                          np.asarray(lower, dtype=float), np.asarray(spacing, dtype=float), cells, half,
                          np.zeros(self.dim, dtype=np.int64), cells + 1, node_index, S, G)
        nodes = np.stack(np.unravel_index(node_index, tuple((cells + 1)[::-1]))[::-1], axis=-1)
        return nodes, S, G


class LinearShape(TensorProductShape):
    """Bilinear / trilinear tent functions (MPM intro Fig. 2-3): each particle
    touches the ``2**dim`` nodes of the cell that contains it."""

    name = "linear"
    stencil_width = 1
    kernel_kind = kernels.LINEAR


class GIMPShape(TensorProductShape):
    """GIMP: the tent functions averaged over each particle's domain (initial
    half-length h / (2 ppc) per axis, stretched by the diagonal of F by the
    caller), smooth across cell boundaries, which
    removes most of the cell-crossing noise of linear shape functions. Each
    particle touches 3 nodes per axis (the nearest node and its neighbours),
    so the DMDA needs a stencil width of 2. Partition of unity and linear
    completeness hold while particle domains stay inside the grid."""

    name = "gimp"
    stencil_width = 2
    nodes_per_axis = 3
    kernel_kind = kernels.GIMP


class QuadraticBSplineShape(TensorProductShape):
    """Node-centred quadratic B-splines (C1, non-negative; Steffen, Kirby &
    Berzins 2008): no cell-crossing jump in the gradients at all, and each
    particle touches the nearest node and its two neighbours per axis
    (stencil width 2).

    Boundary modification: within half a cell of a grid face the uniform
    splines would need a node outside the grid. Its function is folded onto
    the face node and its neighbour by linear extrapolation, N_0 += 2 N_-1,
    N_1 -= N_-1 (x_-1 = 2 x_0 - x_1), which keeps partition of unity and
    linear completeness up to the face and leaves N_0 = 1 - r, N_1 = r on
    the first half cell: non-negative, still C1, and interpolating at the
    face, so symmetry planes and walls constrain exactly the face nodes."""

    name = "bspline"
    stencil_width = 2
    nodes_per_axis = 3
    kernel_kind = kernels.BSPLINE


#: ``grid.shape_functions`` name -> shape-function class
SHAPES = {cls.name: cls for cls in (LinearShape, GIMPShape, QuadraticBSplineShape)}


def make_shape(name, dim):
    if name not in SHAPES:
        raise ValueError(f"unknown shape functions {name!r}")
    return SHAPES[name](dim)
