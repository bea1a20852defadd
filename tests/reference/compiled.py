"""A pimpm material through its compiled kernels, with the numpy reference's
interface (``update``, ``stress``, ``stress_and_tangent``,
``strain_energy``), so that physics tests check the code that runs."""
import numpy as np

from pimpm.kernels import material_point, stress
from pimpm.materials.table import MaterialTable


class Compiled:
    """``material`` (a :class:`pimpm.materials.Material`) evaluated by
    :func:`pimpm.kernels.material_point.update_points` and
    :func:`pimpm.kernels.stress.point_energies`. ``plane_stress``: solve the
    thickness stretch first (F is then changed in place, as the reference's)."""

    def __init__(self, material, plane_stress=False):
        self.material = material
        self.plane_stress = plane_stress

    def __getattr__(self, key):
        return getattr(self.material, key)

    def _table(self, n):
        return MaterialTable([(self.material, np.arange(n))], n)

    def _history(self, n, history):
        initial = self.material.model.initial_history()
        full = {}
        for name, (shape, value) in initial.items():
            given = (history or {}).get(name)
            full[name] = np.asarray(given, float) if given is not None else np.zeros((n,) + shape) + value
        return full

    def update(self, F, history=None, tangent=True, F_inc=None):
        F = np.ascontiguousarray(F, dtype=float)
        n = len(F)
        table = self._table(n)
        full = self._history(n, history)
        packed = table.pack(full)
        out = np.zeros_like(packed)
        sigma = np.zeros((n, 3, 3))
        c = np.zeros((n, 3, 3, 3, 3))
        F_inc = np.zeros((0, 3, 3)) if F_inc is None else F_inc
        self.unconverged = material_point.update_points(table.models, table.params, table.material_of, F,
                                                        packed, out, sigma, c, tangent, self.plane_stress,
                                                        F_inc)
        return sigma, (c if tangent else None), table.unpack(out, full)

    def stress(self, F):
        return self.update(F, None, False)[0]

    def stress_and_tangent(self, F):
        sigma, c, _ = self.update(F, None, True)
        return sigma, c

    def strain_energy(self, F, history=None):
        F = np.ascontiguousarray(F, dtype=float)
        n = len(F)
        table = self._table(n)
        out = np.empty(n)
        stress.point_energies(table.only_model, table.models, table.params, table.material_of, F,
                              table.pack(self._history(n, history)), out)
        return out
