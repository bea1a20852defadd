"""3x3 tensor helpers for the compiled kernels: closed forms written out on
scalars so that nothing is allocated per particle. Arguments are (3, 3)
arrays (views into per-particle storage or workspace)."""
import math

import numpy as np

from .jit import jit


@jit
def det3(A):
    return (A[0, 0] * (A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1])
            - A[0, 1] * (A[1, 0] * A[2, 2] - A[1, 2] * A[2, 0])
            + A[0, 2] * (A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]))


@jit
def inv3(A, out):
    """out = A^-1 (adjugate over determinant); returns det A."""
    d = det3(A)
    out[0, 0] = (A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1]) / d
    out[0, 1] = (A[0, 2] * A[2, 1] - A[0, 1] * A[2, 2]) / d
    out[0, 2] = (A[0, 1] * A[1, 2] - A[0, 2] * A[1, 1]) / d
    out[1, 0] = (A[1, 2] * A[2, 0] - A[1, 0] * A[2, 2]) / d
    out[1, 1] = (A[0, 0] * A[2, 2] - A[0, 2] * A[2, 0]) / d
    out[1, 2] = (A[0, 2] * A[1, 0] - A[0, 0] * A[1, 2]) / d
    out[2, 0] = (A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]) / d
    out[2, 1] = (A[0, 1] * A[2, 0] - A[0, 0] * A[2, 1]) / d
    out[2, 2] = (A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]) / d
    return d


@jit
def inv2(A, out):
    """out[:2, :2] = (A[:2, :2])^-1; returns its determinant."""
    d = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
    out[0, 0] = A[1, 1] / d
    out[1, 1] = A[0, 0] / d
    out[0, 1] = -A[0, 1] / d
    out[1, 0] = -A[1, 0] / d
    return d


@jit
def copy3(stack, p, out):
    """out = stack[p] for a (n, 3, 3) stack, without making a view (a view per
    particle costs numba a reference-count pair)."""
    for a in range(3):
        for b in range(3):
            out[a, b] = stack[p, a, b]


@jit
def matmul3(A, B, out):
    """out = A B (out must not alias A or B)."""
    for i in range(3):
        for j in range(3):
            s = 0.0
            for k in range(3):
                s += A[i, k] * B[k, j]
            out[i, j] = s


@jit
def matmul3_bt(A, B, out):
    """out = A B^T: the products of A's rows with B's rows."""
    for i in range(3):
        for j in range(3):
            out[i, j] = A[i, 0] * B[j, 0] + A[i, 1] * B[j, 1] + A[i, 2] * B[j, 2]


@jit
def trace3(A):
    return A[0, 0] + A[1, 1] + A[2, 2]


@jit
def delta(i, j):
    return 1.0 if i == j else 0.0


@jit
def symmetric_eigen3(A, values, vectors):
    """Eigenvalues ``values`` (3,) and orthonormal eigenvectors (the columns of
    ``vectors``, (3, 3)) of the symmetric 3x3 matrix A, by cyclic Jacobi
    rotations (robust for repeated eigenvalues; converged to round-off in a
    few sweeps). A is not changed."""
    a00, a01, a02, a11, a12, a22 = A[0, 0], 0.5 * (A[0, 1] + A[1, 0]), 0.5 * (A[0, 2] + A[2, 0]), \
        A[1, 1], 0.5 * (A[1, 2] + A[2, 1]), A[2, 2]
    m = np.empty((3, 3))
    m[0, 0], m[0, 1], m[0, 2] = a00, a01, a02
    m[1, 0], m[1, 1], m[1, 2] = a01, a11, a12
    m[2, 0], m[2, 1], m[2, 2] = a02, a12, a22
    for i in range(3):
        for j in range(3):
            vectors[i, j] = 1.0 if i == j else 0.0
    scale = abs(a00) + abs(a11) + abs(a22) + abs(a01) + abs(a02) + abs(a12)
    for _ in range(50):
        off = abs(m[0, 1]) + abs(m[0, 2]) + abs(m[1, 2])
        if off <= 1e-300 or off <= 1e-17 * scale:
            break
        for p in range(2):
            for q in range(p + 1, 3):
                apq = m[p, q]
                if apq == 0.0:
                    continue
                theta = 0.5 * (m[q, q] - m[p, p]) / apq
                t = (1.0 if theta >= 0.0 else -1.0) / (abs(theta) + math.sqrt(theta * theta + 1.0))
                c = 1.0 / math.sqrt(t * t + 1.0)
                s = t * c
                for k in range(3):           # m <- m J (columns p, q)
                    mkp, mkq = m[k, p], m[k, q]
                    m[k, p] = c * mkp - s * mkq
                    m[k, q] = s * mkp + c * mkq
                for k in range(3):           # m <- J^T m (rows p, q)
                    mpk, mqk = m[p, k], m[q, k]
                    m[p, k] = c * mpk - s * mqk
                    m[q, k] = s * mpk + c * mqk
                m[p, q] = 0.0
                m[q, p] = 0.0
                for k in range(3):           # vectors <- vectors J
                    vkp, vkq = vectors[k, p], vectors[k, q]
                    vectors[k, p] = c * vkp - s * vkq
                    vectors[k, q] = s * vkp + c * vkq
    for i in range(3):
        values[i] = m[i, i]
