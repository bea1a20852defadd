"""Guilkey & Weiss (2003) eq. 13 as a SNES convergence test.

Newton has converged when both

    ||du^k|| / ||du^max|| < eps_d      and      |du^k . Q^k| / |du^1 . Q^1| < eps_e

where du^k is the k-th displacement increment, du^max the largest increment
of this step, and Q^k the residual the increment was solved from (an energy
norm). SNES has no "user converged" reason in petsc4py 3.18, so a converged
step is reported as CONVERGED_SNORM_RELATIVE (the closest in spirit) and
:attr:`GuilkeyWeissTest.converged` records that eq. 13 decided.
"""
import numpy as np
from petsc4py import PETSc

Reason = PETSc.SNES.ConvergedReason


class GuilkeyWeissTest:
    def __init__(self, displacement_tolerance, energy_tolerance):
        self.eps_d = float(displacement_tolerance)
        self.eps_e = float(energy_tolerance)
        self.reset()

    def reset(self):
        self.x_prev = None
        self.f_prev = None
        self.du_max = 0.0
        self.energy_first = None
        self.converged = False
        self.ratios = []            # (displacement ratio, energy ratio) per iteration

    def __call__(self, snes, it, norms):
        _, _, fnorm = norms
        X = snes.getSolution()
        F = snes.getFunction()[0]
        if not np.isfinite(fnorm):
            return Reason.DIVERGED_FNORM_NAN
        if it == 0:
            self.reset()
            self.x_prev, self.f_prev = X.copy(), F.copy()
            return Reason.CONVERGED_FNORM_ABS if fnorm == 0.0 else Reason.ITERATING
        du = X.copy()
        du.axpy(-1.0, self.x_prev)
        du_norm = du.norm()
        energy = abs(du.dot(self.f_prev))
        self.du_max = max(self.du_max, du_norm)
        if self.energy_first is None:
            self.energy_first = energy
        self.x_prev, self.f_prev = X.copy(), F.copy()
        d_ratio = du_norm / self.du_max if self.du_max > 0 else 0.0
        e_ratio = energy / self.energy_first if self.energy_first > 0 else 0.0
        self.ratios.append((d_ratio, e_ratio))
        if d_ratio < self.eps_d and e_ratio < self.eps_e:
            self.converged = True
            return Reason.CONVERGED_SNORM_RELATIVE
        if it >= snes.getTolerances()[3]:
            return Reason.DIVERGED_MAX_IT
        return Reason.ITERATING
