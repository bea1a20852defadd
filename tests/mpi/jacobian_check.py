"""Finite-difference check of the assembled Jacobian (run under mpiexec).

A small billet is compressed for two steps (so particles carry a non-trivial
F and stress), then for a random incremental displacement u the assembled
tangent is compared with central differences of the residual, column by
column, over the free dofs (prescribed rows/columns are eliminated by
design: their rows are the identity times a scale). Prints the relative
error; exits 1 if it exceeds the tolerance.
"""
import sys

import petsc4py
petsc4py.init(sys.argv[:1])
import numpy as np
from mpi4py import MPI

from pimpm.config import validate
from pimpm.simulation import Simulation
from pimpm.steps import implicit as implicit_step

from finite_differences import jacobian_error, operator_differences  # noqa: E402 (tests/mpi/)

integrator = sys.argv[1] if len(sys.argv) > 1 else "quasi_static"
three_d = len(sys.argv) > 2 and sys.argv[2] == "3d"
shape = sys.argv[3] if len(sys.argv) > 3 else "linear"
plastic = len(sys.argv) > 4 and sys.argv[4] in ("j2", "j2finite")
options = sys.argv[5:]          # a kinematics name, "momentum", "onecell", "fbar", "fbarnodes", "weak=F"
weak = [a for a in options if a.startswith("weak=")]
options = [a for a in options if not a.startswith("weak=")]
if weak:                                  # the fraction of pimpm.weak_nodes
    from petsc4py import PETSc
    PETSc.Options().setValue("pimpm_weak_node_fraction", weak[0].split("=")[1])
momentum = "momentum" in options
one_cell = "onecell" in options           # a column one cell wide in x (and y in 3D)
# every material averages its volume change per cell (fbar) or on the nodes (fbarnodes)
f_bar = "cells" if "fbar" in options else "nodes" if "fbarnodes" in options else False
kinematics = next((a for a in options if a not in ("momentum", "default", "onecell", "fbar", "fbarnodes")), None)
comm = MPI.COMM_WORLD
raw = {
    "grid": {"lower": [0.0, 0.0], "upper": [5.0, 4.0], "cells": [10, 8],
             "boundary": {"xmin": "roller", "ymin": "roller"}},
    "materials": {"m": {"model": "neo_hookean", "shear_modulus": 6.0e6, "bulk_modulus": 6.0e7,
                        "density": 10.0},
                  "c": {"model": "neo_hookean_compressible", "shear_modulus": 3.0e6,
                        "bulk_modulus": 2.0e7, "density": 5.0}},
    "bodies": [
        {"name": "a", "material": "m", "geometry": {"type": "box", "lower": [0, 0], "upper": [3, 2]},
         "particles_per_cell": 2, "velocity": [1.0, 2.0]},
        {"name": "b", "material": "c", "geometry": {"type": "box", "lower": [0, 2], "upper": [3, 3]},
         "particles_per_cell": 2},
        {"name": "platen", "rigid": True, "geometry": {"type": "box", "lower": [0, 3], "upper": [4, 4]},
         "particles_per_cell": 2, "velocity": [0.0, -10.0]},
    ],
    "time": {"integrator": integrator, "dt": 0.01, "end_time": 1.0, "gravity": [0.0, -981.0]},
    # the two set-up steps crush the 3D B-spline ball against the platen: on 1 rank
    # Newton needs 30 iterations at step 2, and round-off on 2 ranks can need more
    "solver": {"petsc": {"snes_max_it": 100}},
}
if three_d:
    raw["grid"] = {"lower": [0.0, 0.0, 0.0], "upper": [2.5, 2.0, 2.0], "cells": [5, 4, 4],
                   "boundary": {"xmin": "roller", "zmin": "roller"}}
    raw["bodies"] = [
        {"name": "a", "material": "m", "particles_per_cell": 2, "velocity": [1.0, 2.0, -1.0],
         "geometry": {"type": "box", "lower": [0, 0.5, 0], "upper": [1.5, 1.5, 1.0]}},
        {"name": "b", "material": "c", "particles_per_cell": 2,
         "geometry": {"type": "ball", "center": [1.0, 1.0, 1.25], "radius": 0.25}},
        {"name": "platen", "rigid": True, "particles_per_cell": 2, "velocity": [0.0, 0.0, -10.0],
         "geometry": {"type": "box", "lower": [0, 0, 1.5], "upper": [2.0, 2.0, 2.0]}},
    ]
    raw["time"]["gravity"] = [0.0, 0.0, -981.0]
if one_cell:   # GIMP and B-spline stencils are clipped on both sides of the one-cell axis
    raw["grid"] = {"lower": [0.0, 0.0], "upper": [0.5, 4.0], "cells": [1, 16],
                   "boundary": {"xmin": "roller", "ymin": "roller"}}
    raw["bodies"] = [
        {"name": "a", "material": "m", "geometry": {"type": "box", "lower": [0, 0], "upper": [0.5, 2]},
         "particles_per_cell": 2, "velocity": [0.5, 2.0]},
        {"name": "b", "material": "c", "geometry": {"type": "box", "lower": [0, 2], "upper": [0.5, 3]},
         "particles_per_cell": 2},
        {"name": "platen", "rigid": True, "particles_per_cell": 2, "velocity": [0.0, -10.0],
         "geometry": {"type": "box", "lower": [0, 3], "upper": [0.5, 3.5]}}]
    if three_d:
        raw["grid"] = {"lower": [0.0, 0.0, 0.0], "upper": [0.5, 0.5, 4.0], "cells": [1, 1, 16],
                       "boundary": {"xmin": "roller", "ymin": "roller", "zmin": "roller"}}
        for body, (z0, z1) in zip(raw["bodies"], ((0, 2), (2, 3), (3, 3.5))):
            body["geometry"] = {"type": "box", "lower": [0, 0, z0], "upper": [0.5, 0.5, z1]}
        raw["bodies"][0]["velocity"] = [0.5, -0.5, 2.0]
        raw["bodies"][2]["velocity"] = [0.0, 0.0, -10.0]
raw["grid"]["shape_functions"] = shape
if integrator == "hht":                  # Hilber-Hughes-Taylor: tangent (1 + alpha) K + M / (beta dt^2)
    raw["time"]["alpha"] = -0.2
if momentum:                             # Sulsky & Kaul 3.2.1: non-symmetric tangent K R
    raw["time"]["formulation"] = "momentum"
    raw["solver"]["preset"] = "gmres-gamg"
if kinematics:
    raw["kinematics"] = kinematics
if kinematics == "axisymmetric":        # r = x >= 0: keep particles off the axis cell boundary
    raw["grid"]["boundary"] = {"xmin": "roller", "ymin": "roller"}
if plastic:   # small-strain J2 with a low yield stress: particles yield in the first steps
    raw["materials"]["m"] = {"model": "j2_small_strain" if sys.argv[4] == "j2" else "j2_finite_strain",
                             "shear_modulus": 6.0e6, "bulk_modulus": 6.0e7,
                             "density": 10.0, "yield_stress": 2.0e5, "hardening_modulus": 1.0e6}
for material in raw["materials"].values():   # F-bar only where asked (J2 in 2D would average on the nodes)
    material["f_bar"] = f_bar
sim = Simulation(validate(raw), comm)
sim.advance(0.01)
sim.advance(0.01)
state, _ = implicit_step.prepare(sim, 0.01)
weak_pairs = comm.allreduce(int(sim.weak_pairs))
if plastic:
    n_plastic = comm.allreduce(int(np.sum(sim.particles["h_eq_plastic_strain"] > 0)))
    assert n_plastic > 10, n_plastic
solver = sim.solver
problem = sim.problem
solver.prepare(state)
rng = np.random.default_rng(1 + comm.rank)
n_local = len(state.mass)
u = np.where(state.fixed, state.fixed_value, 0.02 * rng.standard_normal(n_local))
X = solver.X.duplicate()
X.getArray()[:] = u
R = solver.R.duplicate()
problem.form_jacobian(None, X, solver.J, solver.J)
# The whole grid's matrix (with the direct solver on the free dofs Newton's
# matrix is pimpm.linear.FreeDofsOperator, which assembles only the free
# dofs' matrix; here the whole one is made from the same values)
J = solver.whole_jacobian()
# Symmetry of the assembled tangent, against what the problem declares
# (measured before the dense copy below, which converts J in place;
# a symmetric tangent is factorized by LDL^T: pimpm/solver.py).
from petsc4py import PETSc
difference, transposed = J.copy(), J.copy()
transposed.transpose()                     # in place (petsc4py transposes self when out is None)
difference.axpy(-1.0, transposed)
asymmetry = difference.norm(PETSc.NormType.INFINITY) / J.norm(PETSc.NormType.INFINITY)
difference.destroy()
transposed.destroy()
# The direct solver's matrix on the free dofs (pimpm.linear.FreeDofsKSP)
# against the free rows and columns of the whole matrix
free_matrix_difference = 0.0
if problem.free_matrix is not None:
    start_J = J.getOwnershipRange()[0]
    keep = PETSc.IS().createGeneral((start_J + np.flatnonzero(~state.fixed)).astype(PETSc.IntType), comm=comm)
    block = J.createSubMatrix(keep, keep)
    block.axpy(-1.0, problem.free_matrix, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
    free_matrix_difference = block.norm(PETSc.NormType.INFINITY) / J.norm(PETSc.NormType.INFINITY)
    block.destroy()
    keep.destroy()
# The COO assembly (pimpm/coo.py) against PETSc's MatSetValuesLocal path
coo_difference = 0.0
if problem.coo:
    from pimpm.implicit.problem import pattern_matrix
    J_csr = pattern_matrix(problem.grid, state.pattern, use_coo=False)
    problem.coo = False
    problem.form_jacobian(None, X, J_csr, J_csr)
    problem.coo = True
    J_csr.axpy(-1.0, J)
    coo_difference = J_csr.norm(PETSc.NormType.INFINITY) / J.norm(PETSc.NormType.INFINITY)
    J_csr.destroy()
free_local = ~state.fixed
err, scale, J_local = jacobian_error(problem, J, X, R, free_local, comm, h=1e-6)
n_free = comm.allreduce(int(free_local.sum()))
# Prescribed rows: identity times the scale, zero elsewhere (symmetric elimination).
fixed_rows = J_local[state.fixed]
diag = state.constraint_scale / problem.residual_scale     # the residual is dimensionless
diag_ok = comm.allreduce(bool(np.all(np.abs(fixed_rows.sum(axis=1) - diag) <= 1e-12 * diag)),
                         op=MPI.LAND)
# The matrix-free shell (analytic directional derivative) against the
# assembled matrix times random vectors.
from pimpm.implicit import StepProblem
from pimpm.implicit.formulation import make_formulation
from pimpm.solver import NewtonSolver
cfg_mf = dict(sim.config["solver"], preset="matrix-free")
shell_problem = StepProblem(sim.grid, problem.residual_scale, formulation=make_formulation(
    "momentum" if momentum else "velocity"), f_bar=sim.f_bar)
shell_solver = NewtonSolver(sim.grid, shell_problem, cfg_mf)
shell_problem.begin(state)
shell_problem.form_jacobian(None, X, shell_solver.J, shell_solver.J)
product, diagonal = operator_differences(J, shell_solver.J, X, rng)
# (with the momentum formulation the shell's diagonal is diag(K) diag(R), a preconditioner only)
shell_error = product if momentum else max(product, diagonal)
shell_solver.destroy()
# Newton's own operator (FreeDofsOperator with the free-dofs solver) against the whole matrix
operator_error = 0.0
free_dofs_operator = J != solver.J
if free_dofs_operator:
    operator_error = max(operator_differences(J, solver.J, X, rng, trials=2, transpose=True))
    J.destroy()

if comm.rank == 0:
    print(f"shell_product_relative_error={shell_error:.3e}")
    print(f"coo_used={problem.coo} coo_csr_difference={coo_difference:.3e}")
    print(f"free_matrix={problem.free_matrix is not None} free_matrix_difference={free_matrix_difference:.3e} "
          f"free_dofs_operator={free_dofs_operator} operator_difference={operator_error:.3e}")
    print(f"jacobian_check {integrator} dim={sim.dim} shape={shape} ranks={comm.size} free_dofs={n_free} "
          f"formulation={'momentum' if momentum else 'velocity'} "
          f"relative_error={err / scale:.3e} prescribed_rows_ok={diag_ok} "
          f"asymmetry={asymmetry:.3e} declared_symmetric={problem.symmetric} weak_pairs={weak_pairs} f_bar={f_bar}")
ok = (err / scale < 1e-6 and diag_ok and n_free > 20 and shell_error < 1e-8 and free_matrix_difference < 1e-14
      and operator_error < 1e-14)
sys.exit(0 if ok else 1)
