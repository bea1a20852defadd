"""F-bar's cells (de Souza Neto et al. 1996; Coombs et al. 2018 for MPM):
which particles average their volume change together. The particles of
materials with ``f_bar: true`` are grouped by the grid cell that holds
them at the start of the step; pimpm distributes particles by that cell,
so every group lives on one rank. The kernels are in
:mod:`pimpm.kernels.fbar` and :func:`pimpm.kernels.particle_step.evaluate_particles`."""
from dataclasses import dataclass

import numpy as np

from .kernels import fbar as kernels


@dataclass
class AveragedCells:
    cell: np.ndarray      # (n,) each particle's averaged cell on this rank, -1 if not averaged
    count: int            # number of averaged cells on this rank
    order: np.ndarray     # the averaged particles sorted by cell
    start: np.ndarray     # first particle of each cell in that order (count + 1)


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
