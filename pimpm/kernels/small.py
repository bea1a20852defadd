"""3x3 tensor helpers for the compiled kernels: closed forms written out on
scalars so that nothing is allocated per particle. Arguments are (3, 3)
arrays (views into per-particle storage or workspace)."""
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
    """out = A B^T."""
    for i in range(3):
        for j in range(3):
            s = 0.0
            for k in range(3):
                s += A[i, k] * B[j, k]
            out[i, j] = s


@jit
def trace3(A):
    return A[0, 0] + A[1, 1] + A[2, 2]


@jit
def delta(i, j):
    return 1.0 if i == j else 0.0
