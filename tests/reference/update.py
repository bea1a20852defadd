"""The stress update of every particle in numpy, material by material (G&W
step 5: stress and tangent at the trial F), with the plane-stress thickness
solve: the reference of pimpm.kernels.particle_step's material points and
pimpm.kernels.material_point.solve_thickness."""
import numpy as np

from .materials import reference_of


def material_update(kinematics, material, F, history, tangent, F_inc=None):
    """Stress, tangent and new history at the material point of the numpy
    reference ``material``; in plane stress (``kinematics.solves_thickness``)
    a vectorised local Newton for F33 so that sigma33 = 0
    (d sigma33 / d ln F33 = c3333 + sigma33), with F and F_inc updated in
    place and the tangent condensed, c_abcd - c_ab33 c_33cd / c_3333."""
    if not kinematics.solves_thickness or len(F) == 0:
        return material.update(F, history, tangent)
    for _ in range(50):
        sigma, c, new = material.update(F, history, True)
        s33 = sigma[:, 2, 2]
        scale = np.abs(c[:, 2, 2, 2, 2]) + np.abs(sigma).max(axis=(1, 2))
        if np.all(np.abs(s33) <= 1e-13 * scale):
            break
        step = np.exp(-s33 / (c[:, 2, 2, 2, 2] + s33))
        F[:, 2, 2] *= step
        if F_inc is not None:
            F_inc[:, 2, 2] *= step
    if tangent:
        c = c.copy()
        c[:, :2, :2, :2, :2] -= (c[:, :2, :2, 2, 2][:, :, :, None, None]
                                 * c[:, 2, 2, :2, :2][:, None, None, :, :]
                                 / c[:, 2, 2, 2, 2][:, None, None, None, None])
    else:
        c = None
    return sigma, c, new


def update_stress(material_groups, kinematics, F, history, tangent, F_inc=None):
    """Cauchy stress (n, 3, 3), the spatial tangent (n, 3, 3, 3, 3) or None,
    and the history after this deformation, for every particle.

    ``material_groups``: [(material, particle index)] of pimpm materials
    (or numpy references); ``history``: the values committed at t (name ->
    per-particle array). Plane stress writes the solved thickness stretch
    back into ``F`` and ``F_inc``."""
    n = len(F)
    sigma = np.zeros((n, 3, 3))
    c = np.zeros((n, 3, 3, 3, 3)) if tangent else None
    new_history = {k: v.copy() for k, v in history.items()}
    for material, index in material_groups:
        if len(index) == 0:
            continue
        reference = material if hasattr(material, "update") else reference_of(material)
        old = {k: history[k][index] for k in reference.history}
        Fi = F[index]
        Fi_inc = F_inc[index] if F_inc is not None else None
        s, cc, new = material_update(kinematics, reference, Fi, old, tangent, Fi_inc)
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
