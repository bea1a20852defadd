#!/usr/bin/env python3
"""Why the 2 mm GIMP upsetting with F-bar reports 1610 kN at 60% with the
weak nodes of the symmetry planes folded along them, and 825 kN without
(issue 28, docs/VALIDATION.md "The bonded upsetting"): the axisymmetric
upsetting of scripts/upsetting_validation.py at 2 mm cells, `f_bar: true`,
one rank, stepped with the run's own step control twice, as shipped and with
the face folds switched off (a weak node that a grid face prescribes in a
component is then left in the basis, as before issue 31); each step's
platen force, Newton iterations and the weak nodes it folds. Then the first
run's state one step before the end is stepped on to 60% in 1, 2 and 4
steps with the face folds off.

    python scripts/fbar_fold_path.py
"""
import contextlib
import os
import sys

import petsc4py

petsc4py.init(sys.argv[:1])
import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from body_contact_validation import march  # noqa: E402
from upsetting_validation import case  # noqa: E402

from pimpm import weak_nodes  # noqa: E402
from pimpm.config import validate  # noqa: E402
from pimpm.simulation import Simulation  # noqa: E402

END = 9.0e-3                  # 60% of the half height at 1 m/s
FOLDED = []                   # per WeakNodes built: (face nodes, free nodes) that are weak


class Recorded(weak_nodes.WeakNodes):
    """The shipped WeakNodes, recording its weak nodes; ``faces``: False
    leaves the weak nodes of the grid faces in the basis."""
    faces = True

    def __init__(self, grid, support, prescribed, fraction, held=None):
        super().__init__(grid, support, prescribed, fraction, held)
        if not Recorded.faces:
            self.weak &= self.mask == 0
            self.receives = ~self.weak & (self.mask >= 0)
            self.strong = self.receives & (self.support > 0.0)
        weak = np.nonzero(self.weak)[0]
        FOLDED.append(([tuple(int(v) for v in grid.ghost_ijk[i]) for i in weak if self.mask[i] > 0],
                       int(np.count_nonzero(self.mask[weak] == 0))))


@contextlib.contextmanager
def face_folds(on):
    saved = weak_nodes.WeakNodes, Recorded.faces
    weak_nodes.WeakNodes, Recorded.faces = Recorded, on
    try:
        yield
    finally:
        weak_nodes.WeakNodes, Recorded.faces = saved


def simulation():
    return Simulation(validate(case(2.0, "gimp", True)), MPI.COMM_SELF)


def kilonewtons(info):
    return -info["forces"]["platen"][1] / 1e3


def main():
    runs = {}
    for label, on in (("face folds (as shipped)", True), ("face folds off", False)):
        print(f"\n{label}: time (ms), platen force (kN), Newton iterations, weak face nodes folded (i, j), "
              "weak free nodes")
        with face_folds(on):
            sim = simulation()
            rows = []
            for info, _ in march(sim, END):
                faces, free = FOLDED[-1]
                FOLDED.clear()
                rows.append((sim.time, kilonewtons(info)))
                print(f"{sim.time * 1e3:7.3f} {kilonewtons(info):8.0f} {info['newton_iterations']:3d}  {faces} {free}")
        runs[label] = rows
    before = runs["face folds (as shipped)"][-2][0]
    print(f"\nThe first run's state at {before * 1e3:.3f} ms stepped on to {END * 1e3:g} ms with the face folds off:")
    for steps in (1, 2, 4):
        with face_folds(True):
            sim = simulation()
            for _ in march(sim, END):        # the same path (the step control aims at END)
                if sim.time >= before:
                    break
        with face_folds(False):
            forces = []
            for _ in range(steps):
                info = sim.advance((END - before) / steps)
                forces.append(kilonewtons(info))
        print(f"{steps} step(s): {', '.join(f'{f:.0f}' for f in forces)} kN")


if __name__ == "__main__":
    main()
