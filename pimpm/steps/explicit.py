"""One explicit MPM step (MPM introduction, eq. 1-10), the baseline implicit
MPM must beat: update-stress-last (``usl``, the intro's eq. 5 with the new
grid velocity), its modified form (``musl``, the default; Sulsky & Kaul's
momentum formulation made explicit) or update-stress-first (``usf``). It
shares the grid, transfers, kinematics, materials, bodies and output of the
implicit step; every per-particle loop is a compiled kernel: the shape
functions (:mod:`pimpm.kernels.transfer`), the stress update
(:func:`pimpm.kernels.particle_step.evaluate_particles`, the same kinematics
and material points as Newton's iterates) and the internal force
(:func:`pimpm.kernels.stress.current_internal_force`)."""
import time as wallclock
from functools import cached_property

import numpy as np

from .. import bc, fbar
from ..errors import THICKNESS_FAILURE, StepFailed
from ..kernels import particle_step
from ..kernels import pattern as kernel_pattern
from ..kernels.stress import current_internal_force, explicit_g2p, explicit_p2g
from ..stages import log_stage

_NO_RADIUS = np.zeros(0)
#: the explicit step sorts particles by footprint only for locality in memory:
#: not after every step, only once more than this fraction is out of order
SORT_DISORDER = 0.05


class ParticleStress:
    """The stress update of an explicit step on this step's footprint:
    F(t+dt) = (1 + dt grad v) F(t) (MPM intro eq. 13-14; the axisymmetric hoop
    stretch 1 + dt v_r / r) and every particle's stress and history, in one
    compiled loop; the internal force of the particles' current stresses."""

    def __init__(self, sim, node_index, S, G):
        """``node_index``: the particles' field nodes (pimpm.fields)."""
        p = sim.particles
        self.sim = sim
        self.node_index, self.S, self.G = node_index, S, G
        self.n_nodes = sim.fields.local_nodes(sim.grid)
        self.active = np.ones(S.shape, dtype=np.bool_)     # footprint entries outside the body add zero
        self.table = sim.material_table()
        self.history = sim.particle_history()
        radius = sim.kinematics.radius(p["x"])
        self.radius = _NO_RADIUS if radius is None else radius
        self.axes = tuple(range(sim.dim))
        self.footprint = tuple(range(S.shape[1]))
        # F-bar: the cells at the step's start, and the volumes their averages weigh
        self.volume = p["volume0"] * np.linalg.det(p["F"]) if sim.f_bar else p["volume0"]
        self.cells = fbar.averaging(sim.f_bar_average, sim.solve_grid, p["x"], self.table, node_index,
                                    self.active, S, self.volume)

    def particle_to_grid(self):
        """Ghosted-local field nodes (n_nodes, 1 + 2 dim): mass, momentum and
        the internal force of the current stresses
        (:func:`pimpm.kernels.stress.explicit_p2g`)."""
        sim, p = self.sim, self.sim.particles
        nodal = np.empty((self.n_nodes, 1 + 2 * sim.dim))
        explicit_p2g(sim.kinematics.kernel_code, self.axes, self.footprint, self.node_index, self.S, self.G,
                     self.radius, p["mass"], p["v"], p["stress"], p["F"], p["volume0"], nodal)
        return nodal

    def grid_to_particle(self, a_local, v_local, dt):
        """The particles' new velocities and positions for the ghosted-local
        grid velocity change rate ``a_local`` and new velocity ``v_local``,
        and their new momenta on the ghosted-local nodes."""
        sim, p = self.sim, self.sim.particles
        n, dim = len(p), sim.dim
        new_v, new_x = np.empty((n, dim)), np.empty((n, dim))
        momentum = np.empty((self.n_nodes, dim))
        explicit_g2p(self.axes, self.footprint, self.node_index, self.S, dt, np.hstack([a_local, v_local]),
                     p["mass"], p["v"], p["x"], new_v, new_x, momentum)
        return new_v, new_x, momentum

    def internal_force(self):
        """Fint (MPM intro eq. 6) of the particles' current stresses, summed
        to owned dofs. Collective."""
        sim, p = self.sim, self.sim.particles
        force = np.empty((self.n_nodes, sim.dim))
        current_internal_force(sim.kinematics.kernel_code, self.axes, self.footprint, self.node_index,
                               self.S, self.G, self.radius, p["stress"], p["F"], p["volume0"], force)
        return sim.solve_grid.sum_to_owned(force)

    def evaluate(self, v_local, dt):
        """Deform the particles with the ghosted-local grid velocity
        ``v_local`` over dt and update their stresses, kept aside until
        :meth:`commit`. Returns this rank's numbers of particles that would
        invert and whose plane-stress thickness did not converge (local: the
        caller reduces them with its other checks)."""
        sim, p, table = self.sim, self.sim.particles, self.table
        n, dim = len(p), sim.dim
        F_inc, F, sigma = np.empty((n, 3, 3)), np.empty((n, 3, 3)), np.empty((n, 3, 3))
        packed = table.pack(self.history)
        h_out = np.empty_like(packed)
        u_local = dt * v_local
        cells, jbar = self.cells, np.zeros(0)
        if cells.kind == "nodes":            # the increments first, then their average on the nodes (collective)
            jbar = cells.increments_and_jbar(sim.kinematics.kernel_code, u_local, self.node_index, self.active,
                                             self.S, self.G, self.radius, self.volume, F_inc)
        inverted, unconverged = particle_step.evaluate_particles(
            sim.kinematics.kernel_code, self.axes, self.footprint, u_local, self.node_index,
            self.active, self.S, self.G, self.radius, p["F"], self.volume, table.only_model, table.models,
            table.params, table.material_of, packed, False, False, cells.cell,
            0 if cells.kind == "nodes" else cells.count,
            F_inc, F, sigma, h_out, np.empty((0, dim)), np.empty((0,) + (dim,) * 4),
            np.empty((0, 2 * dim * dim + 1)), np.empty((0, 3, 3)), np.empty(0), jbar, table.f_bar_alpha)
        self.pending = F, sigma, h_out
        return inverted, unconverged

    def commit(self):
        """The evaluated deformation, stresses and history become the particles'."""
        p = self.sim.particles
        F, sigma, h_out = self.pending
        p["F"], p["stress"] = F, sigma
        self.history = self.table.unpack(h_out, self.history)
        for name, values in self.history.items():
            p["h_" + name] = values


class ExplicitFootprint:
    """What a term sees of the explicit step's footprint (the implicit step
    hands it its StepState): nodes, weights, gradients and the entries with
    a weight or a gradient."""

    def __init__(self, node_index, S, G):
        self.node_index, self.S, self.G = node_index, S, G

    @cached_property
    def active(self):
        """Made when a term asks (steps without contact tools never do)."""
        return kernel_pattern.active_entries(self.S, self.G)


def _check(sim, dt, saved, inverted=0, unconverged=0, outside=False):
    """StepFailed on every rank (the fields in ``saved`` restored) if, on any
    rank, a particle would invert, its thickness did not converge or it
    would leave the grid. One reduction for all three. Collective."""
    inverted, unconverged, outside = sim.comm.allreduce(np.array([inverted, unconverged, int(outside)]))
    if not (inverted or unconverged or outside):
        return
    sim.particles.fields.update(saved)
    where = f"at step {sim.step_index + 1} (t = {sim.time + dt:.6g}"
    if outside:
        raise StepFailed(f"particles would leave the grid {where}); enlarge grid.lower/upper")
    why = THICKNESS_FAILURE if unconverged else "a particle inverted"
    raise StepFailed(f"{why} {where}, dt = {dt:.6g})")


def advance(sim, dt):
    """One explicit step of ``sim`` (a :class:`pimpm.simulation.Simulation`).
    Returns the step's data; raises StepFailed, leaving the particles as they
    were. With several velocity fields (:mod:`pimpm.fields`) every nodal
    array holds each field's dofs side by side, and the contact pairs' law
    acts on the fields' new velocities (Bardenhagen et al. 2000)."""
    t0 = wallclock.perf_counter()
    comm, grid, p, dim = sim.comm, sim.grid, sim.particles, sim.dim
    fields = sim.fields
    with log_stage(sim.stages["P2G"]):
        grid_index, S, G = sim.footprint()
        node_index = fields.node_index(grid_index, p["body"])              # the particles' field nodes
        stress = ParticleStress(sim, node_index, S, G)
        nodal = fields.sum_to_owned(grid, stress.particle_to_grid())      # eq. 2-3, 6: one exchange
        mass = np.repeat(nodal[:, 0], dim)                                 # per (field) dof
        has_mass = mass > sim.mass_floor
        safe_mass = np.where(has_mass, mass, 1.0)
        velocity = np.where(has_mass, nodal[:, 1:1 + dim].reshape(-1) / safe_mass, 0.0)
        fext = sim.nodal_external_force(node_index, S, mass, sim.time, sim.solve_grid)      # eq. 4
        sim.begin_terms(dt)
        footprint = ExplicitFootprint(grid_index, S, G)
        for term in sim.terms:                # contact tools: their corners on this footprint
            term.begin_newton(footprint)
        cons = bc.build_constraints(grid, sim.terms, sim.boundary, fields.total(grid, mass), dt,
                                    sim.mass_floor, time=sim.time, functions=sim.functions)
        fixed, fixed_velocity = fields.spread(grid, cons.fixed), fields.spread(grid, cons.value / dt)
        if not fields.single:
            # the pairs' law on the interpolated velocities too (Bardenhagen et al.
            # 2000): the FLIP update then adds to the particles only what the forces
            # and the new velocities' contact change, as with one field
            fields.find_contacts(sim, node_index, S, G, np.where(has_mass, mass, 0.0))
            velocity = np.where(has_mass, fields.contact(sim, velocity, dt), 0.0)
        velocity = np.where(fixed, fixed_velocity, velocity)
        update = sim.config["time"]["stress_update"]
        saved = {k: p[k] for k in ["F", "stress"] + ["h_" + n for n in sim.history_fields()]}
        if update == "usf":                                   # stress from the velocity at t
            _check(sim, dt, saved, *stress.evaluate(fields.to_local(grid, velocity, dim), dt))
            stress.commit()
            fint = stress.internal_force()
        else:
            fint = nodal[:, 1 + dim:].reshape(-1)
    with log_stage(sim.stages["G2P"]):
        net = fext - fint
        for term in sim.terms:                                                   # pimpm.terms
            term.add_explicit_force(velocity, dt, net, mass=np.where(has_mass, mass, 0.0))
        acceleration = np.where(has_mass, net / safe_mass, 0.0)                  # eq. 1
        v_new = velocity + acceleration * dt                                     # eq. 7
        v_new = np.where(fixed, fixed_velocity, v_new)
        if not fields.single:                 # the pairs' contact law on the new velocities
            v_new = fields.contact(sim, v_new, dt, report=True)
            v_new = np.where(fixed, fixed_velocity, np.where(has_mass, v_new, 0.0))
            acceleration = np.where(has_mass, (v_new - velocity) / dt, 0.0)
        acceleration = np.where(fixed, 0.0, acceleration)
        output = fields.grid_output(grid, mass, v_new, acceleration, v_new * dt)
        # the force the bodies apply
        forces = cons.reactions(fields.total(grid, mass * (v_new - velocity) / dt - fext + fint), comm, dim)
        for term in sim.terms:                 # contact tools: where the step took them, their force
            term.settle(grid.owned_to_local(output["displacement_increment"]))
            term.report(forces, comm, explicit=True)
        v_local = fields.to_local(grid, v_new, dim)
        new_v, new_x, momentum = stress.grid_to_particle(fields.to_local(grid, (v_new - velocity) / dt, dim),
                                                         v_local, dt)             # eq. 9-10
        increments, rigid_moves = sim.rigid_increments(dt)
        new_rigid_x = sim.rigid["x"] + rigid_moves
        outside = not (grid.contains(new_x) and grid.contains(new_rigid_x))
        failures = (0, 0)
        if update == "usl":                       # stress from the new grid velocity
            failures = stress.evaluate(v_local, dt)
        elif update == "musl":
            # modified USL: the velocity gradient comes from the updated
            # particle momenta mapped back to the grid, which keeps nodes
            # with tiny mass (body edges) from driving huge strain rates
            remapped = np.where(has_mass, fields.sum_to_owned(grid, momentum).reshape(-1) / safe_mass, 0.0)
            if not fields.single:
                remapped = fields.contact(sim, remapped, dt)
            remapped = np.where(fixed, fixed_velocity, remapped)
            failures = stress.evaluate(fields.to_local(grid, remapped, dim), dt)
        _check(sim, dt, saved, *failures, outside=outside)       # one reduction for the three checks
        if update != "usf":
            stress.commit()
        fields.commit()
        sim.work.add(forces, increments, new_x - p["x"], sim.particle_external_force(sim.time),
                     sim.particle_external_force(sim.time))
        for term in sim.terms:
            term.commit(p)
        p["v"], p["x"] = new_v, new_x
        p["a"] = np.zeros_like(new_v)
        sim.rigid["x"] = new_rigid_x
    with log_stage(sim.stages["Migration"]):
        sim.migrate(disorder=SORT_DISORDER, lazy=True)
    return sim.finish_step(dt, t0, forces, output, explicit=True)
