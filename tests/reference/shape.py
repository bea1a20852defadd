"""The shape functions in numpy (vectorised over particles): the
references of pimpm.kernels.transfer.footprint, and
:func:`compiled_evaluate`, the compiled shape functions in the same
interface (global node multi-indices), so that the tests check the code that runs.
They were pimpm's production code before the compiled kernels replaced them."""
import itertools

import numpy as np

from pimpm.shape import make_shape


def tensor_product(w, dw):
    """Weights S = prod_d w_d and gradients G_d = dw_d prod_{e != d} w_e from
    per-axis weights and slopes (n, nn, dim)."""
    S = np.prod(w, axis=2)
    G = np.empty(w.shape)
    for d in range(w.shape[2]):  # loop over dimensions only
        G[:, :, d] = dw[:, :, d] * np.prod(np.delete(w, d, axis=2), axis=2)
    return S, G


def offsets(nodes_per_axis, dim):
    """Node offsets from the first node touched, x fastest: (nodes_per_particle, dim)."""
    return np.array([o[::-1] for o in itertools.product(range(nodes_per_axis), repeat=dim)], dtype=np.int64)


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


def _bspline2_1d(r):
    """Uniform quadratic B-spline centred on a node: weight and slope (per
    unit r) at distance r in cell units (support |r| < 3/2, C1)."""
    a = np.abs(r)
    w = np.where(a < 0.5, 0.75 - r ** 2, np.where(a < 1.5, 0.5 * (1.5 - a) ** 2, 0.0))
    dw = np.where(a < 0.5, -2.0 * r, np.where(a < 1.5, -np.sign(r) * (1.5 - a), 0.0))
    return w, dw


def bspline_weights_1d(xi, cells):
    """Per-axis nodes (n, 3), weights and slopes in cell units for
    positions ``xi`` (n,) in cell units, boundary-modified at 0 and ``cells``
    (N_0 += 2 N_-1, N_1 -= N_-1: pimpm.shape.QuadraticBSplineShape)."""
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


def evaluate(name, x, lower, spacing, cells, half_size=None):
    """Shape functions ``name`` (linear, gimp, bspline) at positions ``x``
    (n, dim): ``(nodes, S, G)`` with nodes (n, nn, dim) global node
    multi-indices (x fastest), S (n, nn) weights, G (n, nn, dim) gradients
    in physical units. GIMP needs the particle half sizes (n, dim)."""
    dim = x.shape[1]
    xi = (x - lower) / spacing
    if name == "linear":
        o = offsets(2, dim)[None, :, :]
        base = np.clip(np.floor(xi).astype(np.int64), 0, cells - 1)
        f = (xi - base)[:, None, :]
        w = np.where(o == 1, f, 1.0 - f)
        dw = np.where(o == 1, 1.0, -1.0) / spacing
        S, G = tensor_product(w, dw)
        return base[:, None, :] + o, S, G
    o = offsets(3, dim)
    if name == "gimp":
        if half_size is None:
            raise ValueError("GIMP needs the particle half sizes")
        l = half_size / spacing
        base = np.floor(xi + 0.5).astype(np.int64) - 1            # nearest node - 1
        nodes = base[:, None, :] + o[None, :, :]
        r = xi[:, None, :] - nodes
        w, dw = _gimp_1d(r.ravel(), np.broadcast_to(l[:, None, :], r.shape).ravel())
        w, dw = w.reshape(r.shape), dw.reshape(r.shape)
        outside = (nodes < 0) | (nodes > cells)
        w[outside] = 0.0
        dw[outside] = 0.0
        S, G = tensor_product(w, dw / spacing)
        return np.clip(nodes, 0, cells), S, G
    n = len(x)
    nodes = np.empty((n, len(o), dim), dtype=np.int64)
    w = np.empty((n, len(o), dim))
    dw = np.empty_like(w)
    for d in range(dim):                                           # loop over dimensions only
        nd, wd, dwd = bspline_weights_1d(xi[:, d], int(cells[d]))
        nodes[:, :, d] = nd[:, o[:, d]]
        w[:, :, d] = wd[:, o[:, d]]
        dw[:, :, d] = dwd[:, o[:, d]] / spacing[d]
    S, G = tensor_product(w, dw)
    return nodes, S, G


def compiled_evaluate(name, x, lower, spacing, cells, half_size=None):
    """:func:`evaluate` by the compiled kernel (pimpm.shape's ``evaluate``)."""
    return make_shape(name, x.shape[1]).evaluate(x, lower, spacing, cells, half_size)
