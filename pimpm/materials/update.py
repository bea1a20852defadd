"""The stress update of every particle, material by material (G&W step 5:
stress and tangent at the trial F). Used by the implicit residual and
tangent and by the explicit step alike."""
import numpy as np

from ..kernels import material_point as kernel_codes


def update_stress(material_groups, kinematics, F, history, tangent, F_inc=None):
    """Cauchy stress (n, 3, 3), the spatial tangent (n, 3, 3, 3, 3) or None,
    and the history after this deformation, for every particle.

    ``material_groups``: [(material, particle index)]; ``history``: the
    values committed at t (name -> per-particle array). The kinematics does
    the material-point work (plane stress: solves the thickness stretch and
    writes it back into ``F`` and ``F_inc``)."""
    n = len(F)
    sigma = np.zeros((n, 3, 3))
    c = np.zeros((n, 3, 3, 3, 3)) if tangent else None
    new_history = {k: v.copy() for k, v in history.items()}
    for material, index in material_groups:
        if len(index) == 0:
            continue
        old = {k: history[k][index] for k in material.history}
        Fi = F[index]
        Fi_inc = F_inc[index] if F_inc is not None else None
        s, cc, new = kinematics.material_update(material, Fi, old, tangent, Fi_inc)
        if kinematics.solves_thickness:        # write the solved thickness stretch back
            F[index] = Fi
            if F_inc is not None:
                F_inc[index] = Fi_inc
        sigma[index] = s
        if tangent:
            c[index] = cc
        for k, v in new.items():
            new_history[k][index] = v
    return sigma, c, new_history


class MaterialTable:
    """The materials of a simulation as the compiled kernels take them
    (:mod:`pimpm.kernels.material_point`): each particle's material index,
    each material's model code and packed parameters, and the history of
    every particle packed in one array (a row per particle, the material's
    ``history`` fields one after the other in declaration order)."""

    def __init__(self, material_groups, n):
        self.groups = material_groups
        materials = [m for m, _ in material_groups]
        self.models = np.array([m.kernel_model for m in materials], dtype=np.int64)
        self.params = np.array([m.packed_parameters() for m in materials]).reshape(len(materials), 6)
        self.material_of = np.zeros(n, dtype=np.int64)
        for mi, (_, index) in enumerate(material_groups):
            self.material_of[index] = mi
        self.width = max([self.history_width(m) for m in materials] + [0])
        # one model for every particle: the kernels compile only its code
        codes = set(self.models.tolist())
        self.only_model = kernel_codes.model_tag(codes.pop() if len(codes) == 1 else kernel_codes.MIXED)

    @staticmethod
    def history_width(material):
        return int(sum(np.prod(shape, dtype=int) for shape in material.history.values()))

    def pack(self, history):
        """(n, width) array of the history dict (name -> per-particle array)."""
        packed = np.zeros((len(self.material_of), self.width))
        for material, index in self.groups:
            col = 0
            for name, shape in material.history.items():
                w = int(np.prod(shape, dtype=int))
                packed[index, col:col + w] = history[name][index].reshape(len(index), w)
                col += w
        return packed

    def unpack(self, packed, history):
        """The history dict after a step: ``history`` (the values at t) with
        each material's particles replaced by their packed rows."""
        new = {k: v.copy() for k, v in history.items()}
        for material, index in self.groups:
            col = 0
            for name, shape in material.history.items():
                w = int(np.prod(shape, dtype=int))
                new[name][index] = packed[index, col:col + w].reshape((len(index),) + tuple(shape))
                col += w
        return new
