"""Closed-form determinant and inverse of many small (2x2 or 3x3) matrices.

numpy's batched ``linalg.inv``/``det`` call LAPACK once per matrix; these
vectorized formulas are ~20x faster for (n, 2, 2) and (n, 3, 3) stacks.
"""
import numpy as np


def det(A):
    """Determinants of a stack (n, k, k), k = 1, 2 or 3."""
    k = A.shape[-1]
    if k == 2:
        return A[:, 0, 0] * A[:, 1, 1] - A[:, 0, 1] * A[:, 1, 0]
    if k == 3:
        return (A[:, 0, 0] * (A[:, 1, 1] * A[:, 2, 2] - A[:, 1, 2] * A[:, 2, 1])
                - A[:, 0, 1] * (A[:, 1, 0] * A[:, 2, 2] - A[:, 1, 2] * A[:, 2, 0])
                + A[:, 0, 2] * (A[:, 1, 0] * A[:, 2, 1] - A[:, 1, 1] * A[:, 2, 0]))
    if k == 1:
        return A[:, 0, 0].copy()
    return np.linalg.det(A)


def inv(A):
    """Inverses of a stack (n, k, k), k = 1, 2 or 3 (adjugate / determinant)."""
    k = A.shape[-1]
    d = det(A)
    with np.errstate(divide="ignore", invalid="ignore"):
        if k == 1:
            return 1.0 / A
        if k == 2:
            out = np.empty_like(A)
            out[:, 0, 0] = A[:, 1, 1]
            out[:, 1, 1] = A[:, 0, 0]
            out[:, 0, 1] = -A[:, 0, 1]
            out[:, 1, 0] = -A[:, 1, 0]
            return out / d[:, None, None]
        if k == 3:
            out = np.empty_like(A)
            out[:, 0, 0] = A[:, 1, 1] * A[:, 2, 2] - A[:, 1, 2] * A[:, 2, 1]
            out[:, 0, 1] = A[:, 0, 2] * A[:, 2, 1] - A[:, 0, 1] * A[:, 2, 2]
            out[:, 0, 2] = A[:, 0, 1] * A[:, 1, 2] - A[:, 0, 2] * A[:, 1, 1]
            out[:, 1, 0] = A[:, 1, 2] * A[:, 2, 0] - A[:, 1, 0] * A[:, 2, 2]
            out[:, 1, 1] = A[:, 0, 0] * A[:, 2, 2] - A[:, 0, 2] * A[:, 2, 0]
            out[:, 1, 2] = A[:, 0, 2] * A[:, 1, 0] - A[:, 0, 0] * A[:, 1, 2]
            out[:, 2, 0] = A[:, 1, 0] * A[:, 2, 1] - A[:, 1, 1] * A[:, 2, 0]
            out[:, 2, 1] = A[:, 0, 1] * A[:, 2, 0] - A[:, 0, 0] * A[:, 2, 1]
            out[:, 2, 2] = A[:, 0, 0] * A[:, 1, 1] - A[:, 0, 1] * A[:, 1, 0]
            return out / d[:, None, None]
    return np.linalg.inv(A)
