"""Nodal terms (pimpm/terms): the rigid bodies bonded to the material are
the first; the slot takes any term's force and derivative into Newton's
residual and tangent (assembled and matrix-free) without touching the
particle kernels. Checked with a nonlinear spring, defined here, that pulls
some nodes of a block: the assembled Jacobian equals finite differences of
the residual, the matrix-free product equals the assembled one, and Newton
converges to a state the spring holds."""
import numpy as np
import petsc4py
import pytest

petsc4py.init([])
from mpi4py import MPI  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from pimpm.config import validate  # noqa: E402
from pimpm.implicit import StepProblem  # noqa: E402
from pimpm.simulation import Simulation  # noqa: E402
from pimpm.solver import NewtonSolver  # noqa: E402
from pimpm.steps import implicit as implicit_step  # noqa: E402
from pimpm.terms import BondedRigidBody, NodalTerm  # noqa: E402


class CubicSpring(NodalTerm):
    """f = k (u - target)^3 on every dof of ``nodes`` (owned node indices),
    its derivative the diagonal blocks 3 k (u - target)^2."""

    name = "spring"

    def __init__(self, nodes, k, target, dim):
        self.nodes, self.k, self.target, self.dim = np.asarray(nodes), k, target, dim

    def add_residual(self, u_owned, u_local, residual, grid):
        u = u_owned.reshape(-1, self.dim)[self.nodes]
        residual.reshape(-1, self.dim)[self.nodes] += self.k * (u - self.target) ** 3

    def jacobian_blocks(self, u_owned):
        slope = 3.0 * self.k * (u_owned.reshape(-1, self.dim)[self.nodes] - self.target) ** 2
        return self.nodes, slope[:, :, None] * np.eye(self.dim)[None]


def block_config():
    return validate({
        "grid": {"lower": [0.0, 0.0], "upper": [3.0, 3.0], "cells": [6, 6], "shape_functions": "gimp",
                 "boundary": {"xmin": "roller", "ymin": "roller"}},
        "materials": {"m": {"model": "hencky", "youngs_modulus": 1.0e3, "poisson_ratio": 0.3, "density": 1.0}},
        "bodies": [{"name": "block", "material": "m", "particles_per_cell": 2,
                    "geometry": {"type": "box", "lower": [0.0, 0.0], "upper": [2.0, 2.0]}}],
        "time": {"integrator": "quasi_static", "dt": 1.0, "end_time": 1.0},
    })


def spring_nodes(sim):
    """Owned nodes on the block's top face (y = 2), away from the rollers."""
    ijk = sim.grid.owned_node_ijk
    return np.flatnonzero((ijk[:, 1] == 4) & (ijk[:, 0] >= 1) & (ijk[:, 0] <= 4))


def test_a_terms_force_and_derivative_join_the_tangent_assembled_and_matrix_free():
    sim = Simulation(block_config(), MPI.COMM_WORLD)
    spring = CubicSpring(spring_nodes(sim), 50.0, np.array([0.05, 0.1]), sim.dim)
    sim.terms.append(spring)
    sim.problem.terms.append(spring)
    state, _ = implicit_step.prepare(sim, 1.0)
    solver, problem = sim.solver, sim.problem
    solver.prepare(state)
    problem.begin(state)
    rng = np.random.default_rng(3)
    u = np.where(state.fixed, state.fixed_value, 0.01 * rng.standard_normal(len(state.mass)))
    X = solver.X.duplicate()
    X.getArray()[:] = u
    R = solver.R.duplicate()
    problem.form_residual(None, X, R)
    problem.form_jacobian(None, X, solver.J, solver.J)
    whole = solver.whole_jacobian()
    J = whole.convert("dense").getDenseArray().copy()
    free = np.flatnonzero(~state.fixed)
    h = 1e-6
    J_fd = np.zeros((len(u), len(free)))
    for column, j in enumerate(free):          # test code: a loop over columns is fine here
        cols = []
        for sign in (1.0, -1.0):
            Xp = X.copy()
            Xp.getArray()[j] += sign * h
            problem.form_residual(None, Xp, R)
            cols.append(R.getArray().copy())
        J_fd[:, column] = (cols[0] - cols[1]) / (2 * h)
    A, B = J[np.ix_(free, free)], J_fd[free]
    assert np.max(np.abs(A - B)) < 1e-6 * np.max(np.abs(B))
    # the spring's blocks are in it: without them the difference is their size
    spring_dofs = (spring.nodes[:, None] * sim.dim + np.arange(sim.dim)).reshape(-1)
    assert np.all(np.isin(spring_dofs, free))
    slope = 3.0 * 50.0 * (u.reshape(-1, 2)[spring.nodes] - spring.target) ** 2 / problem.residual_scale
    assert np.min(slope) > 1e3 * np.max(np.abs(A - B))
    # the matrix-free product and diagonal, with the spring
    shell_problem = StepProblem(sim.grid, problem.residual_scale, terms=[spring])
    shell_solver = NewtonSolver(sim.grid, shell_problem, dict(sim.config["solver"], preset="matrix-free"))
    shell_problem.begin(state)
    shell_problem.form_jacobian(None, X, shell_solver.J, shell_solver.J)
    for _ in range(3):
        v = X.duplicate()
        v.getArray()[:] = rng.standard_normal(len(u))
        y, y_shell = X.duplicate(), X.duplicate()
        solver.J.mult(v, y)
        shell_solver.J.mult(v, y_shell)
        assert np.max(np.abs(y_shell.getArray() - y.getArray())) < 1e-10 * np.max(np.abs(y.getArray()))
    d, d_shell = X.duplicate(), X.duplicate()
    solver.J.getDiagonal(d)
    shell_solver.J.getDiagonal(d_shell)
    assert np.allclose(d_shell.getArray(), d.getArray(), rtol=1e-12, atol=0)
    shell_solver.destroy()
    sim.solver.destroy()


def test_newton_converges_to_a_state_the_spring_holds():
    """The spring pulls the top face up and right; the converged step's
    reaction balance: the spring's force on the nodes equals the material's
    internal force there (the residual at the solution is zero)."""
    sim = Simulation(block_config(), MPI.COMM_WORLD)
    spring = CubicSpring(spring_nodes(sim), 5.0e4, np.array([0.05, 0.1]), sim.dim)
    sim.terms.append(spring)
    sim.problem.terms.append(spring)
    info = sim.advance(1.0)
    assert info["newton_iterations"] <= 12 and info["residual_final"] < 1e-8
    top = sim.particles["x"][:, 1] > 1.5
    moved = sim.particles["x"][top] - sim.particles["x0"][top]
    assert np.all(moved[:, 1] > 0.01)            # pulled up, towards the target 0.1
    sim.solver.destroy()


def test_rigid_bodies_are_terms_and_prescribe_the_nodes_their_particles_touch():
    sim = Simulation(validate({
        "grid": {"lower": [0.0, 0.0], "upper": [3.0, 3.0], "cells": [6, 6], "shape_functions": "linear",
                 "boundary": {"xmin": "roller", "ymin": "roller"}},
        "materials": {"m": {"model": "neo_hookean", "youngs_modulus": 1.0e3, "poisson_ratio": 0.3, "density": 1.0}},
        "bodies": [{"name": "block", "material": "m", "particles_per_cell": 2,
                    "geometry": {"type": "box", "lower": [0.0, 0.0], "upper": [2.0, 2.0]}},
                   {"name": "platen", "rigid": True, "particles_per_cell": 2, "velocity": [0.0, -0.1],
                    "constrain": ["y"], "geometry": {"type": "box", "lower": [0.0, 2.0], "upper": [2.5, 2.5]}}],
        "time": {"integrator": "quasi_static", "dt": 1.0, "end_time": 1.0},
    }), MPI.COMM_WORLD)
    assert [type(t) for t in sim.terms] == [BondedRigidBody] and sim.rigid_bodies == sim.terms
    sim.begin_terms(1.0)
    mask, values = sim.terms[0].prescribed()
    ijk = np.repeat(sim.grid.owned_node_ijk, 2, axis=0)
    component = np.tile([0, 1], len(sim.grid.owned_node_ijk))
    # the platen's particles lie in the cells between y = 2 and 2.5 and x up to 2.5:
    # nodes of rows 4 and 5, columns 0-5, y component only
    expected = (component == 1) & (ijk[:, 1] >= 4) & (ijk[:, 1] <= 5) & (ijk[:, 0] <= 5)
    assert np.array_equal(mask, expected)
    assert np.allclose(values[mask], -0.1) and np.all(values[~mask] == 0.0)
    increments, moves = sim.rigid_increments(1.0)
    assert np.allclose(increments["platen"], [0.0, -0.1]) and np.allclose(moves, [0.0, -0.1])
    sim.solver.destroy()


class ConstantForce(NodalTerm):
    """A constant force on every owned dof (explicit step)."""

    name = "push"

    def __init__(self, force):
        self.force = np.asarray(force, dtype=float)

    def add_explicit_force(self, velocity, dt, force, mass=None):
        force.reshape(-1, len(self.force))[:] += self.force


def test_a_terms_force_joins_the_explicit_grid_update():
    """A free block (no faces, no gravity) and a force f on every node: the
    particles' momentum grows by f per node with mass over the step (the
    grid update of MPM intro eq. 1 on nodes with mass)."""
    config = block_config()
    config["grid"]["boundary"] = {face: "free" for face in config["grid"]["boundary"]}
    config["time"] = dict(config["time"], integrator="explicit", dt=None)
    sim = Simulation(config, MPI.COMM_WORLD)
    push = ConstantForce([0.0, 2.0])
    sim.terms.append(push)
    p = sim.particles
    momentum0 = np.sum(p["mass"][:, None] * p["v"], axis=0)
    dt = sim.stable_time_step()
    node_index, S, _ = sim.footprint()
    mass = sim.nodal_state(node_index, S)[0].reshape(-1, 2)[:, 0]
    with_mass = int(np.count_nonzero(mass > sim.mass_floor))
    sim.advance(dt)
    momentum = np.sum(p["mass"][:, None] * sim.particles["v"], axis=0)
    assert with_mass > 20
    assert np.allclose(momentum - momentum0, [0.0, 2.0 * with_mass * dt], rtol=1e-12, atol=1e-15)
