"""What an implicit time integrator contributes to the step of Guilkey &
Weiss (section 3.3): the inertia of the grid as a function of the
incremental displacement u, its derivative, the Newton predictor, and the
particle update of step 7. The Newton step itself (steps 1-8) lives in
:class:`pimpm.simulation.Simulation`; each integrator is one small object.

Grid quantities are owned dof arrays: ``v``, ``a`` the grid velocity and
acceleration at t interpolated from the particles (G&W eq. 3).
"""
from collections import namedtuple

import numpy as np

#: a parameter an integrator takes from the ``time`` section: its default,
#: the closed range it must lie in, and what it means (for error messages)
TimeParameter = namedtuple("TimeParameter", "default lower upper meaning")


class ImplicitIntegrator:
    """Base: the quasi-static step (no inertia). Subclasses override what
    their scheme changes."""

    name = "quasi_static"
    explicit = False
    #: is there inertia (a mass term in the residual and tangent)?
    dynamic = False
    #: factor of the stiffness and of the internal minus external force in the balance
    stiffness_factor = 1.0
    #: ``time`` keys this integrator takes (constructor arguments): name -> TimeParameter
    parameters = {}

    def mass_coefficient(self, dt):
        """d a(t+dt) / du: the mass term of the tangent per unit mass."""
        return 0.0

    def grid_kinematics(self, u, v, a, dt):
        """v_g(t+dt) and a_g(t+dt) for the increment u."""
        return u / dt, np.zeros_like(u)

    def free_flight(self, v, a, dt):
        """The part of u set by the grid state at t alone (the momentum
        formulation's base): nothing in quasi-statics."""
        return np.zeros_like(v)

    def predictor(self, v, a, dt):
        """Initial Newton guess: G&W step 2 starts from u = 0; the expected
        increment dt v + dt^2/2 a is closer and saves Newton iterations
        without changing the converged answer (in quasi-statics v_p is the
        last increment over dt)."""
        return dt * v + 0.5 * dt**2 * a

    def balance(self, force, state, u):
        """The residual -Q of G&W step 3 before constraints, in place: the
        internal minus external force at t+dt (``force``) plus the inertia
        M a(t+dt) of the increment ``u``."""
        if self.dynamic:
            force += state.inertia(u)
        return force

    @property
    def needs_previous_force(self):
        """Does the balance use the internal minus external force at t?"""
        return False

    def update_particles(self, particles, u_p, a_p, dt):
        """G&W step 7 for velocities and accelerations (positions: x += u_p)."""
        particles["v"] = u_p / dt
        particles["a"] = np.zeros_like(u_p)
