"""The cell coupling of the F-bar tangent (de Souza Neto, Peric, Dutko &
Owen 1996; for MPM, Coombs, Charlton, Cortis & Augarde 2018).

With F-bar, particle p of cell c feels F_inc_bar = (J_bar / J_inc)^(1/n)
F_inc, J_bar the volume-weighted mean increment of c's particles
(:func:`pimpm.kernels.particle_step.evaluate_particles`). Its internal
force Fint_ka = v g_kc sigma_ac (sigma of F_bar) then varies, besides the
standard terms, by

    v g_kc Q_ac (div_bar - div_p),    Q = (c_acbb - (n - 2) sigma_ac) / n,

where div_p = sum_m g_mb du_mb (plus the hoop strain du_r / r) is the
divergence of the variation at p and div_bar = sum_q (v_q / V_c) div_q its
volume-weighted mean over the cell. The -div_p part is the particle's own
and joins its stiffness density in the particle kernel; the div_bar part,
R_c (x) D_c with R_c = sum_p v_p Q_p g_p (the rows) and D_c = sum_q (v_q /
V_c) g_q (the columns), couples every node that any particle of the cell
reaches with every other: the cell's union footprint, one node wider per
axis than a particle's for GIMP and the B-splines (the pattern's stencil
grows by one; :func:`pimpm.kernels.pattern.mark_cells`). Particles of a cell all live on the
rank that owns the cell (pimpm distributes them by cell), so the average
is local.

Each cell's union footprint is gathered in a box of ``side`` nodes per
axis (a particle's nodes per axis + 1) anchored at the lowest node any of
its particles reaches.
"""
import numpy as np

from .jit import jit
from .pattern import stencil_slot
from .small import inv2, inv3

#: kinematics code of the particle kernels (pimpm.kernels.particle_step.AXISYMMETRIC)
_AXISYMMETRIC = 2


def cell_groups(fbar_cell, n_cells):
    """(order, start): the averaged particles sorted by cell (stable) and
    the first of each cell's in that order (n_cells + 1 entries)."""
    averaged = np.flatnonzero(fbar_cell >= 0)
    order = averaged[np.argsort(fbar_cell[averaged], kind="stable")].astype(np.int64)
    counts = np.bincount(fbar_cell[averaged], minlength=n_cells)
    start = np.zeros(n_cells + 1, dtype=np.int64)
    np.cumsum(counts, out=start[1:])
    return order, start


@jit
def _box_origin(order, first, last, node_index, active, node_ijk, dim, origin):
    """origin[d] = the lowest multi-index along d of the nodes the cell's particles reach."""
    nn = node_index.shape[1]
    for d in range(dim):
        origin[d] = 1 << 60
    for i in range(first, last):
        p = order[i]
        for k in range(nn):
            if active[p, k]:
                for d in range(dim):
                    v = node_ijk[node_index[p, k], d]
                    if v < origin[d]:
                        origin[d] = v


@jit
def _box_slot(node, node_ijk, origin, dim, side):
    """Slot of ``node`` in the cell's box, or -1 if it lies outside."""
    slot = 0
    for d in range(dim - 1, -1, -1):
        o = node_ijk[node, d] - origin[d]
        if o < 0 or o >= side:
            return -1
        slot = slot * side + o
    return slot


@jit
def _cell_vectors(kinematics, dim, order, first, last, node_index, active, S, G, radius, F_inc, fbar_q,
                  fbar_weight, node_ijk, origin, side, box_node, R, D):
    """Fill the box of the cell whose particles are order[first:last]: its
    ``origin``, R_c (rows) and D_c (columns) over its slots (zeroed here;
    ``box_node``: the ghosted-local node of each slot, -1 if none).
    Returns the number of footprint nodes outside the box (0 unless the
    box is too small: a bug)."""
    nn = node_index.shape[1]
    _box_origin(order, first, last, node_index, active, node_ijk, dim, origin)
    box_node[:] = -1
    R[:] = 0.0
    D[:] = 0.0
    Finv = np.zeros((3, 3))
    g = np.empty(3)
    outside = 0
    for i in range(first, last):
        p = order[i]
        for a in range(3):
            for b in range(3):
                Finv[a, b] = 0.0
        if dim == 2:
            inv2(F_inc[p], Finv)
        else:
            inv3(F_inc[p], Finv)
        r = radius[p] * F_inc[p, 2, 2] if kinematics == _AXISYMMETRIC else 1.0
        weight = fbar_weight[p]
        for k in range(nn):
            if not active[p, k]:
                continue
            node = node_index[p, k]
            slot = _box_slot(node, node_ijk, origin, dim, side)
            if slot < 0:
                outside += 1
                continue
            box_node[slot] = node
            for d in range(dim):                      # g = F_inc^-T G
                s = 0.0
                for cc in range(dim):
                    s += G[p, k, cc] * Finv[cc, d]
                g[d] = s
            for a in range(dim):
                s = 0.0
                for cc in range(dim):
                    s += g[cc] * fbar_q[p, a, cc]
                R[slot, a] += s
                D[slot, a] += weight * g[a]
            if kinematics == _AXISYMMETRIC:           # the hoop strain du_r / r and its row
                w = S[p, k] / r
                R[slot, 0] += w * fbar_q[p, 2, 2]
                D[slot, 0] += weight * w
    return outside


#: what a pass over the cells does (:func:`_each_cell`)
_BLOCKS, _PRODUCT, _DIAGONAL = 0, 1, 2


@jit
def _each_cell(mode, kinematics, dim, side, order, start, node_index, active, S, G, radius, F_inc, fbar_q,
               fbar_weight, node_ijk, x, out, width, indptr, slot_position, values):
    """One pass over the cells: add R_c (x) D_c into the block CSR
    ``values`` (_BLOCKS), R_c (D_c . x) into ``out`` (_PRODUCT) or the
    diagonal of R_c (x) D_c into ``out`` (_DIAGONAL). Returns the number
    of footprint nodes outside their cell's box."""
    slots = side ** dim
    origin = np.empty(dim, dtype=np.int64)
    box_node = np.empty(slots, dtype=np.int64)
    R = np.empty((slots, dim))
    D = np.empty((slots, dim))
    outside = 0
    for c in range(len(start) - 1):
        if start[c] == start[c + 1]:
            continue
        outside += _cell_vectors(kinematics, dim, order, start[c], start[c + 1], node_index, active, S, G,
                                 radius, F_inc, fbar_q, fbar_weight, node_ijk, origin, side, box_node, R, D)
        mean = 0.0                                   # _PRODUCT: div_bar of x
        if mode == _PRODUCT:
            for t in range(slots):
                if box_node[t] >= 0:
                    for b in range(dim):
                        mean += D[t, b] * x[box_node[t], b]
        for s in range(slots):
            i = box_node[s]
            if i < 0:
                continue
            if mode == _PRODUCT:
                for a in range(dim):
                    out[i, a] += R[s, a] * mean
            elif mode == _DIAGONAL:
                for a in range(dim):
                    out[i, a] += R[s, a] * D[s, a]
            else:
                row = dim * dim * indptr[i]
                stride = (indptr[i + 1] - indptr[i]) * dim
                for t in range(slots):
                    j = box_node[t]
                    if j < 0:
                        continue
                    base = row + (slot_position[i, stencil_slot(i, j, node_ijk, dim, width)] - indptr[i]) * dim
                    for a in range(dim):
                        for b in range(dim):
                            values[base + a * stride + b] += R[s, a] * D[t, b]
    return outside


_NO_INT = np.zeros(0, dtype=np.int64)
_NO_INT2 = np.zeros((0, 0), dtype=np.int64)
_NO_FLOAT = np.zeros(0)
_NO_FLOAT2 = np.zeros((0, 0))


def cell_blocks(kinematics, axes, side, order, start, node_index, active, S, G, radius, F_inc, fbar_q,
                fbar_weight, node_ijk, width, indptr, slot_position, values):
    """Add every cell's R_c (x) D_c into ``values`` (the tangent's block
    CSR values of :func:`pimpm.kernels.particle_step.tangent_blocks`, not
    zeroed). Returns the number of footprint nodes outside their cell's box."""
    return _each_cell(_BLOCKS, kinematics, len(axes), side, order, start, node_index, active, S, G, radius, F_inc,
                      fbar_q, fbar_weight, node_ijk, _NO_FLOAT2, _NO_FLOAT2, width, indptr, slot_position, values)


def cell_product(kinematics, axes, side, order, start, node_index, active, S, G, radius, F_inc, fbar_q,
                 fbar_weight, node_ijk, x, out):
    """out += sum_c R_c (D_c . x) (``x``, ``out``: ghosted-local (n_nodes,
    dim); ``out`` not zeroed): the cell coupling applied to a vector."""
    return _each_cell(_PRODUCT, kinematics, len(axes), side, order, start, node_index, active, S, G, radius, F_inc,
                      fbar_q, fbar_weight, node_ijk, x, out, 0, _NO_INT, _NO_INT2, _NO_FLOAT)


def cell_diagonal(kinematics, axes, side, order, start, node_index, active, S, G, radius, F_inc, fbar_q,
                  fbar_weight, node_ijk, out):
    """out += the diagonal of sum_c R_c (x) D_c (``out`` not zeroed)."""
    return _each_cell(_DIAGONAL, kinematics, len(axes), side, order, start, node_index, active, S, G, radius,
                      F_inc, fbar_q, fbar_weight, node_ijk, _NO_FLOAT2, out, 0, _NO_INT, _NO_INT2, _NO_FLOAT)
