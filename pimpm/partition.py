"""Which rank owns which part of the grid: DMDA ownership ranges chosen from
where the particles are (issue "every rank busy"), the imbalance that
decides when to repartition, and the repartitioned grid. Pure functions,
plus collective helpers (the Simulation swaps its state onto a new grid:
:meth:`pimpm.simulation.Simulation.balance_ranks`).
"""
import numpy as np
from mpi4py import MPI

from .grid import Grid


def balanced_ownership(cell_weights, proc_sizes, min_nodes=1):
    """DMDA ownership ranges (nodes per rank along each axis) that split the
    work evenly: ``cell_weights[d]`` is the work in each cell layer along
    axis d (e.g. its particle count), and a cell belongs to the rank owning
    its lower node (pimpm.grid's ownership rule). Each rank keeps at least ``min_nodes``
    nodes per axis (the stencil width). Pure function: the same on every rank."""
    ranges = []
    for weights, parts in zip(cell_weights, proc_sizes):
        weights = np.asarray(weights, dtype=float)
        n_nodes = len(weights) + 1
        # a tiny weight per cell spreads cells without particles evenly too
        weights = weights + 1e-9 * max(float(weights.sum()), 1.0) / len(weights)
        before = np.concatenate([[0.0], np.cumsum(weights)])    # work of cells < k, k = node
        cuts = [0]
        for i in range(1, int(parts)):
            target = i * before[-1] / parts
            k = int(np.searchsorted(before, target))
            if k > 0 and abs(before[k - 1] - target) <= abs(before[min(k, n_nodes - 1)] - target):
                k -= 1
            k = min(max(k, cuts[-1] + min_nodes), n_nodes - (int(parts) - i) * min_nodes)
            cuts.append(k)
        cuts.append(n_nodes)
        ranges.append(np.diff(cuts).astype(np.int64))
    return ranges


def cell_layer_weights(grid, particle_sets, comm):
    """Particles per cell layer along each axis (the work of a layer), summed
    over ranks: ``weights[d][k]`` for the cells with index k along axis d.
    Collective."""
    weights = []
    for d in range(grid.dim):
        local = np.zeros(int(grid.cells[d]))
        for pset in particle_sets:
            if len(pset):
                local += np.bincount(grid.cell_of(pset["x"])[:, d], minlength=int(grid.cells[d]))
        weights.append(comm.allreduce(local, op=MPI.SUM))
    return weights


def particle_imbalance(local_count, comm):
    """Largest local particle count over the mean (1 = balanced). Collective."""
    counts = comm.allgather(int(local_count))
    mean = sum(counts) / len(counts)
    return max(counts) / mean if mean > 0 else 1.0


def balanced_grid(grid, particle_sets, comm):
    """A grid like ``grid`` whose ownership ranges give every rank about the
    same number of particles of ``particle_sets`` (the particle work of a
    step dominates), or None if the balanced ranges are the ones it has.
    Collective."""
    weights = cell_layer_weights(grid, particle_sets, comm)
    ranges = balanced_ownership(weights, grid.proc_sizes, min_nodes=max(1, grid.stencil_width))
    current = [np.asarray(r) for r in grid.da.getOwnershipRanges()]
    if all(np.array_equal(a, b) for a, b in zip(ranges, current)):
        return None
    return Grid(comm, grid.lower, grid.upper, grid.cells, stencil_width=grid.stencil_width,
                ownership_ranges=ranges, proc_sizes=grid.proc_sizes)
