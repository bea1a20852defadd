"""Quasi-static steps (G&W 5.1.1): no inertia, time is a load parameter."""
from .base import ImplicitIntegrator


class QuasiStatic(ImplicitIntegrator):
    name = "quasi_static"
