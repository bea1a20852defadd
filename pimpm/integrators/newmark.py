"""The Newmark family; its default beta = 1/4, gamma = 1/2 is the
trapezoidal rule of Guilkey & Weiss (eq. 14-16), which conserves energy."""
from .base import ImplicitIntegrator


class Newmark(ImplicitIntegrator):
    """u = dt v + dt^2 ((1/2 - beta) a + beta a(t+dt)),
    v(t+dt) = v + dt ((1 - gamma) a + gamma a(t+dt)), written in u."""

    name = "newmark"
    dynamic = True

    def __init__(self, beta=0.25, gamma=0.5):
        self.beta = beta
        self.gamma = gamma

    def mass_coefficient(self, dt):
        return 1.0 / (self.beta * dt**2)                       # 4/dt^2 (G&W step 2)

    def grid_kinematics(self, u, v, a, dt):
        beta, gamma = self.beta, self.gamma
        # a(t+dt) = (u - dt v - dt^2 (1/2 - beta) a) / (beta dt^2)       (G&W eq. 16)
        a_new = self.mass_coefficient(dt) * u - 1.0 / (beta * dt) * v - (0.5 / beta - 1.0) * a
        # v(t+dt) = gamma / (beta dt) u + (1 - gamma / beta) v + dt (1 - gamma / (2 beta)) a   (eq. 15)
        v_new = gamma / (beta * dt) * u + (1.0 - gamma / beta) * v
        a_weight = dt * (1.0 - 0.5 * gamma / beta)
        if a_weight != 0.0:
            v_new += a_weight * a
        return v_new, a_new

    def free_flight(self, v, a, dt):
        return dt * v + (0.5 - self.beta) * dt**2 * a         # u with a(t+dt) = 0

    def update_particles(self, particles, u_p, a_p, dt):
        # G&W step 7: v_p += dt ((1 - gamma) a_p(t) + gamma a_p(t+dt))
        particles["v"] = particles["v"] + dt * ((1.0 - self.gamma) * particles["a"] + self.gamma * a_p)
        particles["a"] = a_p
