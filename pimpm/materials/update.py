"""The stress update of every particle, material by material (G&W step 5:
stress and tangent at the trial F). Used by the implicit residual and
tangent and by the explicit step alike."""
import numpy as np


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
