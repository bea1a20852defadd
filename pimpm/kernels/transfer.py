"""Particle <-> grid transfers, compiled: the shape functions at the
particles (MPM introduction eq. 2-6) written straight in the ghosted-local
node numbering, scatters of particle quantities to the nodes (eq. 2-4) and
gathers of nodal quantities to the particles (eq. 8-10).

A footprint lists ``nodes_per_axis ** dim`` nodes per particle, x fastest
(the order of :class:`pimpm.shape.TensorProductShape`'s offsets); nodes
outside the grid are clipped onto it with zero weight and gradient. The
numpy versions in tests/reference/shape.py are the references
(tests/test_kernels.py).
"""
import math

import numpy as np

from .jit import jit, jit_inline

LINEAR, GIMP, BSPLINE = 0, 1, 2


@jit
def _gimp_1d(r, l):
    """uGIMP weight and slope per unit r (cell units), particle half-length
    l <= 1/2 (as tests/reference/shape.py)."""
    a = abs(r)
    s = 1.0 if r > 0 else (-1.0 if r < 0 else 0.0)
    if a < l:
        return 1.0 - (r * r + l * l) / (2.0 * l), -r / l
    if a < 1.0 - l:
        return 1.0 - a, -s
    if a < 1.0 + l:
        q = 1.0 + l - a
        return q * q / (4.0 * l), -s * q / (2.0 * l)
    return 0.0, 0.0


@jit
def _bspline_1d(r):
    a = abs(r)
    if a < 0.5:
        return 0.75 - r * r, -2.0 * r
    if a < 1.5:
        s = 1.0 if r > 0 else (-1.0 if r < 0 else 0.0)
        return 0.5 * (1.5 - a) ** 2, -s * (1.5 - a)
    return 0.0, 0.0


@jit
def _fold(values, d, phantom, inner):
    """B-spline boundary modification along axis d: the phantom node's
    function goes to the face node (slot 1) and its inner neighbour by
    linear extrapolation, N_face += 2 N_phantom, N_inner -= N_phantom."""
    values[d, 1] += 2.0 * values[d, phantom]
    values[d, inner] -= values[d, phantom]
    values[d, phantom] = 0.0


@jit_inline
def _first_node(kind, xi, cells):
    """The first node a footprint touches along an axis, at xi (cell units):
    the cell's lower node for LINEAR (clipped onto the grid), else the node
    below the nearest one (not clipped: the nodes are clipped one by one)."""
    if kind == LINEAR:
        return min(max(int(math.floor(xi)), 0), cells - 1)
    return int(math.floor(xi + 0.5)) - 1


@jit
def footprint(kind, axes, x, lower, spacing, cells, half_size, ghost_start, ghost_shape,
              node_index, S, G):
    """Shape functions of ``kind`` (LINEAR, GIMP, BSPLINE) at positions x
    (n, dim): ghosted-local node index (n, nn), weight S (n, nn) and
    gradient G (n, nn, dim) in physical units. ``half_size`` (n, dim): GIMP's
    particle half sizes (unused otherwise). ``axes`` = tuple(range(dim))."""
    dim = len(axes)
    n = x.shape[0]
    npa = 2 if kind == LINEAR else 3
    nn = npa ** dim
    node = np.empty((3, 3), dtype=np.int64)       # per axis: the nodes touched
    w = np.empty((3, 3))
    dw = np.empty((3, 3))
    stride = np.empty(3, dtype=np.int64)
    stride[0] = 1
    for d in range(1, dim):
        stride[d] = stride[d - 1] * ghost_shape[d - 1]
    offset = np.empty((nn, dim), dtype=np.int64)     # footprint entry k's node slot per axis, x fastest
    for k in range(nn):
        rest = k
        for d in range(dim):
            offset[k, d] = rest % npa
            rest //= npa
    for p in range(n):
        for d in range(dim):
            xi = (x[p, d] - lower[d]) / spacing[d]
            base = _first_node(kind, xi, cells[d])
            if kind == LINEAR:
                f = xi - base
                node[d, 0], node[d, 1] = base, base + 1
                w[d, 0], w[d, 1] = 1.0 - f, f
                dw[d, 0], dw[d, 1] = -1.0, 1.0
            else:
                half = half_size[p, d] / spacing[d] if kind == GIMP else 0.0
                for k in range(3):
                    node[d, k] = base + k
                    if kind == GIMP:
                        w[d, k], dw[d, k] = _gimp_1d(xi - (base + k), half)
                        if base + k < 0 or base + k > cells[d]:
                            w[d, k] = 0.0
                            dw[d, k] = 0.0
                    else:
                        w[d, k], dw[d, k] = _bspline_1d(xi - (base + k))
                if kind == BSPLINE:
                    # boundary modification: fold the phantom node outside a face
                    # onto the face node and its neighbour (pimpm.shape)
                    if base < 0:
                        _fold(w, d, 0, 2)
                        _fold(dw, d, 0, 2)
                    if base + 2 > cells[d]:
                        _fold(w, d, 2, 0)
                        _fold(dw, d, 2, 0)
                for k in range(3):
                    node[d, k] = min(max(node[d, k], 0), cells[d])
            for k in range(npa):
                dw[d, k] /= spacing[d]
        for k in range(nn):
            _tensor_products(dim, k, p, offset, node, w, dw, ghost_start, stride, node_index, S, G)


@jit
def footprints_in_box(kind, x, lower, spacing, cells, box_start, box_end):
    """Do the footprints of all positions x (n, dim) -- the nodes
    :func:`footprint` gives them, clipped onto the grid -- lie in the node
    box [box_start, box_end)? (The explicit step's lazy migration asks it of
    each rank's ghosted nodes.)"""
    npa = 2 if kind == LINEAR else 3
    for p in range(x.shape[0]):
        for d in range(x.shape[1]):
            xi = (x[p, d] - lower[d]) / spacing[d]
            if not (xi == xi):
                return False
            base = _first_node(kind, xi, cells[d])
            first = min(max(base, 0), cells[d])
            last = min(max(base + npa - 1, 0), cells[d])
            if first < box_start[d] or last >= box_end[d]:
                return False
    return True


@jit_inline
def _tensor_products(dim, k, p, offset, node, w, dw, ghost_start, stride, node_index, S, G):
    """Footprint entry k of particle p from the per-axis nodes, weights and
    slopes: its node, S = prod_d w_d and G_d = dw_d prod_(e != d) w_e,
    written out per dimension (numba leaves loops of length dim rolled:
    the whole footprint took 1.6 times as long with them)."""
    i, j = offset[k, 0], offset[k, 1]
    if dim == 2:
        node_index[p, k] = (node[0, i] - ghost_start[0]) + (node[1, j] - ghost_start[1]) * stride[1]
        S[p, k] = w[0, i] * w[1, j]
        G[p, k, 0] = dw[0, i] * w[1, j]
        G[p, k, 1] = w[0, i] * dw[1, j]
    else:
        m = offset[k, 2]
        node_index[p, k] = ((node[0, i] - ghost_start[0]) + (node[1, j] - ghost_start[1]) * stride[1]
                            + (node[2, m] - ghost_start[2]) * stride[2])
        S[p, k] = w[0, i] * w[1, j] * w[2, m]
        G[p, k, 0] = dw[0, i] * w[1, j] * w[2, m]
        G[p, k, 1] = w[0, i] * dw[1, j] * w[2, m]
        G[p, k, 2] = w[0, i] * w[1, j] * dw[2, m]


@jit
def scatter(node_index, weights, values, n_nodes, out):
    """out[i] = sum over pairs (p, k) with node i of weights[p, k] values[p]
    (``values`` (n, m), ``out`` (n_nodes, m), zeroed here): MPM intro eq. 2-4."""
    out[:] = 0.0
    n, nn = node_index.shape
    m = values.shape[1]
    for p in range(n):
        for k in range(nn):
            wk = weights[p, k]
            i = node_index[p, k]
            for c in range(m):
                out[i, c] += wk * values[p, c]


@jit
def gather(node_index, weights, nodal, out):
    """out[p] = sum_k weights[p, k] nodal[node_index[p, k]] (``nodal``
    (n_nodes, m), ``out`` (n, m)): MPM intro eq. 8-10."""
    n, nn = node_index.shape
    m = nodal.shape[1]
    for p in range(n):
        for c in range(m):
            s = 0.0
            for k in range(nn):
                s += weights[p, k] * nodal[node_index[p, k], c]
            out[p, c] = s


@jit
def _scaled_norm2(G, p, k, spacing, dim):
    """|h G_pk|^2 (h the cell size per axis)."""
    s = 0.0
    for d in range(dim):
        hg = spacing[d] * G[p, k, d]
        s += hg * hg
    return s


@jit
def gradient_weight(node_index, G, spacing, mass, out):
    """out[i] = sum_p m_p |h G_ip|^2 (zeroed here): a node no particle's
    gradient reaches has none (it has no stiffness either)."""
    out[:] = 0.0
    n, nn = node_index.shape
    dim = G.shape[2]
    for p in range(n):
        for k in range(nn):
            out[node_index[p, k]] += mass[p] * _scaled_norm2(G, p, k, spacing, dim)


@jit
def fold_weak_nodes(axes, nodes_per_axis, node_index, S, G, weak, faces, strong, ghost_start,
                    ghost_shape):
    """Extend the weakly supported nodes (``weak``, ghosted-local flags) out
    of the footprint (pimpm.weak_nodes). For each particle and each weak
    node at an end of its stencil along some axes, the smallest sets D of
    those axes are found along which every node 1 or 2 steps inward is a
    genuine node (not clipped onto the grid) that may take its weight (not
    weak, and ``faces``, the bits of the components the grid faces prescribe,
    -1 where a tool holds the node, equal to the weak node's: a free node's
    weight goes to free nodes, a symmetry plane's to that plane); the weak node's weight and
    gradient go to those nodes with the tensor product of the linear
    extrapolation weights (+2 one step in, -1 two steps in, per axis of D),
    shared equally among the sets found (so that no axis comes first).
    Linear fields stay exact; the weak node keeps no weight.

    A weak node in the middle of a particle's stencil along every axis (the
    particle's nearest node: a lone particle at a fold of the surface) has
    no inward node two steps away inside the stencil; its weight goes to the
    parallelogram one step away along two axes (+1, +1, -1: u_I = u_{I-a} +
    u_{I-b} - u_{I-a-b}, exact for linear fields), over every pair of axes
    and sides whose three nodes are genuine, take weight as above and are
    ``strong`` (have support of their own), shared equally. Returns the number of
    (particle, node) pairs folded."""
    dim = len(axes)
    n, nn = S.shape
    npa = nodes_per_axis
    stride = np.empty(3, dtype=np.int64)     # stencil slot strides
    gstride = np.empty(3, dtype=np.int64)    # ghosted-local node strides
    stride[0] = 1
    gstride[0] = 1
    for d in range(1, dim):
        stride[d] = stride[d - 1] * npa
        gstride[d] = gstride[d - 1] * ghost_shape[d - 1]
    o = np.empty(3, dtype=np.int64)
    inward = np.empty(3, dtype=np.int64)
    good = np.zeros(8, dtype=np.bool_)       # per subset of axes (bit mask)
    folded = 0
    for p in range(n):
        for s in range(nn):
            node = node_index[p, s]
            if not weak[node] or S[p, s] == 0.0:
                continue
            ends = 0
            for d in range(dim):
                o[d] = (s // stride[d]) % npa
                inward[d] = 1 if o[d] == 0 else -1
                if o[d] != 1:
                    ends |= 1 << d
            if ends == 0:
                if dim > 1 and _fold_middle(p, s, node, dim, stride, gstride, ghost_shape,
                                            node_index, S, G, faces, strong):
                    folded += 1
                continue
            # the smallest subsets of the end axes whose 2^|D| targets all qualify
            count = 0
            for size in range(1, dim + 1):
                for mask in range(1, 1 << dim):
                    good[mask] = False
                    if (mask & ends) != mask or _bits(mask) != size:
                        continue
                    ok = True
                    for code in range(1 << size):
                        t = _target(s, node, mask, code, dim, inward, stride, gstride, ghost_shape,
                                    node_index, p)
                        if t < 0 or weak[node_index[p, t]] or faces[node_index[p, t]] != faces[node]:
                            ok = False
                            break
                    good[mask] = ok
                    if ok:
                        count += 1
                if count > 0:
                    break
            if count == 0:
                continue
            w, g = S[p, s] / count, np.empty(dim)
            for e in range(dim):
                g[e] = G[p, s, e] / count
            S[p, s] = 0.0
            for e in range(dim):
                G[p, s, e] = 0.0
            for mask in range(1, 1 << dim):
                if not good[mask]:
                    continue
                size = _bits(mask)
                for code in range(1 << size):
                    t = _target(s, node, mask, code, dim, inward, stride, gstride, ghost_shape,
                                node_index, p)
                    c = 1.0
                    for b in range(size):
                        c *= -1.0 if (code >> b) & 1 else 2.0
                    S[p, t] += c * w
                    for e in range(dim):
                        G[p, t, e] += c * g[e]
            folded += 1
    return folded


@jit
def _fold_middle(p, s, node, dim, stride, gstride, ghost_shape, node_index, S, G, faces, strong):
    """Fold the weak node in the middle slot ``s`` of particle ``p``'s
    stencil onto the parallelograms one step away along two axes (see
    fold_weak_nodes); False (nothing changed) if none qualifies."""
    slots = np.empty((12, 3), dtype=np.int64)       # at most 3 pairs x 4 sides in 3D
    count = 0
    for a in range(dim):
        for b in range(a + 1, dim):
            for sa in (-1, 1):
                for sb in (-1, 1):
                    ta = s + sa * stride[a]
                    tb = s + sb * stride[b]
                    tab = ta + sb * stride[b]
                    ok = True
                    for t, da, db in ((ta, sa, 0), (tb, 0, sb), (tab, sa, sb)):
                        target = node_index[p, t]
                        if not strong[target] or faces[target] != faces[node]:   # strong: not weak
                            ok = False
                            break
                        for d in range(dim):
                            i0 = (node // gstride[d]) % ghost_shape[d]
                            i1 = (target // gstride[d]) % ghost_shape[d]
                            step = da if d == a else (db if d == b else 0)
                            if i1 != i0 + step:
                                ok = False
                        if not ok:
                            break
                    if ok:
                        slots[count, 0] = ta
                        slots[count, 1] = tb
                        slots[count, 2] = tab
                        count += 1
    if count == 0:
        return False
    w = S[p, s] / count
    g = np.empty(dim)
    for e in range(dim):
        g[e] = G[p, s, e] / count
    S[p, s] = 0.0
    for e in range(dim):
        G[p, s, e] = 0.0
    for c in range(count):
        for k in range(3):
            sign = -1.0 if k == 2 else 1.0
            t = slots[c, k]
            S[p, t] += sign * w
            for e in range(dim):
                G[p, t, e] += sign * g[e]
    return True


@jit
def _bits(mask):
    c = 0
    while mask:
        c += mask & 1
        mask >>= 1
    return c


@jit
def _target(s, node, mask, code, dim, inward, stride, gstride, ghost_shape, node_index, p):
    """The stencil slot 1 or 2 steps inward from slot ``s`` along the axes of
    ``mask`` (bit b of ``code``: 2 steps along the b-th axis of the mask), or
    -1 if a node on the way is clipped onto the grid (not genuine)."""
    t = s
    b = 0
    for d in range(dim):
        if (mask >> d) & 1:
            steps = 2 if (code >> b) & 1 else 1
            t += steps * inward[d] * stride[d]
            b += 1
    # genuine: the target's grid index along each folded axis is the weak node's plus the steps
    target = node_index[p, t]
    b = 0
    for d in range(dim):
        i0 = (node // gstride[d]) % ghost_shape[d]
        i1 = (target // gstride[d]) % ghost_shape[d]
        steps = 0
        if (mask >> d) & 1:
            steps = 2 if (code >> b) & 1 else 1
            b += 1
        if i1 != i0 + steps * inward[d]:
            return -1
    return t


@jit
def gimp_half_sizes(half_size, F, cap, out):
    """out[p, d] = min(half_size[p, d] |F[p, d, d]|, cap[d]): the GIMP
    particle domains convected by the diagonal of F (:meth:`pimpm.simulation.
    Simulation.particle_half_sizes`); a NaN stays NaN, as with np.minimum."""
    for p in range(half_size.shape[0]):
        for d in range(half_size.shape[1]):
            v = half_size[p, d] * abs(F[p, d, d])
            out[p, d] = cap[d] if v > cap[d] else v
