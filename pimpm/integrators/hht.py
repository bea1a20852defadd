"""Hilber-Hughes-Taylor alpha method (Hilber, Hughes & Taylor 1977): the
Newmark update with beta = (1 - alpha)^2 / 4, gamma = 1/2 - alpha, and the
balance taken between t and t+dt,

    M a(t+dt) + (1 + alpha) (Fint(t+dt) - Fext(t+dt)) - alpha (Fint(t) - Fext(t)) = 0,

with alpha in [-1/3, 0]. Second order, unconditionally stable, and it damps
high frequencies more the larger |alpha| (alpha = 0 is the trapezoidal rule
of Guilkey & Weiss, bit for bit). Fint(t) is the internal force of the
particles' stresses at t on the reset grid; the external force is the same
at t and t+dt (gravity), so its two terms add up to Fext."""
from .base import TimeParameter
from .newmark import Newmark


class HHT(Newmark):
    name = "hht"
    parameters = {"alpha": TimeParameter(0.0, -1.0 / 3.0, 0.0,
                                         "HHT: 0 is the trapezoidal rule, -1/3 the most damping")}

    def __init__(self, alpha=0.0):
        if not -1.0 / 3.0 <= alpha <= 0.0:
            raise ValueError(f"HHT alpha = {alpha!r}: expected a number in [-1/3, 0]")
        super().__init__(beta=0.25 * (1.0 - alpha) ** 2, gamma=0.5 - alpha)
        self.alpha = alpha
        self.stiffness_factor = 1.0 + alpha

    @property
    def needs_previous_force(self):
        return self.alpha != 0.0

    def balance(self, force, state, u):
        if self.alpha != 0.0:
            force *= self.stiffness_factor
        force += state.inertia(u)
        if self.alpha != 0.0:
            force -= self.alpha * state.previous_force
        return force
