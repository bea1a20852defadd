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
from .pattern import box_offsets, stencil_slot
from .small import det3, inv2, inv3

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
def _particle_vectors(kinematics, dim, p, active, S, G, radius, F_inc, fbar_q, Finv, g, rows, cols):
    """Particle p's row vector v Q g_k (rows[k]) and divergence vector g_k
    (cols[k]) at each of its nodes k, g = F_inc^-T G, with the axisymmetric
    hoop strain du_r / r and its row (S_k / r, r the current radius);
    ``Finv``, ``g``: scratch. Inactive entries are left as they are."""
    nn = active.shape[1]
    for a in range(3):
        for b in range(3):
            Finv[a, b] = 0.0
    if dim == 2:
        inv2(F_inc[p], Finv)
    else:
        inv3(F_inc[p], Finv)
    r = radius[p] * F_inc[p, 2, 2] if kinematics == _AXISYMMETRIC else 1.0
    for k in range(nn):
        if not active[p, k]:
            continue
        for d in range(dim):
            s = 0.0
            for cc in range(dim):
                s += G[p, k, cc] * Finv[cc, d]
            g[d] = s
        for a in range(dim):
            s = 0.0
            for cc in range(dim):
                s += g[cc] * fbar_q[p, a, cc]
            rows[k, a] = s
            cols[k, a] = g[a]
        if kinematics == _AXISYMMETRIC:
            w = S[p, k] / r
            rows[k, 0] += w * fbar_q[p, 2, 2]
            cols[k, 0] += w


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
    rows = np.empty((nn, 3))
    cols = np.empty((nn, 3))
    outside = 0
    for i in range(first, last):
        p = order[i]
        _particle_vectors(kinematics, dim, p, active, S, G, radius, F_inc, fbar_q, Finv, g, rows, cols)
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
            for a in range(dim):
                R[slot, a] += rows[k, a]
                D[slot, a] += weight * cols[k, a]
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


# ----------------------------------------------------------------- averaged on the nodes
#
# J_bar_p = sum_I S+_Ip J_I / sum_I S+_Ip,  J_I = sum_q S+_Iq V_q J_q / W_I,  W_I = sum_q S+_Iq V_q,
#
# S+ = max(S, 0) (the weak-node extension can make a weight negative), V the volume at the step's
# start, J = det F_inc, sums over the averaged particles of every rank. Its variation
# dJ_bar_p / J_bar_p = sum_I (S+_Ip / (s_p J_bar_p)) sum_q (S+_Iq V_q J_q / W_I) div_q (s_p the sum of
# p's weights) makes the coupling sum_I R_I (x) D_I, rank one per node:
#
#   R_I = sum_p (S+_Ip / (s_p J_bar_p)) v_p Q_p g_p,   D_I = sum_q (S+_Iq V_q J_q / W_I) g_q
#
# over the nodes that particles reaching I reach: a box of 2 (nodes per axis) - 1 per axis about I.
# Each rank sums its particles' shares into (n_local_nodes, slots, dim) boxes, the owner of I adds
# them up (pimpm.fbar.AveragedNodes) and adds R_I (x) D_I, whose rows and columns lie within
# nodes-per-axis - 1 <= the DMDA's stencil width of I.

@jit
def node_sums(node_index, active, S, volume_n, F_inc, averaged, weights, out):
    """out[I] += S+_Ip V_p (``weights``) or S+_Ip V_p det F_inc,p over the
    particles with ``averaged`` >= 0 (``out``: ghosted-local, not zeroed)."""
    nn = node_index.shape[1]
    for p in range(S.shape[0]):
        if averaged[p] < 0:
            continue
        value = volume_n[p] if weights else volume_n[p] * det3(F_inc[p])
        for k in range(nn):
            if active[p, k] and S[p, k] > 0.0:
                out[node_index[p, k]] += S[p, k] * value


@jit
def node_average(node_index, active, S, averaged, J_node, jbar):
    """jbar[p] = sum_k S+_pk J_node[k] / sum_k S+_pk for the averaged
    particles (1 for the others: not used)."""
    nn = node_index.shape[1]
    for p in range(S.shape[0]):
        jbar[p] = 1.0
        if averaged[p] < 0:
            continue
        num = 0.0
        den = 0.0
        for k in range(nn):
            if active[p, k] and S[p, k] > 0.0:
                num += S[p, k] * J_node[node_index[p, k]]
                den += S[p, k]
        if den > 0.0:
            jbar[p] = num / den


@jit
def _node_box_slot(centre, node, node_ijk, dim, half):
    """Slot of ``node`` in the box of 2 half + 1 nodes per axis about ``centre`` (x fastest), -1 outside."""
    side = 2 * half + 1
    slot = 0
    for d in range(dim - 1, -1, -1):
        o = node_ijk[node, d] - node_ijk[centre, d] + half
        if o < 0 or o >= side:
            return -1
        slot = slot * side + o
    return slot


@jit
def node_presence(node_index, active, S, averaged, node_ijk, dim, half, out):
    """out[I, slot of K] += 1 for every averaged particle reaching I (S+ > 0)
    and K (``out``: (n_local_nodes, slots), not zeroed): where R_I and D_I
    can be nonzero. Returns the number of footprint nodes outside a box (0
    unless ``half`` is too small: a bug)."""
    nn = node_index.shape[1]
    outside = 0
    for p in range(S.shape[0]):
        if averaged[p] < 0:
            continue
        for k0 in range(nn):
            if not (active[p, k0] and S[p, k0] > 0.0):
                continue
            centre = node_index[p, k0]
            for k in range(nn):
                if active[p, k]:
                    slot = _node_box_slot(centre, node_index[p, k], node_ijk, dim, half)
                    if slot < 0:
                        outside += 1
                    else:
                        out[centre, slot] += 1.0
    return outside


@jit
def node_vectors(kinematics, dim, node_index, active, S, G, radius, F_inc, fbar_q, averaged, volume_n, jbar,
                 weight_sum, node_ijk, half, R, D):
    """This rank's shares of R_I and D_I (``R``, ``D``: (n_local_nodes,
    slots, dim), not zeroed; ``weight_sum``: W_I of every rank's particles
    on the ghosted-local nodes). Returns the number of footprint nodes
    outside a box (0 unless ``half`` is too small: a bug)."""
    nn = node_index.shape[1]
    Finv = np.zeros((3, 3))
    g = np.empty(3)
    rows = np.empty((nn, 3))
    cols = np.empty((nn, 3))
    outside = 0
    for p in range(S.shape[0]):
        if averaged[p] < 0:
            continue
        share = 0.0
        for k in range(nn):
            if active[p, k] and S[p, k] > 0.0:
                share += S[p, k]
        if share <= 0.0:
            continue
        J = det3(F_inc[p])
        _particle_vectors(kinematics, dim, p, active, S, G, radius, F_inc, fbar_q, Finv, g, rows, cols)
        for k0 in range(nn):
            if not (active[p, k0] and S[p, k0] > 0.0):
                continue
            centre = node_index[p, k0]
            row_factor = S[p, k0] / (share * jbar[p])
            col_factor = S[p, k0] * volume_n[p] * J / weight_sum[centre]
            for k in range(nn):
                if not active[p, k]:
                    continue
                slot = _node_box_slot(centre, node_index[p, k], node_ijk, dim, half)
                if slot < 0:
                    outside += 1
                    continue
                for a in range(dim):
                    R[centre, slot, a] += row_factor * rows[k, a]
                    D[centre, slot, a] += col_factor * cols[k, a]
    return outside


@jit
def _each_node(mode, dim, half, centres, R, D, ghost_x, ghost_y, x, out, width, indptr, slot_position, values):
    """One pass over the owned nodes ``centres``: add R_I (x) D_I into the
    block CSR ``values`` (_BLOCKS), R_I (D_I . x) into ``out`` (_PRODUCT)
    or the diagonal of R_I (x) D_I into ``out`` (_DIAGONAL). Slots whose
    R or D are all zero are skipped (they hold no particle's share).
    Returns the number of couplings missing from the pattern (0 unless the
    pattern is wrong: a bug)."""
    slots = R.shape[1]
    wide = 2 * width + 1
    # each box slot's offsets from the centre, and its node's offset in the ghosted numbering
    offset, shift = box_offsets(half, dim, ghost_x, ghost_y)
    rows = np.empty(slots, dtype=np.int64)
    cols = np.empty(slots, dtype=np.int64)
    missing = 0
    for I in centres:
        n_rows = 0
        n_cols = 0
        for s in range(slots):
            r_used = False
            d_used = False
            for a in range(dim):
                if R[I, s, a] != 0.0:
                    r_used = True
                if D[I, s, a] != 0.0:
                    d_used = True
            if r_used:
                rows[n_rows] = s
                n_rows += 1
            if d_used:
                cols[n_cols] = s
                n_cols += 1
        if mode == _PRODUCT:
            mean = 0.0
            for c in range(n_cols):
                t = cols[c]
                j = I + shift[t]
                for b in range(dim):
                    mean += D[I, t, b] * x[j, b]
            for r in range(n_rows):
                s = rows[r]
                i = I + shift[s]
                for a in range(dim):
                    out[i, a] += R[I, s, a] * mean
        elif mode == _DIAGONAL:
            for r in range(n_rows):
                s = rows[r]
                i = I + shift[s]
                for a in range(dim):
                    out[i, a] += R[I, s, a] * D[I, s, a]
        else:
            for r in range(n_rows):
                s = rows[r]
                i = I + shift[s]
                row = dim * dim * indptr[i]
                stride = (indptr[i + 1] - indptr[i]) * dim
                for c in range(n_cols):
                    t = cols[c]
                    slot = 0                    # stencil_slot(i, j): the offset of t from s
                    for d in range(dim - 1, -1, -1):
                        slot = slot * wide + offset[t, d] - offset[s, d] + width
                    position = slot_position[i, slot]
                    if position < 0:
                        missing += 1
                        continue
                    base = row + (position - indptr[i]) * dim
                    for a in range(dim):
                        ra = R[I, s, a]
                        for b in range(dim):
                            values[base + a * stride + b] += ra * D[I, t, b]
    return missing


def node_blocks(half, centres, R, D, ghost_x, ghost_y, width, indptr, slot_position, values):
    """Add R_I (x) D_I of the owned nodes ``centres`` (ghosted-local; ``R``,
    ``D``: (n_nodes, slots, dim), every rank's shares summed on them; the
    ghosted box ``ghost_x`` by ``ghost_y`` nodes) into ``values`` (not
    zeroed). Returns the number of couplings missing from the pattern."""
    return _each_node(_BLOCKS, R.shape[2], half, centres, R, D, ghost_x, ghost_y, _NO_FLOAT2, _NO_FLOAT2,
                      width, indptr, slot_position, values)


def node_product(half, centres, R, D, ghost_x, ghost_y, x, out):
    """out += sum_I R_I (D_I . x) (``x``, ``out``: ghosted-local (n_nodes, dim))."""
    return _each_node(_PRODUCT, R.shape[2], half, centres, R, D, ghost_x, ghost_y, x, out, 0, _NO_INT,
                      _NO_INT2, _NO_FLOAT)


def node_diagonal(half, centres, R, D, ghost_x, ghost_y, out):
    """out += the diagonal of sum_I R_I (x) D_I."""
    return _each_node(_DIAGONAL, R.shape[2], half, centres, R, D, ghost_x, ghost_y, _NO_FLOAT2, out, 0,
                      _NO_INT, _NO_INT2, _NO_FLOAT)
