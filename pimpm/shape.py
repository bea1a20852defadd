"""Grid shape functions evaluated at particles.

A shape-function object maps particle positions to the grid nodes they touch,
the weights ``S_ip`` and the gradients ``G_ip`` (MPM intro eq. 2-6). Every
object exposes the same interface so that GIMP or B-splines can be added
later with a wider ``stencil_width``.
"""
import itertools

import numpy as np


class LinearShape:
    """Bilinear / trilinear tent functions (MPM intro Fig. 2-3): each particle
    touches the ``2**dim`` nodes of the cell that contains it."""

    name = "linear"
    stencil_width = 1

    def __init__(self, dim):
        self.dim = dim
        # node offsets within a cell, x fastest: (nodes_per_particle, dim)
        self.offsets = np.array([o[::-1] for o in itertools.product((0, 1), repeat=dim)],
                                dtype=np.int64)
        self.nodes_per_particle = len(self.offsets)

    def evaluate(self, x, lower, spacing, cells):
        """Return ``(nodes, S, G)`` for positions ``x`` (n, dim):

        nodes (n, nn, dim) global node multi-indices,
        S (n, nn) weights (partition of unity),
        G (n, nn, dim) gradients in physical units.
        """
        xi = (x - lower) / spacing
        base = np.clip(np.floor(xi).astype(np.int64), 0, cells - 1)
        frac = xi - base                                    # (n, dim) in [0, 1]
        o = self.offsets[None, :, :]                        # (1, nn, dim)
        f = frac[:, None, :]                                # (n, 1, dim)
        w = np.where(o == 1, f, 1.0 - f)                    # 1D weights (n, nn, dim)
        dw = np.where(o == 1, 1.0, -1.0) / spacing          # 1D slopes (1, nn, dim)
        S = np.prod(w, axis=2)
        G = np.empty(w.shape)
        for d in range(self.dim):  # loop over dimensions only
            others = np.prod(np.delete(w, d, axis=2), axis=2)
            G[:, :, d] = dw[:, :, d] * others
        nodes = base[:, None, :] + o
        return nodes, S, G


def make_shape(name, dim):
    if name == "linear":
        return LinearShape(dim)
    raise ValueError(f"unknown shape functions {name!r}")
