"""The nonzero pattern of the consistent tangent, from the particle
footprints of one step: node i couples with node j when some particle's
shape functions reach both (G&W step 3). Nodes are ghosted-local DMDA
nodes; a pattern is a block CSR (one dim x dim block per coupled node pair,
columns sorted) plus, for the tangent kernel, the position of each coupling
given as (row node, stencil slot), so that the kernel adds a particle's
block where it belongs without a search.

The values are kept in the layout of the equivalent scalar CSR (row
(i, a) holds the blocks of node row i, component row a, one after the
other; :func:`scalar_csr` gives its indptr and indices): PETSc takes them
in one call as COO values in that order (:mod:`pimpm.coo`), or one scalar
row per call (``MatSetValuesLocal``) where COO is not available.

Nodes that no particle reaches (the empty background grid) only get their
diagonal block: they are out of the coupled system and cost the direct
solver nothing (docs/PERFORMANCE.md).
"""
import numpy as np

from .jit import jit


@jit
def active_entries(S, G):
    """(n, nn) True where a footprint entry carries a weight or a gradient
    (GIMP and boundary-modified B-splines list nodes with both zero)."""
    n, nn = S.shape
    dim = G.shape[2]
    out = np.zeros((n, nn), dtype=np.bool_)
    for p in range(n):
        for k in range(nn):
            on = S[p, k] != 0.0
            for d in range(dim):
                on = on or G[p, k, d] != 0.0
            out[p, k] = on
    return out


@jit
def stencil_slot(i, j, node_ijk, dim, width):
    """Slot of node j in the (2 width + 1)^dim box around node i (x
    fastest), both ghosted-local nodes; ``node_ijk`` (n_nodes, dim) holds
    every node's ghosted-local multi-index (:meth:`pimpm.grid.Grid.ghost_ijk`)."""
    side = 2 * width + 1
    slot = 0
    for d in range(dim - 1, -1, -1):
        slot = slot * side + node_ijk[j, d] - node_ijk[i, d] + width
    return slot


@jit
def mark_cells(order, start, node_index, active, node_ijk, dim, width, mark):
    """mark[i, slot of j] = True for every pair of nodes (i, j) that
    particles of one cell reach (the couplings of :func:`pimpm.kernels.fbar.cell_blocks`)."""
    n_nodes_max = node_index.shape[1] * 64
    nodes = np.empty(n_nodes_max, dtype=np.int64)
    for c in range(len(start) - 1):
        count = 0
        for i in range(start[c], start[c + 1]):
            p = order[i]
            for k in range(node_index.shape[1]):
                if not active[p, k]:
                    continue
                node = node_index[p, k]
                seen = False
                for q in range(count):
                    if nodes[q] == node:
                        seen = True
                        break
                if not seen and count < n_nodes_max:
                    nodes[count] = node
                    count += 1
        for a in range(count):
            for b in range(count):
                mark[nodes[a], stencil_slot(nodes[a], nodes[b], node_ijk, dim, width)] = True


@jit
def box_offsets(half, dim, ghost_x, ghost_y):
    """(offset, shift) of the box of 2 half + 1 nodes per axis about a node
    (slots x fastest): each slot's offset from the centre along x, y, z
    (slots, 3), and its node's offset in the ghosted-local numbering of a
    box ``ghost_x`` by ``ghost_y`` nodes (slots,)."""
    side = 2 * half + 1
    slots = side ** dim
    offset = np.zeros((slots, 3), dtype=np.int64)
    shift = np.zeros(slots, dtype=np.int64)
    gy = ghost_y if dim == 3 else 1
    for s in range(slots):
        offset[s, 0] = s % side - half
        offset[s, 1] = (s // side) % side - half
        offset[s, 2] = s // (side * side) - half if dim == 3 else 0
        shift[s] = offset[s, 0] + ghost_x * (offset[s, 1] + gy * offset[s, 2])
    return offset, shift


@jit
def mark_boxes(centres, presence, half, node_ijk, dim, width, ghost_x, ghost_y, mark):
    """mark[i, slot of j] = True for every pair of nodes (i, j) present in
    the box of 2 half + 1 nodes per axis about one of the ``centres``
    (``presence`` (n_nodes, slots) > 0; the couplings of
    :func:`pimpm.kernels.fbar.node_blocks`)."""
    slots = presence.shape[1]
    nodes = np.empty(slots, dtype=np.int64)
    shift = box_offsets(half, dim, ghost_x, ghost_y)[1]
    for centre in centres:
        count = 0
        for s in range(slots):
            if presence[centre, s] > 0.0:
                nodes[count] = centre + shift[s]
                count += 1
        for a in range(count):
            for b in range(count):
                mark[nodes[a], stencil_slot(nodes[a], nodes[b], node_ijk, dim, width)] = True


@jit
def block_pattern(node_index, active, node_ijk, dim, width, owned_nodes, n_nodes, ghost_x, ghost_y,
                  cell_order, cell_start, box_centres, box_presence, box_half):
    """Block CSR of the couplings (indptr over all ghosted-local nodes,
    column node indices sorted; ``ghost_x``, ``ghost_y``: the ghosted box's
    nodes along x and y) and slot_position (n_nodes, slots): the
    block's position in the CSR, -1 where uncoupled. Every owned node keeps
    its diagonal block (the mass term and prescribed rows need it).
    ``cell_order``, ``cell_start`` (:func:`pimpm.kernels.fbar.cell_groups`;
    empty without F-bar): the nodes that particles of one averaged cell
    reach are coupled too (the F-bar cell coupling). ``box_centres``,
    ``box_presence``, ``box_half`` (empty without F-bar on the nodes): the
    nodes present in each centre's box are coupled (:func:`mark_boxes`)."""
    side = 2 * width + 1
    slots = side ** dim
    centre = (slots - 1) // 2
    mark = np.zeros((n_nodes, slots), dtype=np.bool_)
    n, nn = node_index.shape
    for p in range(n):
        if p > 0:                       # particles sorted by footprint: neighbours often share one
            same = True
            for k in range(nn):
                if node_index[p, k] != node_index[p - 1, k] or active[p, k] != active[p - 1, k]:
                    same = False
                    break
            if same:
                continue
        for k in range(nn):
            if not active[p, k]:
                continue
            i = node_index[p, k]
            for m in range(k, nn):      # the couplings are symmetric: j's slot of i mirrors i's of j
                if active[p, m]:
                    j = node_index[p, m]
                    s = stencil_slot(i, j, node_ijk, dim, width)
                    mark[i, s] = True
                    mark[j, slots - 1 - s] = True
    if len(cell_start) > 1:
        mark_cells(cell_order, cell_start, node_index, active, node_ijk, dim, width, mark)
    if len(box_centres):
        mark_boxes(box_centres, box_presence, box_half, node_ijk, dim, width, ghost_x, ghost_y, mark)
    for i in owned_nodes:
        mark[i, centre] = True
    indptr = np.zeros(n_nodes + 1, dtype=np.int64)
    for i in range(n_nodes):
        indptr[i + 1] = indptr[i] + np.sum(mark[i])
    indices = np.empty(indptr[n_nodes], dtype=np.int64)
    slot_position = np.full((n_nodes, slots), -1, dtype=np.int64)
    gx = ghost_x
    gy = ghost_y if dim == 3 else 1
    for i in range(n_nodes):
        pos = indptr[i]
        for s in range(slots):          # slots in increasing column order
            if mark[i, s]:
                dx = s % side - width
                dy = (s // side) % side - width
                dz = s // (side * side) - width if dim == 3 else 0
                indices[pos] = i + dx + gx * (dy + gy * dz)
                slot_position[i, s] = pos
                pos += 1
    return indptr, indices, slot_position


@jit
def scalar_csr(indptr, indices, dim):
    """The scalar CSR (indptr over ghosted-local dofs, dof indices) of a
    block CSR whose values are stored row-oriented: block k of node row i,
    entry (a, b), is value dim^2 indptr[i] + a L_i dim + k dim + b with L_i
    the row's number of blocks."""
    n_nodes = len(indptr) - 1
    sp = np.zeros(n_nodes * dim + 1, dtype=np.int64)
    si = np.empty(len(indices) * dim * dim, dtype=np.int64)
    for i in range(n_nodes):
        L = indptr[i + 1] - indptr[i]
        for a in range(dim):
            row = i * dim + a
            start = dim * dim * indptr[i] + a * L * dim
            sp[row + 1] = start + L * dim
            for k in range(L):
                for b in range(dim):
                    si[start + k * dim + b] = indices[indptr[i] + k] * dim + b
    return sp, si
