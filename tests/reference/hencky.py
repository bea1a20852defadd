"""Hencky's model in numpy, by eigen-decomposition of b = F F^T (numpy's
eigh): tau = lam tr(eps) 1 + 2 mu eps, eps = ln V; the tangent as in
pimpm.materials.hencky (the coefficient of the off-diagonal modes in its
first, quotient form, with the equal-stretch limit mu - tau_B)."""
import numpy as np

from .base import Material


class Hencky(Material):
    name = "hencky"

    def _principal(self, F):
        """Logarithmic principal stretches (NaN where det F <= 0), directions
        and squared stretches."""
        values, vectors = np.linalg.eigh(np.matmul(F, np.swapaxes(F, 1, 2)))
        good = np.linalg.det(F) > 0.0
        with np.errstate(divide="ignore", invalid="ignore"):
            x = np.where(good[:, None], 0.5 * np.log(np.where(good[:, None], values, 1.0)), np.nan)
        return x, vectors, values

    def _kernel(self, F, tangent):
        F = np.asarray(F, float)
        if F.ndim < 2 or F.shape[-2:] != (3, 3):
            raise ValueError(f"deformation gradient must have shape (..., 3, 3), got {F.shape}")
        if F.ndim != 3:
            sigma, c = self._kernel(F.reshape(-1, 3, 3), tangent)
            return (sigma.reshape(F.shape),
                    None if c is None else c.reshape(F.shape[:-2] + (3, 3, 3, 3)))
        J = np.linalg.det(F)
        x, n, stretch2 = self._principal(F)
        lam, mu = self.lame_lambda, self.shear_modulus
        tau_a = lam * x.sum(axis=1)[:, None] + 2.0 * mu * x                  # (p, A)
        sigma = np.einsum("pa,pia,pja->pij", tau_a, n, n) / J[:, None, None]
        if not tangent:
            return sigma, None
        m = np.einsum("pia,pja->paij", n, n)                                 # n_A (x) n_A
        D = lam + 2.0 * mu * np.eye(3)
        coefficient = D[None] - 2.0 * tau_a[:, :, None] * np.eye(3)[None]    # (p, A, B)
        Jc = np.einsum("pab,paij,pbkl->pijkl", coefficient, m, m)
        for a in range(3):
            for b in range(3):
                if a == b:
                    continue
                la, lb = stretch2[:, a], stretch2[:, b]
                close = np.abs(la - lb) <= 1e-8 * (la + lb)
                with np.errstate(invalid="ignore"):
                    quotient = (tau_a[:, a] * lb - tau_a[:, b] * la) / np.where(close, 1.0, la - lb)
                k = np.where(close, mu - tau_a[:, b], quotient)
                mab = np.einsum("pi,pj->pij", n[:, :, a], n[:, :, b])
                Jc += k[:, None, None, None, None] * (np.einsum("pij,pkl->pijkl", mab, mab)
                                                      + np.einsum("pij,plk->pijkl", mab, mab))
        return sigma, Jc / J[:, None, None, None, None]

    def _energy(self, F):
        x, _, _ = self._principal(np.asarray(F, float))
        return 0.5 * self.lame_lambda * x.sum(axis=1) ** 2 + self.shear_modulus * np.sum(x * x, axis=1)
