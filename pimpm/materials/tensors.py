"""Small-tensor helpers shared by the material models, the kinematics and the
assembly: closed-form determinant and inverse of many 2x2 or 3x3 matrices,
the constant fourth-order tensors, and the von Mises stress.

numpy's batched ``linalg.inv``/``det`` call LAPACK once per matrix; the
closed forms here are ~20x faster for (n, 2, 2) and (n, 3, 3) stacks.
"""
import numpy as np

I3 = np.eye(3)
II = np.einsum("ij,kl->ijkl", I3, I3)                       # I (x) I
#: symmetric fourth-order identity 1/2 (d_ik d_jl + d_il d_jk)
IS = 0.5 * (np.einsum("ik,jl->ijkl", I3, I3) + np.einsum("il,jk->ijkl", I3, I3))
IDEV = IS - II / 3.0


def det(A):
    """Determinants of a stack (..., k, k), k = 1, 2 or 3."""
    k = A.shape[-1]
    if k == 2:
        return A[..., 0, 0] * A[..., 1, 1] - A[..., 0, 1] * A[..., 1, 0]
    if k == 3:
        return (A[..., 0, 0] * (A[..., 1, 1] * A[..., 2, 2] - A[..., 1, 2] * A[..., 2, 1])
                - A[..., 0, 1] * (A[..., 1, 0] * A[..., 2, 2] - A[..., 1, 2] * A[..., 2, 0])
                + A[..., 0, 2] * (A[..., 1, 0] * A[..., 2, 1] - A[..., 1, 1] * A[..., 2, 0]))
    if k == 1:
        return A[..., 0, 0].copy()
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


def as_F(F):
    """F as a float array of shape (..., 3, 3), or ValueError."""
    F = np.asarray(F, dtype=float)
    if F.ndim < 2 or F.shape[-2:] != (3, 3):
        raise ValueError(f"deformation gradient must have shape (..., 3, 3), got {F.shape}")
    return F


def trace(A):
    return A[..., 0, 0] + A[..., 1, 1] + A[..., 2, 2]


def outer(A, B):
    """A (x) B of second-order tensors (..., 3, 3) -> (..., 3, 3, 3, 3)."""
    return A[..., :, :, None, None] * B[..., None, None, :, :]


def von_mises(sigma):
    """Von Mises equivalent stress sqrt(3/2 s:s), s = dev(sigma); shape (...)."""
    sigma = np.asarray(sigma, dtype=float)
    s = sigma - trace(sigma)[..., None, None] / 3.0 * I3
    return np.sqrt(1.5 * np.sum(s * s, axis=(-2, -1)))
