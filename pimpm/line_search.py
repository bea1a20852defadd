"""The line search of runs with unilateral contact: the full Newton step
when it cuts the residual norm to a fraction (pimpm.presets.FULL_STEP_FIRST)
of the current one, else l2's parabola.

PETSc's ``l2`` fits ||F(x - lambda y)||^2 through lambda = 0, 1/2 and 1 and
evaluates the residual at the fitted lambda: three residuals every Newton
iteration. Contact needs that fit while the contact states settle (a full
step taken where a corner has just left a tool lets the body spring back
through it, presets.CONTACT_OPTIONS), but once they have settled Newton
converges quadratically and the fit only confirms lambda = 1. Here the
full step is evaluated first and kept when it cuts the residual norm to a
quarter (one residual); otherwise the residual at lambda = 1/2 gives l2's
parabola and the step is scaled as l2 scales it. Accepting any decrease
(a factor of 1) broke the friction onset (a full step that lifts the block
off the floor lowers the residual a little; docs/PERFORMANCE.md), and a half
cut the frictional billet at mu = 0.1 once.

Made of PETSc's ``basic`` line search and a pre-check that scales the
direction (SNESLineSearchSetPreCheck, the only line-search hook petsc4py
3.18 has); ``basic`` then evaluates the residual at the step the pre-check
chose. For a kept full step that is the pre-check's own evaluation: SNES's
residual function here hands it back instead of evaluating it again (the
iterate is compared bit for bit: both are x - 1.0 y by VecWAXPY)."""
import math
import weakref

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

#: l2's smallest step (PETSc's steptol): a smaller fitted step is replaced by 1/2
LAMBDA_MIN = 1e-8
#: and the largest pimpm takes (l2 has none but -snes_linesearch_maxstep on |y|)
LAMBDA_MAX = 2.0
#: halvings of a step whose residual is not finite (an inverted particle),
#: as l2 (PETSc's -snes_linesearch_max_it does not bound them either)
MAX_HALVINGS = 20


def l2_step(f0, f_half, f1):
    """The step PETSc's SNESLINESEARCHL2 takes (one iteration) from the
    residual norms at lambda = 0, 1/2 and 1: a Newton step on the parabola
    E(lambda) through their squares from lambda = 1, downhill where the
    parabola is concave: 1 - E'(1) / |E''|. Within [LAMBDA_MIN, LAMBDA_MAX]
    (1/2 below it, as l2 does)."""
    g0, gh, g1 = f0 * f0, f_half * f_half, f1 * f1
    slope = 3.0 * g1 - 4.0 * gh + g0                 # E'(1)
    curvature = 4.0 * (g1 - 2.0 * gh + g0)           # E''
    if curvature == 0.0 or not math.isfinite(slope / curvature):
        return 1.0 if g1 < gh else 0.5
    lam = 1.0 - slope / abs(curvature)
    return 0.5 if lam < LAMBDA_MIN else min(lam, LAMBDA_MAX)


class FullStepFirst:
    """The pre-check of PETSc's ``basic`` line search on ``snes``, whose
    residual ``form_residual(snes, X, R)`` and current residual vector ``R``
    it uses: the full step is kept when it cuts the residual norm to at most
    ``threshold`` times the current one. Collective (norms)."""

    def __init__(self, snes, form_residual, R, threshold):
        # weakly: SNES holds this object (its pre-check and residual), and a
        # cycle between them could outlive PetscFinalize, destroying the SNES after it
        self.snes = weakref.ref(snes)
        self.form_residual = form_residual
        self.R = R
        self.threshold = threshold
        self.W = R.duplicate()
        self.G = R.duplicate()
        self.kept = False         # do W and G hold the full step just kept and its residual?
        self.full_steps = 0       # full steps kept at once
        self.fitted = 0           # steps scaled to l2's parabola
        # -snes_linesearch_monitor: say what was kept, as PETSc's line searches do
        self.monitor = PETSc.Options().hasName("snes_linesearch_monitor")
        snes.setFunction(self.residual, R)
        snes.setLineSearchPreCheck(self)

    def residual(self, snes, X, R):
        """SNES's residual function: the kept full step's residual, or
        ``form_residual``."""
        kept, self.kept = self.kept, False
        if kept:
            same = np.array_equal(X.getArray(readonly=True), self.W.getArray(readonly=True))
            if X.getComm().tompi4py().allreduce(same, op=MPI.LAND):
                self.G.copy(R)
                return
        self.form_residual(snes, X, R)

    def norm_at(self, x, y, lam):
        self.W.waxpy(-lam, y, x)                    # SNES steps x - lambda y
        self.form_residual(self.snes(), self.W, self.G)
        return self.G.norm()

    def __call__(self, x, y):
        """Scale the direction y in place; True if it changed."""
        f0 = self.R.norm()
        f1 = self.norm_at(x, y, 1.0)
        if math.isfinite(f1) and f1 <= self.threshold * f0:
            self.full_steps += 1
            self.kept = True
            self._say(f"full step kept, fnorms = [{f1:g}, {f0:g}] at lambdas = [1., 0.]")
            return False
        self.fitted += 1
        # as l2: halve the step until its residual is finite, then fit through it, its half and 0
        top = 1.0
        for _ in range(MAX_HALVINGS):
            if math.isfinite(f1):
                break
            top *= 0.5
            f1 = self.norm_at(x, y, top)
        if math.isfinite(f1):
            f_half = self.norm_at(x, y, 0.5 * top)
            lam = top * l2_step(f0, f_half, f1)
            self._say(f"lambdas = [{top:g}, {0.5 * top:g}, 0.], fnorms = [{f1:g}, {f_half:g}, {f0:g}]: l2's lambda = {lam:g}")
        else:
            lam = top
            self._say(f"no finite residual down to lambda = {top:g}")
        y.scale(lam)
        return True

    def _say(self, text):
        if self.monitor:
            PETSc.Sys.Print(f"      Line search (pimpm, full step first): {text}", comm=self.R.getComm())

    def destroy(self):
        snes = self.snes()
        if snes is not None:
            snes.setLineSearchPreCheck(None)
        self.W.destroy()
        self.G.destroy()
