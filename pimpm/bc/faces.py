"""Grid-face conditions: ``fixed`` (all components zero), ``roller`` (the
normal component zero: a symmetry plane; ``symmetry`` in the input) and
``free``."""
import numpy as np

AXES = "xyz"


def face_constraints(grid, boundary):
    """Owned dof indices prescribed to zero by the grid-face conditions."""
    dofs = []
    for face, kind in boundary.items():
        if kind == "fixed":
            dofs.append(grid.face_dofs(face, range(grid.dim)))
        elif kind == "roller":
            dofs.append(grid.face_dofs(face, [AXES.index(face[0])]))
    return np.unique(np.concatenate(dofs)) if dofs else np.zeros(0, dtype=np.int64)
