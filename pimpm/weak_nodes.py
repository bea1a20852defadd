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

A weak node can also be the nearest node of a particle (the middle of its
stencil along every axis): a lone particle in a fold of the surface
against a tool, the only particle left on the node after the others have
folded theirs away. Its stiffness is then one plastic particle's, soft
enough under compression for Newton to push the node by many cells (the
3D upsetting at 0.5 mm stalled on one at 33% reduction, docs/VALIDATION.md).
Nothing lies two steps inward inside such a stencil; the weight goes to
the parallelograms one step away along two axes (u_I = u_{I-a} + u_{I-b} -
u_{I-a-b}, exact for linear fields) whose three nodes are free, not weak
and supported by particles of their own ("strong"), shared equally. A
weak node in the middle of a flat face has no such parallelogram and
stays.

The extension applies to quasi-static steps, where nothing but the
particles' stiffness holds a node. In dynamic steps the mass matrix takes
part; there it was tried and made Newton worse on a violent plastic impact
(tests/mpi/jacobian_check.py's set-up steps with Newmark and HHT), so
dynamics keeps the plain basis.

A node is weak when its volume support sum_p S_Ip V_p is a positive
fraction below ``grid.weak_node_fraction`` (or ``-pimpm_weak_node_fraction``;
default 0.05; 0 turns the
extension off) of a cell's volume (in axisymmetry the in-plane area of the
particles is used), no rigid body (or other term) prescribes any of its
components, and the grid faces leave at least one free. A node on a
symmetry plane (or another face condition) folds only onto nodes that the
faces prescribe in the same components, i.e. along that plane: their
prescribed values are the face's, so the particles see the condition as
before (the 3D upsetting at 0.5 mm stalled at 46% on a weak node of its
symmetry plane x = 0 that Newton moved by metres). Only stencils of three nodes per axis (gimp,
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
    """Ghosted-local node data: ``weak`` (support below the fraction, not
    held by a tool, not prescribed in every component), ``mask`` (the bits
    of the components a grid face prescribes; -1 where a rigid body or other
    term prescribes any), ``receives`` (may take some weak node's weight:
    not weak, not held), ``support`` (the fractions) and ``strong``
    (receives and has support of its own). A weak node's weight goes only to
    nodes with its own mask: a free node's to free nodes, a node on a
    symmetry plane's to nodes on that plane, whose prescribed component
    (the same value along a face) the particles then see as before."""

    def __init__(self, grid, support, prescribed, fraction, held=None):
        """From the owned dof arrays ``support``, ``prescribed`` (bool: by
        the grid faces) and ``held`` (bool: by rigid bodies and other terms;
        None: none). Collective."""
        dim = grid.dim
        mask = (prescribed.reshape(-1, dim) * (1 << np.arange(dim))).sum(axis=1)
        if held is not None:
            mask = np.where(held.reshape(-1, dim).any(axis=1), -1, mask)
        node_support = support.reshape(-1, dim)[:, 0]
        owned_weak = ((node_support > 0.0) & (node_support < fraction) & (mask >= 0)
                      & (mask != (1 << dim) - 1))
        code = mask + 16 * owned_weak                          # mask in [-1, 7]
        local = grid.owned_to_local(np.stack([code.astype(float), node_support]
                                             + [node_support] * (dim - 2), axis=1).reshape(-1))
        code = np.rint(local[:, 0]).astype(np.int64)
        self.weak = code >= 15
        self.mask = np.where(self.weak, code - 16, code)
        self.receives = ~self.weak & (self.mask >= 0)
        self.support = np.ascontiguousarray(local[:, 1])
        self.strong = self.receives & (self.support > 0.0)


def extend(shape, grid, node_index, S, G, nodes):
    """Fold the weak nodes (a :class:`WeakNodes`) out of the footprint (in
    place); returns the number of (particle, node) pairs folded on this rank."""
    if shape.nodes_per_axis != 3 or not nodes.weak.any() or len(S) == 0:
        return 0
    return transfer_kernels.fold_weak_nodes(tuple(range(grid.dim)), shape.nodes_per_axis, node_index,
                                            S, G, nodes.weak, nodes.mask, nodes.strong, grid.ghost_start,
                                            grid.ghost_shape)
