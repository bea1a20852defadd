"""F-bar (de Souza Neto et al. 1996; Coombs et al. 2018 for MPM): over what
the particles of materials with ``f_bar`` average their volume change.

* ``cells`` (:class:`AveragedCells`): the particles of one grid cell at the
  start of the step share the volume-weighted mean of their J_inc; pimpm
  distributes particles by that cell, so every group lives on one rank.
* ``nodes`` (:class:`AveragedNodes`): J_inc is averaged onto the nodes with
  the particles' weights and back to each particle, a smooth average that
  neighbouring particles share in part (no jump when a particle changes
  cell, no cell-by-cell checkerboard); its sums run over every rank.

The kernels are in :mod:`pimpm.kernels.fbar` and
:func:`pimpm.kernels.particle_step.evaluate_particles`."""
from dataclasses import dataclass

import numpy as np

from .kernels import fbar as kernels
from .kernels import particle_step


@dataclass
class AveragedCells:
    cell: np.ndarray      # (n,) each particle's averaged cell on this rank, -1 if not averaged
    count: int            # number of averaged cells on this rank
    order: np.ndarray     # the averaged particles sorted by cell
    start: np.ndarray     # first particle of each cell in that order (count + 1)
    kind = "cells"


#: no particle is averaged (the kernels take empty arrays)
NONE = AveragedCells(np.zeros(0, dtype=np.int64), 0, np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64))


def averaged_cells(grid, x, table):
    """The F-bar groups of the particles at positions ``x`` whose materials
    (``table``: pimpm.materials.table.MaterialTable) average their volume."""
    on = table.f_bar[table.material_of] if len(table.f_bar) else np.zeros(len(x), dtype=bool)
    if not np.any(on):
        return NONE
    cells = grid.cell_of(x[on])
    flat = np.ravel_multi_index(tuple(cells.T), tuple(int(c) for c in grid.cells))
    unique, inverse = np.unique(flat, return_inverse=True)
    cell = np.full(len(x), -1, dtype=np.int64)
    cell[on] = inverse
    order, start = kernels.cell_groups(cell, len(unique))
    return AveragedCells(cell, len(unique), order, start)


def cell_box_side(state):
    """Nodes per axis of an F-bar cell's union footprint box: a particle's
    nodes per axis plus one (pimpm.kernels.fbar)."""
    nn = state.S.shape[1]
    dim = state.G.shape[2]
    return int(round(nn ** (1.0 / dim))) + 1


def check_cell_boxes(outside):
    """The F-bar kernels found footprint nodes outside their cell's box (a bug)."""
    if outside:
        raise RuntimeError(f"F-bar: {outside} footprint nodes lie outside their cell's union box")


# --------------------------------------------------------------------- on the nodes
class AveragedNodes:
    """F-bar's J averaged on the nodes for one step (``f_bar: nodes``):
    J_I = sum_q S+_Iq V_q J_q / W_I over every rank's averaged particles
    (S+ = max(S, 0), V the volume at the step's start, W_I = sum_q S+_Iq
    V_q), and J_bar_p = sum_I S+_Ip J_I / sum_I S+_Ip. Made collectively
    at the start of the step (W and the pattern's boxes do not change
    within it); :meth:`jbar` and :meth:`coupling` are collective too.

    ``cell``: the kernels' marker, 0 for an averaged particle and -1 for
    the others (empty when this rank has none); ``count``: how many this
    rank has; ``half``: a particle's nodes per axis - 1, the half-width of
    the box about a node in which R_I and D_I live
    (:mod:`pimpm.kernels.fbar`)."""

    kind = "nodes"

    def __init__(self, grid, table, node_index, active, S, volume_n):
        n = len(node_index)
        on = table.f_bar[table.material_of] if len(table.f_bar) else np.zeros(n, dtype=bool)
        self.count = int(np.count_nonzero(on))
        marker = np.where(on, 0, -1).astype(np.int64)
        self.cell = marker if self.count else np.zeros(0, dtype=np.int64)
        dim = grid.dim
        self.half = int(round(node_index.shape[1] ** (1.0 / dim))) - 1
        self.slots = (2 * self.half + 1) ** dim
        self.grid = grid
        weights = np.zeros(grid.n_local_nodes)
        kernels.node_sums(node_index, active, S, volume_n, _NO_F, marker, True, weights)
        self.weight_sum = self._summed(weights[:, None])[:, 0]
        self._marker = marker
        self._footprint = (node_index, active, S)
        self._boxes = None

    def _box_presence(self):
        """(presence, centres): how many particles put a share in each slot
        of each owned node's box (n_local_nodes, slots; zero on the other
        nodes), and the owned nodes whose box holds any. Made at the first
        call, which every rank makes (the implicit step's pattern);
        collective."""
        if self._boxes is None:
            grid = self.grid
            node_index, active, S = self._footprint
            presence = np.zeros((grid.n_local_nodes, self.slots))
            check_node_boxes(kernels.node_presence(node_index, active, S, self._marker, grid.ghost_ijk, grid.dim,
                                                   self.half, presence))
            owned = grid.sum_columns_to_owned(presence)
            presence[:] = 0.0
            presence[grid.owned_local_nodes] = owned
            self._boxes = (presence, grid.owned_local_nodes[np.any(owned > 0.0, axis=1)].astype(np.int64))
        return self._boxes

    @property
    def presence(self):
        return self._box_presence()[0]

    @property
    def centres(self):
        return self._box_presence()[1]

    def _summed(self, local):
        """Every rank's ghosted-local shares summed, on the ghosted-local nodes."""
        grid = self.grid
        return grid.owned_columns_to_local(grid.sum_columns_to_owned(local))

    def jbar(self, node_index, active, S, volume_n, F_inc):
        """J_bar of every particle (n,) for the increments ``F_inc`` (empty if
        this rank has no averaged particle). Collective."""
        sums = np.zeros(self.grid.n_local_nodes)
        kernels.node_sums(node_index, active, S, volume_n, F_inc, self._marker, False, sums)
        sums = self._summed(sums[:, None])[:, 0]
        J_node = np.where(self.weight_sum > 0.0, sums / np.where(self.weight_sum > 0.0, self.weight_sum, 1.0), 1.0)
        if not self.count:
            return np.zeros(0)
        jbar = np.empty(len(node_index))
        kernels.node_average(node_index, active, S, self._marker, J_node, jbar)
        return jbar

    def increments_and_jbar(self, kinematics, u_local, node_index, active, S, G, radius, volume_n, F_inc):
        """The particles' increments at ``u_local`` (into ``F_inc``, which the
        particle kernel then reuses) and their J_bar (:meth:`jbar`): the
        average needs every increment before any particle's stress.
        Collective."""
        dim = self.grid.dim
        particle_step.increments(kinematics, tuple(range(dim)), tuple(range(S.shape[1])), u_local, node_index,
                                 active, S, G, radius, F_inc)
        return self.jbar(node_index, active, S, volume_n, F_inc)

    def coupling(self, kinematics, node_index, active, S, G, radius, F_inc, fbar_q, volume_n, jbar):
        """(R, D): (n_local_nodes, slots, dim), every rank's shares of R_I and
        D_I summed on the owned nodes, zero on the others. Collective."""
        grid = self.grid
        shape = (grid.n_local_nodes, self.slots, grid.dim)
        R, D = np.zeros(shape), np.zeros(shape)
        if self.count:
            check_node_boxes(kernels.node_vectors(
                kinematics, grid.dim, node_index, active, S, G, radius, F_inc, fbar_q, self._marker, volume_n,
                jbar, self.weight_sum, grid.ghost_ijk, self.half, R, D))
        both = grid.sum_columns_to_owned(np.hstack([R.reshape(len(R), -1), D.reshape(len(D), -1)]))
        k = self.slots * grid.dim
        R[:], D[:] = 0.0, 0.0
        R.reshape(len(R), -1)[grid.owned_local_nodes] = both[:, :k]
        D.reshape(len(D), -1)[grid.owned_local_nodes] = both[:, k:]
        return R, D

    def ghost_shape(self):
        """The ghosted box's nodes along x and y (the kernels' node numbering)."""
        return int(self.grid.ghost_shape[0]), int(self.grid.ghost_shape[1])


_NO_F = np.zeros((0, 3, 3))


def averaging(kind, grid, x, table, node_index, active, S, volume_n):
    """F-bar's averaging for one step: ``kind`` "cells" or "nodes" (None:
    no F-bar, :data:`NONE`). Collective for "nodes"."""
    if kind is None:
        return NONE
    if kind == "nodes":
        return AveragedNodes(grid, table, node_index, active, S, volume_n)
    return averaged_cells(grid, x, table)


def check_node_boxes(outside):
    """The nodal F-bar kernels found a node outside its box or a coupling outside the pattern (a bug)."""
    if outside:
        raise RuntimeError(f"F-bar on the nodes: {outside} nodes or couplings lie outside their box or pattern")
