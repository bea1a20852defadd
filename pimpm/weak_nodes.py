"""Weakly supported nodes, extended out of the basis (implicit steps).

A node that the body's particles barely reach (a GIMP or B-spline particle
domain just across a grid line at a free surface) gets a sliver of mass and
a stiffness that vanishes with the sliver, while the strain of the particle
that touches it still depends on its displacement: the tangent becomes
nearly singular there and Newton crawls (a thin beam bent to large
rotations stalled at a relative residual of 1e-4 with every shape function;
docs/VALIDATION.md, cantilever). This is the small-cut-cell problem of
immersed and cut finite elements; pimpm removes such nodes from the basis
by extension (the aggregation of cut-cell methods, and what the B-spline
basis already does at grid faces): for each particle, a weak node's weight
and gradient go to the nodes one and two steps inward by linear
extrapolation (+2, -1), along the fewest axes that reach nodes that are
free and not weak (a node beyond a face: one axis; beyond an edge or a
corner: the tensor product along two or three, +4 -2 -2 +1), shared
equally when several choices qualify so that no axis comes first (a
problem symmetric in x and y stays so). Linear displacement fields stay
exact, and the weak node, left without weight, is dropped like any
massless node.

The extension applies to quasi-static steps, where nothing but the
particles' stiffness holds a node. In dynamic steps the mass matrix takes
part; there it was tried and made Newton worse on a violent plastic impact
(tests/mpi/jacobian_check.py's set-up steps with Newmark and HHT), so
dynamics keeps the plain basis.

A node is weak when its volume support sum_p S_Ip V_p is a positive
fraction below ``grid.weak_node_fraction`` (or ``-pimpm_weak_node_fraction``;
default 0.05; 0 turns the
extension off) of a cell's volume (in axisymmetry the in-plane area of the
particles is used), and it is free (no grid face or rigid body prescribes
any of its components). Only stencils of three nodes per axis (gimp,
bspline) are extended; the footprint of a step is fixed during its Newton
solve, so the residual and the tangent use the same extended basis (the
finite-difference checks of tests/test_weak_nodes.py).
"""
import numpy as np

from .kernels import transfer as transfer_kernels

def support_fraction(grid, node_index, S, in_plane_volume):
    """Owned dof array: each node's sum_p S_Ip V_p over a cell's volume
    (summed over ranks). Collective."""
    local = np.zeros((grid.n_local_nodes, 1))
    transfer_kernels.scatter(node_index, S, np.ascontiguousarray(in_plane_volume).reshape(-1, 1),
                             grid.n_local_nodes, local)
    return grid.sum_scalar_to_owned(local[:, 0]) / float(np.prod(grid.spacing))


class WeakNodes:
    """Ghosted-local node flags: ``weak`` (free, support below the
    fraction), ``receives`` (may take a weak node's weight: neither weak nor
    prescribed) and the ``support`` fractions."""

    def __init__(self, grid, support, prescribed, fraction):
        """From the owned dof arrays ``support`` and ``prescribed`` (bool).
        Collective."""
        dim = grid.dim
        node_prescribed = prescribed.reshape(-1, dim).any(axis=1)
        node_support = support.reshape(-1, dim)[:, 0]
        owned_weak = (node_support > 0.0) & (node_support < fraction) & ~node_prescribed
        code = np.where(owned_weak, 1.0, np.where(node_prescribed, 2.0, 0.0))
        local = grid.owned_to_local(np.stack([code, node_support] + [node_support] * (dim - 2),
                                             axis=1).reshape(-1))
        self.weak, self.receives = local[:, 0] == 1.0, local[:, 0] == 0.0
        self.support = np.ascontiguousarray(local[:, 1])


def extend(shape, grid, node_index, S, G, nodes):
    """Fold the weak nodes (a :class:`WeakNodes`) out of the footprint (in
    place); returns the number of (particle, node) pairs folded on this rank."""
    if shape.nodes_per_axis != 3 or not nodes.weak.any() or len(S) == 0:
        return 0
    return transfer_kernels.fold_weak_nodes(tuple(range(grid.dim)), shape.nodes_per_axis, node_index,
                                            S, G, nodes.weak, nodes.receives, grid.ghost_start,
                                            grid.ghost_shape)
