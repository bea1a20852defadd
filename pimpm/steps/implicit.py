"""One implicit MPM step (Guilkey & Weiss 2003, section 3.3), the sibling of
:mod:`pimpm.steps.explicit`: P2G and the Newton state on the reset grid
(steps 1-2, :func:`prepare`), Newton on the grid displacement (steps 3-6,
:class:`pimpm.solver.NewtonSolver` on :class:`pimpm.implicit.StepProblem`),
the particle update (step 7, :func:`update_particles`) and the migration
(step 8). The time scheme (inertia, predictor, particle update) is the
run's integrator (:mod:`pimpm.integrators`); the state the step reads and
changes is the :class:`pimpm.simulation.Simulation`'s."""
import time as wallclock

import numpy as np
from mpi4py import MPI

from .. import bc, fbar, weak_nodes
from ..errors import THICKNESS_FAILURE, StepFailed
from ..implicit import StepState, constraint_scale
from ..kernels import pattern as kernel_pattern
from ..kernels import stress as stress_kernels
from ..kernels import transfer as transfer_kernels
from ..materials import tensors
from ..stages import log_stage
from ..terms.base import moves_free_dofs
from ..terms.pairs import FieldContact
from ..transfer import grid_to_particle


def advance(sim, dt):
    """One implicit step of ``sim`` (a :class:`pimpm.simulation.Simulation`;
    G&W section 3.3, steps 1-8). Returns the step's data; raises
    StepFailed, leaving the particles as they were."""
    t0 = wallclock.perf_counter()
    with log_stage(sim.stages["P2G"]):
        state, cons = prepare(sim, dt)                   # steps 1-2
    try:
        u, info = sim.solver.solve(state, lambda: initial_guess(sim, state), sim.step_index + 1)   # steps 3-6
        if not info["converged"]:
            why = (THICKNESS_FAILURE if info["thickness_failed"] else
                   "a particle inverted (det F <= 0)" if info["inverted"] else info["reason_name"])
            raise StepFailed(f"Newton did not converge at step {sim.step_index + 1} "
                             f"(t = {sim.time + dt:.6g}, dt = {dt:.6g}): {why} after "
                             f"{info['newton_iterations']} iterations")
        with log_stage(sim.stages["G2P"]):
            forces, v_new, a_new = update_particles(sim, state, cons, u, dt)   # step 7
        mass = state.mass
    finally:
        # the step's particle state goes before the migration copies the
        # particles and the next step makes its own (also when it failed)
        sim.solver.end_step()
        del state
    with log_stage(sim.stages["Migration"]):
        sim.migrate()                                        # step 8
    history = info["residual_history"]
    return sim.finish_step(dt, t0, forces, sim.fields.grid_output(sim.grid, mass, v_new, a_new, u),
                            newton_iterations=info["newton_iterations"],
                            linear_iterations=info["linear_iterations"],
                            backtracks=info["backtracks"],
                            linear_fallbacks=info["linear_fallbacks"],
                            residual_initial=float(history[0]) if len(history) else 0.0,
                            residual_final=float(history[-1]) if len(history) else 0.0,
                            residual_history=history)



def prepare(sim, dt):
    """Steps 1-2: P2G and the Newton state on the reset grid. With several
    velocity fields (pimpm.fields) the unknowns are the field nodes'
    (``sim.solve_grid``) and the contact pairs' candidates are set up."""
    p, grid, fields = sim.particles, sim.grid, sim.fields
    solve_grid = sim.solve_grid
    grid_index, S, G = sim.footprint()
    sim.begin_terms(dt)
    sim.weak_pairs = 0
    if fields.single:               # (the weak-node folds are the grid's nodes': one field)
        extend_weak_nodes(sim, grid_index, S, G, dt)
    node_index = fields.node_index(grid_index, p["body"])        # the particles' field nodes
    mass, velocity, acceleration, fext = sim.nodal_state(node_index, S, sim.time + dt, solve_grid)
    # sum_p m_p |h G_ip|^2: zero only where no particle gradient reaches
    weight = np.empty(solve_grid.n_local_nodes)
    transfer_kernels.gradient_weight(node_index, G, grid.spacing, p["mass"], weight)
    stiffness_weight = solve_grid.sum_scalar_to_owned(weight)
    cons = bc.build_constraints(grid, sim.terms, sim.boundary, fields.total(grid, mass), dt, sim.mass_floor,
                                fields.total(grid, stiffness_weight), sim.time, sim.functions)
    fixed, fixed_value = cons.fixed, cons.value
    pairs = None
    if not fields.single:
        # a field node no particle of its field reaches is out of the system, like a massless node
        empty = (mass <= sim.mass_floor) & (stiffness_weight <= sim.mass_floor)
        fixed = fields.spread(grid, cons.fixed) | empty
        fixed_value = np.where(empty, 0.0, fields.spread(grid, cons.value))
        nodes, pair_fields, normals, gaps, shares = fields.candidates(sim, node_index, S, G,
                                                              np.where(mass > sim.mass_floor, mass, 0.0))
        for term in sim.terms:
            if isinstance(term, FieldContact):
                term.set_candidates(grid, nodes, pair_fields, normals, gaps, shares)
        local = grid.owned_local_nodes[nodes]
        pairs = local[:, None] * fields.count + pair_fields
    materials = sim.material_table()
    groups = materials.groups
    history = sim.particle_history()
    active = kernel_pattern.active_entries(S, G)
    volume_n = p["volume0"] * tensors.det(p["F"])
    cells = fbar.averaging(sim.f_bar_average, solve_grid, p["x"], materials, node_index, active, S, volume_n)
    state = StepState(
        dt=dt, integrator=sim.integrator, kinematics=sim.kinematics,
        node_index=node_index, S=S, G=G,
        F_n=p["F"], volume_n=volume_n,
        material_groups=groups, materials=materials, history_packed=materials.pack(history),
        active=active, pattern=sim.tangent_pattern(node_index, active, cells, pairs), cells=cells,
        mass=mass, velocity=velocity, acceleration=acceleration, external_force=fext,
        history=history, radius=sim.kinematics.radius(p["x"]),
        particle_mass=p["mass"], projection_floor=1e4 * sim.mass_floor,
        fixed=fixed, fixed_value=fixed_value,
        constraint_scale=constraint_scale(sim.materials, grid, sim.integrator, dt))
    if sim.integrator.needs_previous_force:     # HHT: Fint(t) - Fext(t) on the reset grid
        fext_now = sim.nodal_external_force(node_index, S, mass, sim.time, solve_grid)
        force = np.empty((solve_grid.n_local_nodes, sim.dim))
        radius = state.radius if state.radius is not None else np.zeros(0)
        stress_kernels.current_internal_force(sim.kinematics.kernel_code, tuple(range(sim.dim)),
                                              tuple(range(S.shape[1])), node_index, S, G, radius,
                                              p["stress"], p["F"], p["volume0"], force)
        state.previous_force = solve_grid.sum_to_owned(force) - fext_now
    return state, cons



def extend_weak_nodes(sim, node_index, S, G, dt):
    """Fold the free nodes the particles barely reach out of this step's
    footprint (pimpm.weak_nodes; in place): quasi-static steps, where
    no inertia holds such a node. Collective."""
    sim.weak_pairs = 0
    if sim.weak_fraction <= 0.0 or sim.shape.nodes_per_axis != 3 \
            or sim.integrator.name != "quasi_static":
        return
    p, grid = sim.particles, sim.grid
    area = p["volume0"] * np.linalg.det(p["F"][:, :sim.dim, :sim.dim])
    if sim.kinematics.name == "axisymmetric":                 # the in-plane area
        area = area / (2.0 * np.pi * p["x0"][:, 0])
    support = weak_nodes.support_fraction(grid, node_index, S, area)
    prescribed = np.zeros(grid.n_owned_nodes * sim.dim, dtype=bool)
    faces, _ = bc.face_constraints(grid, sim.boundary, sim.time, dt, sim.functions)
    prescribed[faces] = True
    held = np.zeros_like(prescribed)
    for term in sim.terms:
        dofs = term.prescribed()
        if dofs is not None:
            held |= dofs[0]
    nodes = weak_nodes.WeakNodes(grid, support, prescribed, sim.weak_fraction, held)
    sim.weak_pairs = weak_nodes.extend(sim.shape, grid, node_index, S, G, nodes)



def initial_guess(sim, state):
    """G&W step 2: the integrator's predictor with each term's correction
    (contact tools push the corners it drives into them back out:
    :meth:`pimpm.terms.NodalTerm.predict`), or without it if that inverts a
    particle, or u = 0 (corrected) if the predictor does; prescribed values
    on prescribed dofs. Where the predictor moves no free dof (a body at rest), the
    linearized response to the prescribed motion instead, if the solver
    makes one (``solver.linear_predictor``; not with contact tools, whose
    predictor is their own)."""
    guess = np.where(state.fixed, state.fixed_value, state.predictor())
    if (sim.solver.plan.linear_predictor and not any(term.couples_particles for term in sim.terms)
            and not moves_free_dofs(guess, state.fixed, sim.comm)):      # (the same test on every rank first)
        linear = sim.solver.linear_predictor(state, guess)
        if linear is not None and not sim.problem.inverts(state, linear):
            return linear
    corrected = _corrected(sim, state, guess)
    if corrected is not guess and not sim.problem.inverts(state, corrected):
        return corrected                     # (its residual is Newton's first: evaluated once)
    if sim.problem.inverts(state, guess):
        guess = np.where(state.fixed, state.fixed_value, 0.0)
        corrected = _corrected(sim, state, guess)
        if corrected is not guess and not sim.problem.inverts(state, corrected):
            return corrected
    return guess


def _corrected(sim, state, guess):
    """The Newton guess as the terms improve it (``guess`` itself if none does)."""
    for term in sim.terms:
        guess = term.predict(guess, sim.grid, state.fixed)
    return guess



def update_particles(sim, state, cons, u, dt):
    """G&W step 7: reactions, a_g(t+dt) from eq. 16, and the particle
    update. Raises StepFailed (particles untouched) if a particle would
    leave the grid or move farther than the Lagrangian limit."""
    grid, p = sim.grid, sim.particles
    u_local = sim.solve_grid.owned_to_local(u)
    forces = cons.reactions(sim.fields.total(grid, sim.problem.unconstrained_residual(u, u_local)), sim.comm,
                            sim.dim)
    # converged state (kinematics and stress of the residual just evaluated),
    # a_g(t+dt) from eq. 16, interpolate to particles
    converged = state.residual_evaluation
    F, sigma = converged.F, converged.sigma
    v_new, a_new = state.grid_kinematics(u)
    a_local = sim.solve_grid.owned_to_local(a_new)
    u_p = grid_to_particle(state.node_index, state.S, u_local)
    a_p = grid_to_particle(state.node_index, state.S, a_local)
    new_x = p["x"] + u_p
    increments, rigid_moves = sim.rigid_increments(dt)
    sim.check_stays_on_grid(new_x, sim.rigid["x"] + rigid_moves, dt)
    limit = sim.config["time"]["max_particle_displacement"]
    if limit is not None:
        moved = np.max(np.abs(u_p) / grid.spacing) if len(u_p) else 0.0
        moved = sim.comm.allreduce(float(moved), op=MPI.MAX)
        if moved > limit:
            raise StepFailed(f"a particle would move {moved:.3g} cells at step "
                             f"{sim.step_index + 1} (t = {sim.time + dt:.6g}, dt = {dt:.6g}); "
                             f"time.max_particle_displacement is {limit:g}")
    for term in sim.terms:                 # contact: their forces (once the step stands: they book dissipation)
        term.report(forces, sim.comm)
    sim.work.add(forces, increments, u_p, sim.particle_external_force(sim.time),
                  sim.particle_external_force(sim.time + dt))
    p["x"] = new_x
    sim.integrator.update_particles(p, u_p, a_p, dt)        # G&W step 7
    p["F"] = F
    p["stress"] = sigma
    committed = state.committed_history(converged.history)
    for name, values in committed.items():                   # commit the history
        p["h_" + name] = values
    sim.rigid["x"] = sim.rigid["x"] + rigid_moves
    for term in sim.terms:
        term.commit(p)
    return forces, v_new, a_new
