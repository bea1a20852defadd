"""``python -m pimpm.precompile``: compile every kernel once (2D and 3D, every
material model, implicit and explicit steps), so that the first run after installing does not wait for
numba; scripts/setup.sh runs it. Compiled code is cached on disk
(:mod:`pimpm.kernels.jit`). (A problem whose materials mix several models
compiles its own particle kernel at its first run.)"""
import itertools
import sys
import time

import petsc4py

petsc4py.init(sys.argv[:1])
import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402

from .config import validate  # noqa: E402
from .kernels import contact  # noqa: E402
from .kernels.jit import CACHE_DIRECTORY  # noqa: E402
from .materials import MODELS, REQUIRED  # noqa: E402
from .simulation import Simulation  # noqa: E402


#: one material of each registered model (the particle evaluation is compiled per model)
MATERIALS = [dict({"model": name}, **{key: 0.1 for key, p in model.parameters.items() if p.default is REQUIRED})
             for name, model in MODELS.items()]


def tiny(dim, shape_functions, material):
    """A small block pressed by a platen: one step uses every implicit kernel
    (the particle kernels are compiled per footprint size: linear shape
    functions touch 2^dim nodes, GIMP and B-splines 3^dim)."""
    upper, cells = ([2.0, 2.0], [4, 4]) if dim == 2 else ([2.0, 2.0, 2.0], [2, 2, 3])
    body_upper = [1.0] * (dim - 1) + [1.0]
    return {"grid": {"lower": [0.0] * dim, "upper": upper, "cells": cells,
                     "shape_functions": shape_functions},
            "materials": {"m": dict(material, shear_modulus=1.0, bulk_modulus=3.0, density=1.0)},
            "bodies": [{"name": "block", "material": "m", "particles_per_cell": 2,
                        "geometry": {"type": "box", "lower": [0.0] * dim, "upper": body_upper}},
                       {"name": "platen", "rigid": True, "particles_per_cell": 2,
                        "velocity": [0.0] * (dim - 1) + [-0.01],
                        "geometry": {"type": "box", "lower": [0.0] * (dim - 1) + [1.0],
                                     "upper": [1.5] * (dim - 1) + [1.5]}}],
            "time": {"integrator": "quasi_static", "dt": 1.0, "end_time": 1.0}}


def main():
    start = time.perf_counter()
    for dim in (2, 3):
        for shape_functions, material in itertools.product(("linear", "gimp"), MATERIALS):
            sim = Simulation(validate(tiny(dim, shape_functions, material)), MPI.COMM_SELF)
            sim.advance(1.0)
            sim.solver.destroy()
        for shape_functions, average in itertools.product(("linear", "gimp"), ("cells", "nodes")):
            config = tiny(dim, shape_functions, MATERIALS[0])   # F-bar's couplings (pimpm.kernels.fbar)
            config["materials"]["m"]["f_bar"] = average
            sim = Simulation(validate(config), MPI.COMM_SELF)
            sim.advance(1.0)
            sim.solver.destroy()
        config = tiny(dim, "gimp", MATERIALS[0])             # contact with a rigid tool
        config["bodies"][1].update(contact="frictionless")   # the same kernels as friction
        sim = Simulation(validate(config), MPI.COMM_SELF)
        sim.advance(1.0)
        sim.solver.destroy()
        contact.point_distances(contact.MESH, np.zeros(contact.MESH_HEADER), np.zeros((0, dim)),
                                np.zeros(0))                 # a surface tool's seeding (pimpm.surfaces)
        for shape_functions in ("linear", "gimp"):          # the explicit step's kernels
            config = tiny(dim, shape_functions, MATERIALS[0])
            config["time"] = {"integrator": "explicit", "end_time": 1.0}
            sim = Simulation(validate(config), MPI.COMM_SELF)
            sim.advance(0.5 * sim.stable_time_step())
            # deformable bodies in contact, a velocity field each (pimpm.fields)
            config["bodies"][1] = dict(config["bodies"][0], name="top", geometry={
                "type": "box", "lower": [0.0] * (dim - 1) + [1.0], "upper": [1.0] * (dim - 1) + [1.5]})
            config["contact"] = [{"bodies": ["block", "top"], "law": "friction", "friction_coefficient": 0.3}]
            sim = Simulation(validate(config), MPI.COMM_SELF)
            sim.advance(0.5 * sim.stable_time_step())
            # ... and inside Newton (pimpm.terms.pairs)
            config["contact"] = [{"bodies": ["block", "top"], "law": "frictionless"}]
            config["time"] = {"integrator": "newmark", "dt": 0.01, "end_time": 1.0}
            sim = Simulation(validate(config), MPI.COMM_SELF)
            sim.advance(0.01)
            sim.solver.destroy()
    print(f"pimpm: kernels compiled in {time.perf_counter() - start:.1f} s "
          f"(cache: {CACHE_DIRECTORY})")


if __name__ == "__main__":
    main()
