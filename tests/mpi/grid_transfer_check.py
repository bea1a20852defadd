"""Grid.transfer_owned: owned nodal values moved onto the same grid
partitioned differently (what a rebalance does) arrive at their nodes, for
1, dim and 5 values a node, in 2D and 3D (run under mpiexec with any number
of ranks). Prints "transfer_ok=True" when every check holds; exits 1
otherwise."""
import sys

import petsc4py
petsc4py.init(sys.argv[:1])
import numpy as np
from mpi4py import MPI

from pimpm.grid import Grid

comm = MPI.COMM_WORLD


def shifted(ranges):
    """Other ownership ranges: one node moves from each axis' first part to
    its second, where there are two parts (and the first keeps 2 nodes)."""
    out = [list(r) for r in ranges]
    for r in out:
        if len(r) > 1 and r[0] > 2:
            r[0] -= 1
            r[1] += 1
    return out


def natural_values(grid, k):
    """k values a node, a function of the node's natural index."""
    index = grid.natural_node_index().astype(float)
    return np.stack([np.sin(0.37 * index + j) + j for j in range(k)], axis=1).reshape(-1)


ok = True
for cells in ([11, 7], [6, 5, 4]):
    dim = len(cells)
    first = Grid(comm, [0.0] * dim, [1.0] * dim, cells)
    ranges = shifted(first.da.getOwnershipRanges())
    second = Grid(comm, [0.0] * dim, [1.0] * dim, cells, ownership_ranges=ranges,
                  proc_sizes=first.da.getProcSizes())
    for k in (1, dim, 5):
        moved = first.transfer_owned(natural_values(first, k), second)
        error = float(np.max(np.abs(moved - natural_values(second, k)), initial=0.0))
        good = comm.allreduce(len(moved) == second.n_owned_nodes * k and error == 0.0, op=MPI.LAND)
        back = second.transfer_owned(moved, first)
        good = good and comm.allreduce(bool(np.array_equal(back, natural_values(first, k))), op=MPI.LAND)
        if comm.rank == 0:
            print(f"cells={cells} k={k} moved={ranges != [list(r) for r in first.da.getOwnershipRanges()]} "
                  f"ok={good}")
        ok = ok and good
    first.destroy()
    second.destroy()
if comm.rank == 0:
    print(f"transfer_ok={ok}")
sys.exit(0 if ok else 1)
