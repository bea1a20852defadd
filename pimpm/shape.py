"""Grid shape functions evaluated at particles.

A shape-function object maps particle positions to the grid nodes they touch,
the weights ``S_ip`` and the gradients ``G_ip`` (MPM intro eq. 2-6). Every
object exposes the same interface (linear tents, GIMP, quadratic B-splines);
the wider ones need a DMDA ``stencil_width`` of 2.
"""
import itertools

import numpy as np

from .kernels import transfer as kernels


def tensor_product(w, dw):
    """Weights S = prod_d w_d and gradients G_d = dw_d prod_{e != d} w_e from
    per-axis weights and slopes (n, nn, dim)."""
    S = np.prod(w, axis=2)
    G = np.empty(w.shape)
    for d in range(w.shape[2]):  # loop over dimensions only
        G[:, :, d] = dw[:, :, d] * np.prod(np.delete(w, d, axis=2), axis=2)
    return S, G


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
        """Compiled :meth:`evaluate` in the grid's ghosted-local numbering:
        ``(node_index, S, G)`` with node_index (n, nn) ghosted-local nodes."""
        n, nn = len(x), self.nodes_per_particle
        node_index = np.empty((n, nn), dtype=np.int64)
        S = np.empty((n, nn))
        G = np.empty((n, nn, self.dim))
        half = np.zeros((0, self.dim)) if half_size is None else np.ascontiguousarray(half_size, dtype=float)
        kernels.footprint(self.kernel_kind, tuple(range(self.dim)), np.ascontiguousarray(x, dtype=float),
                          grid.lower, grid.spacing, grid.cells, half, grid.ghost_start,
                          grid.ghost_shape, node_index, S, G)
        return node_index, S, G


class LinearShape(TensorProductShape):
    """Bilinear / trilinear tent functions (MPM intro Fig. 2-3): each particle
    touches the ``2**dim`` nodes of the cell that contains it."""

    name = "linear"
    stencil_width = 1
    kernel_kind = kernels.LINEAR

    def evaluate(self, x, lower, spacing, cells, half_size=None):
        """Return ``(nodes, S, G)`` for positions ``x`` (n, dim):

        nodes (n, nn, dim) global node multi-indices,
        S (n, nn) weights (partition of unity),
        G (n, nn, dim) gradients in physical units.
        """
        xi = (x - lower) / spacing
        base = np.clip(np.floor(xi).astype(np.int64), 0, cells - 1)
        frac = xi - base                                    # (n, dim) in [0, 1]
        o = self.offsets[None, :, :]                        # (1, nn, dim)
        f = frac[:, None, :]                                # (n, 1, dim)
        w = np.where(o == 1, f, 1.0 - f)                    # 1D weights (n, nn, dim)
        dw = np.where(o == 1, 1.0, -1.0) / spacing          # 1D slopes (1, nn, dim)
        S, G = tensor_product(w, dw)
        nodes = base[:, None, :] + o
        return nodes, S, G


def make_shape(name, dim):
    if name not in SHAPES:
        raise ValueError(f"unknown shape functions {name!r}")
    return SHAPES[name](dim)


def _gimp_1d(r, l):
    """uGIMP weight and slope (per unit r) in cell units: the linear hat
    averaged over a particle of half-length l (<= 1/2) centred at r from the
    node (Bardenhagen & Kober 2004)."""
    a = np.abs(r)
    s = np.sign(r)
    w = np.zeros_like(r)
    dw = np.zeros_like(r)
    inner = a < l
    middle = (a >= l) & (a < 1.0 - l)
    outer = (a >= 1.0 - l) & (a < 1.0 + l)
    w[inner] = 1.0 - (r[inner] ** 2 + l[inner] ** 2) / (2.0 * l[inner])
    dw[inner] = -r[inner] / l[inner]
    w[middle] = 1.0 - a[middle]
    dw[middle] = -s[middle]
    q = 1.0 + l[outer] - a[outer]
    w[outer] = q ** 2 / (4.0 * l[outer])
    dw[outer] = -s[outer] * q / (2.0 * l[outer])
    return w, dw


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

    def evaluate(self, x, lower, spacing, cells, half_size=None):
        xi = (x - lower) / spacing
        if half_size is None:
            raise ValueError("GIMP needs the particle half sizes")
        l = half_size / spacing                                   # (n, dim) in cell units
        base = np.floor(xi + 0.5).astype(np.int64) - 1            # nearest node - 1
        nodes = base[:, None, :] + self.offsets[None, :, :]       # (n, nn, dim)
        r = xi[:, None, :] - nodes
        lb = np.broadcast_to(l[:, None, :], r.shape)
        w, dw = _gimp_1d(r.ravel(), lb.ravel())
        w, dw = w.reshape(r.shape), dw.reshape(r.shape)
        outside = (nodes < 0) | (nodes > cells)
        w[outside] = 0.0
        dw[outside] = 0.0
        nodes = np.clip(nodes, 0, cells)
        S, G = tensor_product(w, dw / spacing)
        return nodes, S, G


def _bspline2_1d(r):
    """Uniform quadratic B-spline centred on a node: weight and slope (per
    unit r) at distance r in cell units (support |r| < 3/2, C1)."""
    a = np.abs(r)
    w = np.where(a < 0.5, 0.75 - r ** 2, np.where(a < 1.5, 0.5 * (1.5 - a) ** 2, 0.0))
    dw = np.where(a < 0.5, -2.0 * r, np.where(a < 1.5, -np.sign(r) * (1.5 - a), 0.0))
    return w, dw


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

    @staticmethod
    def weights_1d(xi, cells):
        """Per-axis nodes (n, 3), weights and slopes in cell units for
        positions ``xi`` (n,) in cell units, boundary-modified at 0 and ``cells``."""
        base = np.floor(xi + 0.5).astype(np.int64) - 1                 # nearest node - 1
        nodes = base[:, None] + np.arange(3)[None, :]
        w, dw = _bspline2_1d(xi[:, None] - nodes)
        low = base < 0                                                 # phantom node -1 at slot 0
        high = base + 2 > cells                                        # phantom node cells+1 at slot 2
        for mask, phantom, face, inner in ((low, 0, 1, 2), (high, 2, 1, 0)):
            for a in (w, dw):
                a[mask, face] += 2.0 * a[mask, phantom]
                a[mask, inner] -= a[mask, phantom]
                a[mask, phantom] = 0.0
        return np.clip(nodes, 0, cells), w, dw

    def evaluate(self, x, lower, spacing, cells, half_size=None):
        xi = (x - lower) / spacing
        n = len(x)
        per_axis = [self.weights_1d(xi[:, d], int(cells[d])) for d in range(self.dim)]
        o = self.offsets
        nodes = np.empty((n, self.nodes_per_particle, self.dim), dtype=np.int64)
        w = np.empty((n, self.nodes_per_particle, self.dim))
        dw = np.empty_like(w)
        for d, (nd, wd, dwd) in enumerate(per_axis):                   # loop over dimensions only
            nodes[:, :, d] = nd[:, o[:, d]]
            w[:, :, d] = wd[:, o[:, d]]
            dw[:, :, d] = dwd[:, o[:, d]] / spacing[d]
        S, G = tensor_product(w, dw)
        return nodes, S, G


#: ``grid.shape_functions`` name -> shape-function class
SHAPES = {cls.name: cls for cls in (LinearShape, GIMPShape, QuadraticBSplineShape)}
