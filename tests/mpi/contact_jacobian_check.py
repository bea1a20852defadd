"""Finite-difference check of the assembled Jacobian with a rigid tool in
unilateral contact (pimpm.terms.contact), run under mpiexec.

    contact_jacobian_check.py DIM LAW GEOMETRY [INTEGRATOR [KINEMATICS [SHAPE [uncapped]]]]

(defaults: newmark, plane strain or 3d, gimp; ``uncapped``: friction without
the cap on the tangential stiffness, so that every sticking corner's
stiffness is mu p / stick; by default most pressing corners are capped).

A block under gravity is pressed by a tool (LAW: frictionless, friction or tied;
GEOMETRY: box, ball, half_space or surface (the ball as a polygon or
polyhedron), the half-space inclined and moving sideways too) for two steps (without friction), then with friction and a
random elastic slip carried in from the last step (tied: the tool moved so that
half of the corners it holds pull); at the next step's
Newton guess the assembled tangent (COO, all ranks' shares summed) is
compared with central differences of the residual over the free dofs, and
the matrix-free product with the assembled one. Prints the errors and the
corners in each state (open, stick, slip); exits 1 if an error exceeds
its tolerance or no corner is in contact."""
import sys

import petsc4py
petsc4py.init(sys.argv[:1])
import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402

from pimpm.config import validate  # noqa: E402
from pimpm.simulation import Simulation  # noqa: E402
from pimpm.steps import implicit as implicit_step  # noqa: E402

from finite_differences import tangent_errors  # noqa: E402 (tests/mpi/)

dim = int(sys.argv[1][0])
law = sys.argv[2]
geometry = sys.argv[3]
integrator = sys.argv[4] if len(sys.argv) > 4 else "newmark"
kinematics = sys.argv[5] if len(sys.argv) > 5 else ("plane_strain" if dim == 2 else "3d")
shape = sys.argv[6] if len(sys.argv) > 6 else "gimp"
uncapped = len(sys.argv) > 7 and sys.argv[7] == "uncapped"
comm = MPI.COMM_WORLD
zero = [0.0] * (dim - 1)
lower, upper = [0.0] * dim, [2.0] * (dim - 1) + [2.5]
cells = [8] * (dim - 1) + [10]
tools = {
    "box": {"type": "box", "lower": zero + [1.0], "upper": [1.5] * (dim - 1) + [1.5]},
    "ball": {"type": "ball", "center": [0.9] * (dim - 1) + [1.6], "radius": 0.61},
    # inclined, touching the block's top at its x = 0.25 edge
    "half_space": {"type": "half_space", "point": [0.25] + [0.0] * (dim - 2) + [1.0],
                   "normal": [0.3] + [0.0] * (dim - 2) + [-1.0]},
}
if geometry == "surface":      # the ball as a surface mesh (pimpm.surfaces): faces, edges and vertices
    import os
    import tempfile
    from surface_shapes import ball_polygon, ball_polyhedron, write_surface  # noqa: E402 (tests/mpi/)
    polygon = ball_polygon if dim == 2 else ball_polyhedron
    path = os.path.join(tempfile.mkdtemp(), "ball.vtk")
    write_surface(path, *polygon(tools["ball"]["center"], tools["ball"]["radius"], 40 if dim == 2 else 3))
    tools["surface"] = {"type": "surface", "file": path}
# the inclined half-space also moves sideways (its corners slip), the others straight down
# (its corners slip), the others slowly straight down (most of theirs stick)
sideways, down = (0.3, -1.0) if geometry == "half_space" else (0.0, -0.05)
tool = {"name": "tool", "rigid": True, "contact": law, "geometry": tools[geometry],
        "particles_per_cell": 1, "velocity": [sideways] + [0.0] * (dim - 2) + [down]}
if law == "friction":
    tool["friction_coefficient"] = 0.2
    if uncapped:
        tool["tangential_stiffness"] = 1e12
raw = {
    "grid": {"lower": lower, "upper": upper, "cells": cells, "shape_functions": shape,
             "boundary": {"ymin" if dim == 2 else "zmin": "fixed"}},
    "kinematics": kinematics,
    "materials": {"m": {"model": "neo_hookean_compressible", "youngs_modulus": 1.0e6,
                        "poisson_ratio": 0.3, "density": 100.0}},
    "bodies": [{"name": "block", "material": "m", "particles_per_cell": 2,
                "geometry": {"type": "box", "lower": [0.25] * (dim - 1) + [0.0],
                             "upper": [1.25] * (dim - 1) + [1.0]}}, tool],
    "time": {"integrator": integrator, "dt": 0.02, "end_time": 1.0,
             "gravity": zero + [-9.81]},
}
if integrator == "hht":
    raw["time"]["alpha"] = -0.2
sim = Simulation(validate(raw), comm)
term = sim.contact_tools[0]
# the set-up steps without friction (Newton's stick-slip cycling on a dropped
# block is a known limitation: see docs/VALIDATION.md), then friction with a
# random tangential traction carried into the step, so that corners stick and slip
term.friction = False
for _ in range(2):
    sim.advance(0.02)
term.friction = law in ("friction", "tied")
rng = np.random.default_rng(7 + comm.rank)
state, _ = implicit_step.prepare(sim, 0.02)
solver, problem = sim.solver, sim.problem
solver.prepare(state)
X = solver.X.duplicate()
# the integrator's predictor (not the contact predictor, which puts corners exactly on
# the tool's surface, where the finite differences would straddle the kink)
X.getArray()[:] = np.where(state.fixed, state.fixed_value, state.predictor())
R = solver.R.duplicate()
term._holding = False          # the exact tangent (not the first iteration's held corners)
if law == "tied":
    # the tool moved along y so that half of the corners it holds at the guess pull
    # (those above the median gap) and half press, and a random elastic slip carried in
    problem.form_residual(None, X, R)
    held = term._local["status"] == 1
    gap = np.concatenate(comm.allgather(-term._local["pressure"][held] / term.kn))
    term._increment[dim - 1] -= float(np.median(gap))
    term.begin_newton(state)   # the corners' areas on the moved tool
    history = term._cand["history"]
    history[:] = 1e-3 * rng.standard_normal(history.shape)
    term._history[term._candidates] = history
    term._u = None
elif term.friction:
    # a random elastic slip carried into the step, about each pressing corner's stick
    # limit at the guess (so that corners stick and slip), and unless ``uncapped`` a cap
    # on the tangential stiffness that half of them reach (mu p > kt stick)
    problem.form_residual(None, X, R)
    pressure = term._local["pressure"]
    pressing = comm.allgather(pressure[pressure > 0.0])
    if not uncapped:       # the cap between the two middle distinct pressures (no corner on its kink)
        levels = np.unique(np.concatenate(pressing))
        levels = levels[np.concatenate([[True], np.diff(levels) > 1e-6 * levels[1:]])]
        middle = levels[max(len(levels) // 2 - 1, 0):len(levels) // 2 + 1]
        term.kt = term.mu * float(np.sqrt(middle[0] * middle[-1])) / term.stick
    limit = np.maximum(term.stick, term.mu * pressure / term.kt)
    history = term._cand["history"]
    history[:] = (limit * rng.uniform(0.3, 1.7, limit.shape))[..., None] * rng.standard_normal(history.shape)
    term._history[term._candidates] = history     # as if carried in (the shell's step reads it)
    term._u = None
problem.form_residual(None, X, R)
problem.form_jacobian(None, X, solver.J, solver.J)
J = solver.whole_jacobian()          # (the free dofs' operator's values, assembled whole)
status = term._local["status"]
capped = (status == 1) & (term.mu * term._local["pressure"] > term.kt * term.stick)
states = comm.allreduce(np.array([np.sum(status == k) for k in range(3)] + [np.sum(capped)]))
pulling = comm.allreduce(int(np.sum((status == 1) & (term._local["pressure"] < 0.0))))
# the central differences, and the matrix-free product and diagonal (pimpm.implicit.shell)
relative, shell_error, diagonal_error = tangent_errors(sim.grid, problem, sim.terms, sim.config["solver"],
                                                       state, X, R, J, comm)
if comm.rank == 0:
    print(f"contact jacobian {dim}d {law} {geometry} {integrator} {kinematics} {shape} ranks {comm.size}: "
          f"relative error {relative:.3e}, "
          f"shell {shell_error:.3e} (diagonal {diagonal_error:.3e}), corners open/stick/slip {states[:3].tolist()} "
          f"(sticking with the capped stiffness {states[3]}, pulling {pulling})")
ok = relative < 1e-5 and shell_error < 1e-12 and states[1] + states[2] > 0
if law == "friction" and geometry == "box":   # stick (capped and not, as asked) and slip are checked
    ok = ok and states[1] > 0 and states[2] > 0 and (states[3] == 0 if uncapped else 0 < states[3] < states[1])
if law == "tied":              # tied corners that press and that pull are checked
    ok = ok and pulling > 0 and states[1] > pulling
sys.exit(0 if ok else 1)
