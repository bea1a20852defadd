"""Explicit MPM (MPM introduction, eq. 1-10), the baseline implicit MPM must
beat: update-stress-last (``usl``, the intro's eq. 5 with the new grid
velocity), its modified form (``musl``, the default; Sulsky & Kaul's
momentum formulation made explicit) or update-stress-first (``usf``), with
the CFL step. It shares the grid, transfers, kinematics, materials, bodies
and output of the implicit steps, and owns its whole step."""
import time as wallclock

import numpy as np
from mpi4py import MPI

from .. import bc, kinematics
from ..errors import StepFailed
from ..materials import tensors
from ..materials.update import update_stress
from ..stages import log_stage
from ..transfer import gradient_at_particles, grid_to_particle, particle_to_grid, scatter


def stable_time_step(particles, material_groups, grid, cfl, comm):
    """CFL limit dt = cfl * h / max_p (c + |v_p|) (MPM intro), with c the
    dilatational wave speed of each particle's material. Collective."""
    h = float(np.min(grid.spacing))
    speed = 0.0
    for material, index in material_groups:
        if len(index):
            v = np.sqrt(np.max(np.sum(particles["v"][index] ** 2, axis=1)))
            speed = max(speed, material.wave_speed() + v)
    speed = comm.allreduce(speed, op=MPI.MAX)
    return cfl * h / speed


class Explicit:
    name = "explicit"
    explicit = True
    dynamic = True
    parameters = {}

    def check_time_step(self, sim):
        """A fixed ``time.dt`` above the stability limit is refused; returns
        the message or None. Collective."""
        time = sim.config["time"]
        if time["dt"] is not None:
            limit = sim.stable_time_step() / time["cfl"]
            if time["dt"] > limit:
                return (f"time.dt = {time['dt']!r}: expected at most the explicit stability limit "
                        f"h / (c + |v|) = {limit:.6g} (omit time.dt for an automatic "
                        f"step of time.cfl = {time['cfl']} times it)")
        return None

    def update_stress(self, sim, node_index, S, G, v_local, dt):
        """F(t+dt) = (1 + dt grad v) F(t) (MPM intro eq. 13-14) and the
        stress of every particle; False (nothing changed) if a particle would
        invert."""
        p = sim.particles
        L = gradient_at_particles(node_index, G, v_local)
        F_inc = sim.kinematics.deformation_increment(
            dt * L, sim.kinematics.radius(p["x"]), lambda: dt * grid_to_particle(node_index, S, v_local))
        F = np.matmul(F_inc, p["F"])
        if kinematics.inverted_count(F_inc):
            return False
        sigma, _, new_history = update_stress(sim.material_groups(), sim.kinematics, F,
                                              sim.particle_history(), False)
        p["F"], p["stress"] = F, sigma
        for name, values in new_history.items():
            p["h_" + name] = values
        return True

    def _stress(self, sim, node_index, S, G, v_local, dt, saved):
        ok = self.update_stress(sim, node_index, S, G, v_local, dt)
        if sim.comm.allreduce(int(not ok)):
            sim.particles.fields.update(saved)
            raise StepFailed(f"a particle inverted at step {sim.step_index + 1} "
                              f"(t = {sim.time + dt:.6g}, dt = {dt:.6g})")

    def advance(self, sim, dt):
        """One explicit step. Raises StepFailed, leaving the particles as they were."""
        t0 = wallclock.perf_counter()
        comm, grid, p, dim = sim.comm, sim.grid, sim.particles, sim.dim
        with log_stage(sim.stages["P2G"]):
            node_index, S, G = sim.footprint()
            mass, velocity, _, fext = sim.nodal_state(node_index, S, sim.time)   # eq. 2-4
            cons = bc.build_constraints(grid, sim.shape, sim.rigid, sim.rigid_bodies,
                                        sim.boundary, mass, dt, sim.mass_floor,
                                        time=sim.time, functions=sim.functions)
            velocity = np.where(cons.fixed, cons.value / dt, velocity)
            update = sim.config["time"]["stress_update"]
            saved = {k: p[k] for k in ["F", "stress"] + ["h_" + n for n in sim.history_fields()]}
            if update == "usf":                                   # stress from the velocity at t
                self._stress(sim, node_index, S, G, grid.owned_to_local(velocity), dt, saved)
            # current volume: full det F (thickness in plane stress, hoop in axisymmetry)
            volume = p["volume0"] * tensors.det(p["F"]) if len(p["F"]) else np.zeros(0)
            pairs = sim.kinematics.internal_force_pairs(p["stress"], None, G, S, volume,
                                                        sim.kinematics.radius(p["x"]))   # eq. 6
            fint = grid.sum_to_owned(scatter(node_index, pairs, grid.n_local_nodes))
        with log_stage(sim.stages["G2P"]):
            has_mass = mass > sim.mass_floor
            acceleration = np.where(has_mass, (fext - fint) / np.where(has_mass, mass, 1.0), 0.0)  # eq. 1
            v_new = velocity + acceleration * dt                                     # eq. 7
            v_new = np.where(cons.fixed, cons.value / dt, v_new)
            acceleration = np.where(cons.fixed, 0.0, acceleration)
            # the force the bodies apply
            forces = cons.reactions(mass * (v_new - velocity) / dt - fext + fint, comm, dim)
            a_local = grid.owned_to_local((v_new - velocity) / dt)
            v_local = grid.owned_to_local(v_new)
            new_v = p["v"] + dt * grid_to_particle(node_index, S, a_local)             # eq. 9
            new_x = p["x"] + dt * grid_to_particle(node_index, S, v_local)             # eq. 10
            increments, rigid_moves = sim.rigid_increments(dt)
            new_rigid_x = sim.rigid["x"] + rigid_moves
            try:
                sim.check_stays_on_grid(new_x, new_rigid_x, dt)
            except StepFailed:
                p.fields.update(saved)
                raise
            if update == "usl":                       # stress from the new grid velocity
                self._stress(sim, node_index, S, G, v_local, dt, saved)
            elif update == "musl":
                # modified USL: the velocity gradient comes from the updated
                # particle momenta mapped back to the grid, which keeps nodes
                # with tiny mass (body edges) from driving huge strain rates
                m = p["mass"]
                momentum = grid.sum_to_owned(particle_to_grid(node_index, S, m[:, None] * new_v,
                                                              grid.n_local_nodes))
                remapped = np.where(has_mass, momentum / np.where(has_mass, mass, 1.0), 0.0)
                remapped = np.where(cons.fixed, cons.value / dt, remapped)
                self._stress(sim, node_index, S, G, grid.owned_to_local(remapped), dt, saved)
            sim.work.add(forces, increments, new_x - p["x"], sim.particle_external_force(sim.time),
                         sim.particle_external_force(sim.time))
            p["v"], p["x"] = new_v, new_x
            p["a"] = np.zeros_like(new_v)
            sim.rigid["x"] = new_rigid_x
        with log_stage(sim.stages["Migration"]):
            sim.migrate()
        return sim.finish_step(dt, t0, forces, {"mass": mass, "velocity": v_new,
                                                "acceleration": acceleration,
                                                "displacement_increment": v_new * dt},
                               explicit=True)
