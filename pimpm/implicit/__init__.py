"""The implicit step of Guilkey & Weiss (2003), section 3.3, as physics:
:mod:`.state` (what is fixed during one step's Newton iterations),
:mod:`.problem` (residual and exact tangent, the SNES callbacks),
:mod:`.formulation` (what deforms the particles: the velocity or Sulsky &
Kaul's momentum formulation, objects chosen by ``time.formulation``),
:mod:`.momentum` (the momentum formulation's projection) and :mod:`.shell`
(the matrix-free tangent). The PETSc solver set-up is :mod:`pimpm.solver`."""
from .problem import StepProblem, constraint_scale, residual_scale
from .state import StepState, TangentPattern

__all__ = ["StepProblem", "StepState", "TangentPattern", "constraint_scale", "residual_scale"]
