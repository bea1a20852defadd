"""The materials of a run as the compiled kernels take them (G&W step 5:
stress and tangent at the trial F, for the implicit residual and tangent
and the explicit step alike)."""
import numpy as np

from ..kernels import material_point as kernel_codes


class MaterialTable:
    """The materials of a simulation as the compiled kernels take them
    (:mod:`pimpm.kernels.material_point`): each particle's material index,
    each material's model code and packed parameters, and the history of
    every particle packed in one array (a row per particle, the material's
    ``history`` fields one after the other in declaration order)."""

    def __init__(self, material_groups, n):
        self.groups = material_groups
        materials = [m for m, _ in material_groups]
        self.models = np.array([m.code for m in materials], dtype=np.int64)
        packed = [m.packed_parameters() for m in materials]
        #: each material's packed parameters, padded to the widest (a model reads its own)
        self.params = np.zeros((len(materials), max([len(p) for p in packed] + [2])))
        for mi, values in enumerate(packed):
            self.params[mi, :len(values)] = values
        self.material_of = np.zeros(n, dtype=np.int64)
        for mi, (_, index) in enumerate(material_groups):
            self.material_of[index] = mi
        self.width = max([self.history_width(m) for m in materials] + [0])
        #: each material's F-bar switch (pimpm.kernels.fbar)
        self.f_bar = np.array([bool(getattr(m, "f_bar", False)) for m in materials], dtype=bool)
        #: ... and the exponent of its average, 1 - f_bar_blend (det F_bar = J_bar^alpha J^(1 - alpha))
        self.f_bar_alpha = np.array([1.0 - getattr(m, "f_bar_blend", 0.0) for m in materials] + [1.0])
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
