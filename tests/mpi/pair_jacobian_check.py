"""Finite-difference check of the assembled Jacobian with two deformable
bodies in contact, a velocity field each (pimpm.fields, pimpm.terms.pairs),
run under mpiexec.

    pair_jacobian_check.py DIM LAW [INTEGRATOR [SHAPE [ball]]]

(LAW: frictionless, friction or bonded; defaults newmark, gimp). A block
(``ball``: a disk or ball, pressed down ten times harder, so that some
pairs near its contact are open) slides down and sideways onto a wider one fixed
at its base for two steps; at the next step's Newton guess the assembled tangent (COO, all
ranks' shares summed) is compared with central differences of the residual
over the free dofs, and the matrix-free product with the assembled one.
Prints the errors and the pairs in each state (open, stick, slip); exits 1
if an error exceeds its tolerance or no pair is in contact (with friction:
none sticks or none slips)."""
import sys

import petsc4py
petsc4py.init(sys.argv[:1])
import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402

from pimpm.config import validate  # noqa: E402
from pimpm.simulation import Simulation  # noqa: E402
from pimpm.steps import implicit as implicit_step  # noqa: E402
from pimpm.kernels import multifield as kernels  # noqa: E402
from pimpm.terms.pairs import FieldContact  # noqa: E402

from finite_differences import tangent_errors  # noqa: E402 (tests/mpi/)

dim = int(sys.argv[1][0])
law = sys.argv[2]
integrator = sys.argv[3] if len(sys.argv) > 3 else "newmark"
shape = sys.argv[4] if len(sys.argv) > 4 else "gimp"
ball = len(sys.argv) > 5 and sys.argv[5] == "ball"
comm = MPI.COMM_WORLD
mid = [1.0] * (dim - 1)
raw = {
    "grid": {"lower": [0.0] * dim, "upper": [2.0] * (dim - 1) + [2.5], "cells": [8] * (dim - 1) + [10],
             "shape_functions": shape, "boundary": {"ymin" if dim == 2 else "zmin": "fixed"}},
    "materials": {"m": {"model": "neo_hookean_compressible", "youngs_modulus": 1.0e6,
                        "poisson_ratio": 0.3, "density": 100.0}},
    "bodies": [{"name": "floor", "material": "m", "particles_per_cell": 2,
                "geometry": {"type": "box", "lower": [0.25] * (dim - 1) + [0.0], "upper": [1.75] * (dim - 1) + [1.0]}},
               {"name": "block", "material": "m", "particles_per_cell": 2, "velocity": [2.0] + [0.0] * (dim - 2) + [0.0],
                "geometry": {"type": "box", "lower": [0.5] * (dim - 1) + [1.0], "upper": [1.25] * (dim - 1) + [1.5]}}],
    "contact": [{"bodies": ["block", "floor"], "law": law}],
    "time": {"integrator": integrator, "dt": 0.01, "end_time": 1.0, "gravity": [0.0] * (dim - 1) + [-9.81]},
}
if integrator == "hht":
    raw["time"]["alpha"] = -0.2
if ball:
    raw["bodies"][1]["geometry"] = {"type": "ball", "center": mid + [1.3], "radius": 0.3}
    raw["time"]["gravity"] = [0.0] * (dim - 1) + [-98.1]
raw["contact"][0].update({"friction_coefficient": 0.3} if law == "friction" else {})
sim = Simulation(validate(raw), comm)
term = next(t for t in sim.terms if isinstance(t, FieldContact))
for _ in range(2):
    sim.advance(0.01)
state, _ = implicit_step.prepare(sim, 0.01)
solver, problem = sim.solver, sim.problem
solver.prepare(state)
X = solver.X.duplicate()
X.getArray()[:] = np.where(state.fixed, state.fixed_value, state.predictor())
R = solver.R.duplicate()
problem.form_residual(None, X, R)
problem.form_jacobian(None, X, solver.J, solver.J)
J = solver.whole_jacobian()          # (the free dofs' operator's values, assembled whole)
status = term._local["status"]
states = comm.allreduce(np.array([np.sum(status == k) for k in range(3)]))
# the central differences, and the matrix-free product and diagonal (pimpm.implicit.shell)
relative, shell_error, diagonal_error = tangent_errors(sim.solve_grid, problem, sim.terms, sim.config["solver"],
                                                       state, X, R, J, comm)
if comm.rank == 0:
    print(f"pair jacobian {dim}d {law} {integrator} {shape} ranks {comm.size}: relative error {relative:.3e}, "
          f"shell {shell_error:.3e} (diagonal {diagonal_error:.3e}), pairs open/stick/slip {states.tolist()}")
ok = relative < 1e-5 and shell_error < 1e-12 and diagonal_error < 1e-12 and states[1] + states[2] > 0
if law == "friction" and not ball:
    ok = ok and states[1] > 0 and states[2] > 0
if ball:
    ok = ok and states[0] > 0
sys.exit(0 if ok else 1)
