"""Backward Euler, Sulsky & Kaul's theta = 1 scheme (eq. 2.4.1-2.4.13):
first order, dissipative."""
from .base import ImplicitIntegrator


class BackwardEuler(ImplicitIntegrator):
    """v(t+dt) = u / dt, a(t+dt) = (v(t+dt) - v) / dt."""

    name = "backward_euler"
    dynamic = True

    def mass_coefficient(self, dt):
        return 1.0 / dt**2

    def grid_kinematics(self, u, v, a, dt):
        return u / dt, (u / dt - v) / dt

    def free_flight(self, v, a, dt):
        return dt * v

    def predictor(self, v, a, dt):
        return dt * v

    def update_particles(self, particles, u_p, a_p, dt):
        particles["v"] = particles["v"] + dt * a_p              # v_p += dt a_p (FLIP)
        particles["a"] = a_p
