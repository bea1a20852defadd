#!/usr/bin/env python3
"""Is the billet's J drift (docs/VALIDATION.md) made by the kinematics of a
step alone? A 20 x 20 block of 4 x 4 particles per cell on a grid of unit
cells is moved in N steps by a prescribed smooth displacement (compression
in y, a bulge in x: 30% in total), interpolated from its nodal values with
each shape function, the grid reset every step: x += sum N u, F = (1 + sum
u (x) grad N) F. Prints the lattice J drift (pimpm.measures.lattice_j_drift's
definition) after 5, 10, 20, 40 steps, without and with a random nodal part
of 1e-3 h per step. No PETSc, 1 process.

    python scripts/kinematic_j_drift.py
"""
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from pimpm.shape import make_shape      # noqa: E402


def drift(shape_name, steps, total=0.3, rough=0.0, ppc=4):
    shape = make_shape(shape_name, 2)
    h, cells = 1.0, np.array([60, 60])
    d = h / ppc
    g = (np.arange(20 * ppc) + 0.5) * d + 10.0                  # the block [10, 30]^2
    x = np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1).reshape(-1, 2)
    F = np.broadcast_to(np.eye(2), (len(x), 2, 2)).copy()
    half = np.full_like(x, d / 2)
    grid_nodes = np.stack(np.meshgrid(np.arange(61.0), np.arange(61.0), indexing="ij"), -1)
    rng = np.random.default_rng(0)
    for _ in range(steps):
        s = total / steps
        X, Y = grid_nodes[..., 0] - 10, grid_nodes[..., 1] - 10
        u_nodes = s * np.stack([0.5 * X * (1 + 0.02 * Y * (20 - Y) / 5), -Y * (1 + 0.01 * X)], -1)
        u_nodes = u_nodes + rough * rng.standard_normal(u_nodes.shape)
        sizes = np.minimum(half * np.abs(np.diagonal(F, axis1=1, axis2=2)), 0.5 * h)
        nodes, S, G = shape.evaluate(x, np.zeros(2), np.array([h, h]), cells, sizes)
        un = u_nodes[nodes[..., 0], nodes[..., 1]]
        F = np.matmul(np.eye(2) + np.einsum("pia,pib->pab", un, G), F)
        x = x + np.einsum("pi,pia->pa", S, un)
    n = 20 * ppc
    xs, J = x.reshape(n, n, 2), np.linalg.det(F).reshape(n, n)
    dX = (xs[2:, 1:-1] - xs[:-2, 1:-1]) / (2 * d)
    dY = (xs[1:-1, 2:] - xs[1:-1, :-2]) / (2 * d)
    return np.mean(J[1:-1, 1:-1]) / np.mean(dX[..., 0] * dY[..., 1] - dX[..., 1] * dY[..., 0]) - 1


def main():
    print("| shape functions | nodal field | 5 steps | 10 steps | 20 steps | 40 steps |")
    print("|---|---|---|---|---|---|")
    for shape in ("linear", "gimp", "bspline"):
        for rough, label in ((0.0, "smooth"), (1e-3, "smooth + random 1e-3 h per step")):
            print(f"| {shape} | {label} | " + " | ".join(f"{100 * drift(shape, n, rough=rough):+.4f}%"
                                                      for n in (5, 10, 20, 40)) + " |")


if __name__ == "__main__":
    main()
