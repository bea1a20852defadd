"""Functions of time that scale velocities, forces and gravity (the input's
``functions:`` section, docs/INPUT.md): piecewise-linear tables, constant
beyond their ends. Every shorthand (``constant``, ``ramp``) is a table once
validated.

A prescribed motion is integrated exactly over a step: a rigid body moving
with velocity v f(t) moves by v times the integral of f over the step
(:meth:`TimeFunction.integral`), not by v f(t) dt, so a platen that
approaches, holds and retracts ends exactly where the table says, whatever
the step.
"""
import numpy as np


class TimeFunction:
    """f(t) from the points (t_k, f_k) with t_k non-decreasing (two equal
    times make a jump: the later value holds from then on); constant before
    the first point and after the last."""

    def __init__(self, points, name=""):
        points = np.asarray(points, dtype=float).reshape(-1, 2)
        self.t = points[:, 0].copy()
        self.f = points[:, 1].copy()
        self.name = name

    def __call__(self, time):
        t, f = self.t, self.f
        if time < t[0]:
            return float(f[0])
        if time >= t[-1]:
            return float(f[-1])
        k = int(np.searchsorted(t, time, side="right")) - 1      # t[k] <= time < t[k+1]
        width = t[k + 1] - t[k]
        return float(f[k] + (f[k + 1] - f[k]) * (time - t[k]) / width)

    def primitive(self, time):
        """The integral of f from t_0 to ``time`` (negative before t_0)."""
        t, f = self.t, self.f
        if time <= t[0]:
            return float(f[0] * (time - t[0]))
        widths = np.diff(t)
        areas = 0.5 * (f[1:] + f[:-1]) * widths
        k = int(np.searchsorted(t, time, side="right")) - 1
        if k >= len(t) - 1:
            return float(np.sum(areas) + f[-1] * (time - t[-1]))
        partial = time - t[k]
        here = self(time)
        return float(np.sum(areas[:k]) + 0.5 * (f[k] + here) * partial)

    def integral(self, t0, t1):
        """The exact integral of f over [t0, t1]."""
        return self.primitive(t1) - self.primitive(t0)

    def __repr__(self):
        return f"TimeFunction({self.name!r}, {np.column_stack([self.t, self.f]).tolist()})"


#: f = 1 at all times (a quantity given without a function)
ONE = TimeFunction([[0.0, 1.0]], "1")


def make_functions(config):
    """name -> TimeFunction for the validated ``functions`` section."""
    return {name: TimeFunction(spec["points"], name) for name, spec in config.get("functions", {}).items()}


def lookup(functions, name):
    """The function called ``name`` (None: f = 1)."""
    return ONE if name is None else functions[name]
