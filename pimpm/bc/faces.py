"""Grid-face conditions: ``fixed`` (all components zero), ``roller`` (the
normal component zero: a symmetry plane; ``symmetry`` in the input),
``free``, and a prescribed velocity of some or all components, times a
function of time (the face's nodes move by the velocity times the
function's exact integral over the step)."""
import numpy as np

from ..functions import lookup

AXES = "xyz"


def face_constraints(grid, boundary, time=0.0, dt=0.0, functions=None):
    """Owned dof indices prescribed by the grid-face conditions and their
    incremental displacements over the step from ``time`` to ``time + dt``."""
    dofs, values = [], []
    for face, kind in boundary.items():
        if kind == "fixed":
            d = grid.face_dofs(face, range(grid.dim))
            dofs.append(d)
            values.append(np.zeros(len(d)))
        elif kind == "roller":
            d = grid.face_dofs(face, [AXES.index(face[0])])
            dofs.append(d)
            values.append(np.zeros(len(d)))
        elif isinstance(kind, dict):
            scale = lookup(functions or {}, kind["function"]).integral(time, time + dt)
            for axis, v in kind["velocity"].items():
                d = grid.face_dofs(face, [AXES.index(axis)])
                dofs.append(d)
                values.append(np.full(len(d), v * scale))
    dofs = np.concatenate(dofs) if dofs else np.zeros(0, dtype=np.int64)
    values = np.concatenate(values) if values else np.zeros(0)
    if len(dofs) == 0:
        return dofs, values
    # a dof on two faces (an edge node): fixed or roller (zero) wins over a velocity
    order = np.lexsort((np.abs(values) > 0, dofs))
    dofs, values = dofs[order], values[order]
    first = np.r_[True, dofs[1:] != dofs[:-1]]
    return dofs[first], values[first]
