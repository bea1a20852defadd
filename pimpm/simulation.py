"""The simulation: particles on a DMDA grid advanced by the implicit MPM step
of Guilkey & Weiss (2003), section 3.3. Steps 1-8 of their algorithm are
marked in :meth:`Simulation.advance`.
"""
import time as wallclock

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from . import bodies as bc
from .grid import Grid
from .implicit import ImplicitSolver, StepState, material_update
from .materials import make_material, von_mises
from .particles import ParticleSet, migrate, seed_body
from .shape import make_shape
from .stages import log_stage, log_stages
from . import smallmat
from .assembly import deformation_increment, hoop_force_pairs, internal_force_pairs
from .transfer import gradient_at_particles, grid_to_particle, particle_to_grid, scatter


class SetupError(Exception):
    """The problem cannot be set up as given (bad solver option value, a body
    that gets no particles): reported like bad input, before any output."""


class StepFailed(Exception):
    """A step could not be completed (Newton diverged, a particle inverted or
    left the grid). The state of the simulation is the last good step."""


#: program defaults for PETSc options (the preset, then the YAML, then the command line override)
DEFAULT_SOLVER_OPTIONS = {
    "snes_type": "newtonls",
    "snes_linesearch_type": "bt",
    "snes_rtol": "1e-10",
    "snes_atol": "1e-12",        # the residual is dimensionless (Sulsky & Kaul 3.2.2)
    "snes_max_it": "30",
}


def diagnose_solver_options(config, err):
    """A one-line message for a PETSc error raised while the solver read its
    options: names the offending ``*_type`` option when it can find it."""
    if isinstance(err, ValueError):
        return str(err)
    db = PETSc.Options()
    yaml_options = config["solver"]["petsc"]
    candidates = dict(yaml_options)
    candidates.update({k: db.getString(k) for k in ("ksp_type", "pc_type", "snes_type")
                       if db.hasName(k)})
    makers = {"ksp_type": PETSc.KSP, "pc_type": PETSc.PC, "snes_type": PETSc.SNES}
    for name, value in candidates.items():
        kind = next((k for k in makers if name == k or name.endswith("_" + k)), None)
        if kind is None:
            continue
        obj = makers[kind]().create(comm=PETSc.COMM_SELF)
        try:
            obj.setType(value)
        except PETSc.Error:
            where = f"solver.petsc.{name}" if yaml_options.get(name) == value else f"-{name}"
            return f"{where} = {value!r}: expected a {kind.split('_')[0].upper()} type known to PETSc"
        finally:
            obj.destroy()
    return (f"PETSc rejected the solver options (error code {getattr(err, 'ierr', err)}): "
            f"expected valid option values in solver.petsc and on the command line")


def residual_scale(config, materials):
    """Sulsky & Kaul 3.2.2: the largest Young's modulus times h^(dim-1) (a
    force per unit thickness in 2D, a force in 3D) makes the residual
    dimensionless."""
    dim = config["dim"]
    h = float(np.min((np.asarray(config["grid"]["upper"]) - np.asarray(config["grid"]["lower"]))
                     / np.asarray(config["grid"]["cells"])))
    young = max(9.0 * m.bulk_modulus * m.shear_modulus / (3.0 * m.bulk_modulus + m.shear_modulus)
                for m in materials)
    return young * h ** (dim - 1)


class Simulation:
    def __init__(self, config, comm=MPI.COMM_WORLD):
        self.config = config
        self.comm = comm
        self.dim = dim = config["dim"]
        g = config["grid"]
        self.shape = make_shape(g["shape_functions"], dim)
        self.grid = Grid(comm, g["lower"], g["upper"], g["cells"],
                         stencil_width=self.shape.stencil_width)
        self.boundary = {face: kind for face, kind in g.get("boundary", {}).items()}
        self.material_names = list(config["materials"])
        self.materials = [make_material(config["materials"][k]) for k in self.material_names]
        self.integrator = config["time"]["integrator"]
        self.plane_stress = config.get("kinematics") == "plane_stress"
        self.axisymmetric = config.get("kinematics") == "axisymmetric"
        self.dynamic = self.integrator in ("newmark", "backward_euler")
        self.gravity = np.asarray(config["time"].get("gravity", [0.0] * dim), dtype=float)
        self.body_names = [b["name"] for b in config["bodies"]]
        self.rigid_bodies = []          # (index, name, velocity, axes)
        self.body_material = {}         # deformable body index -> material index
        for i, b in enumerate(config["bodies"]):
            if b.get("rigid", False):
                axes = ["xyz".index(a) for a in b.get("constrain", "xyz"[:dim])]
                self.rigid_bodies.append((i, b["name"], np.asarray(b["velocity"], float), axes))
            else:
                self.body_material[i] = self.material_names.index(b["material"])
        self._seed()
        self._check_every_body_has_particles()
        self.time = 0.0
        self.external_work = 0.0        # work of rigid bodies and gravity on the material so far
        self._body_forces = {}          # forces of the last step (trapezoidal work increments)
        self.step_index = 0
        self.count0 = self.particles.global_count(comm)
        self.rigid_count0 = self.rigid.global_count(comm)
        self.mass0 = float(self.particles.global_sum(comm, "mass"))
        largest = float(np.max(self.particles["mass"])) if len(self.particles) else 0.0
        self.mass_floor = 1e-10 * comm.allreduce(largest, op=MPI.MAX)
        self.stages = log_stages()
        self.explicit = self.integrator == "explicit"
        self.solver = None
        self.last_grid = None
        if self.explicit:
            self._check_explicit_time_step()
            return
        try:
            self.solver = ImplicitSolver(self.grid, config["solver"], DEFAULT_SOLVER_OPTIONS,
                                         residual_scale(config, self.materials), self.stages,
                                         formulation=config["time"]["formulation"])
        except (PETSc.Error, ValueError) as err:
            raise SetupError(diagnose_solver_options(config, err)) from None

    def _check_every_body_has_particles(self):
        counts = np.zeros(len(self.config["bodies"]), dtype=np.int64)
        for pset in (self.particles, self.rigid):
            counts += np.bincount(pset["body"], minlength=len(counts)).astype(np.int64)
        counts = self.comm.allreduce(counts)
        for i, (b, n) in enumerate(zip(self.config["bodies"], counts)):
            if n == 0:
                raise SetupError(
                    f"bodies[{i}].geometry = {b['geometry']}: body {b['name']!r} gets no particles "
                    f"with particles_per_cell {b['particles_per_cell']} on cells of "
                    f"{', '.join(f'{h:g}' for h in self.grid.spacing)}: expected a geometry that "
                    f"contains at least one particle position (enlarge it or refine)")

    # ----------------------------------------------------------------- seeding
    def _seed(self):
        dim = self.dim
        mat = {k: [] for k in ("x", "volume0", "id", "body", "v", "density", "half_size")}
        rig = {k: [] for k in ("x", "id", "body", "v", "half_size")}
        id_offset = 0
        for i, b in enumerate(self.config["bodies"]):
            ppc = b["particles_per_cell"]
            x, vol, pid = seed_body(self.grid, b["geometry"], ppc, i, id_offset)
            id_offset += int(np.prod(self.grid.cells)) * int(np.prod(ppc))
            target = rig if b.get("rigid", False) else mat
            target["x"].append(x)
            target["id"].append(pid)
            target["body"].append(np.full(len(x), i, dtype=np.int64))
            target["v"].append(np.tile(np.asarray(b.get("velocity", [0.0] * dim), float), (len(x), 1)))
            # particle domain half size (used by GIMP): h / (2 ppc) per axis
            half = self.grid.spacing / (2.0 * np.asarray(ppc, dtype=float))
            target["half_size"].append(np.tile(half, (len(x), 1)))
            if not b.get("rigid", False):
                target["volume0"].append(vol)
                target["density"].append(np.full(len(x), self.materials[self.body_material[i]].density))
        cat = lambda lst, shape, dt=float: (np.concatenate(lst) if lst else np.zeros(shape, dtype=dt))
        x = cat(mat["x"], (0, dim))
        volume0 = cat(mat["volume0"], (0,))
        if self.config.get("kinematics") == "axisymmetric":
            volume0 = volume0 * 2.0 * np.pi * x[:, 0]     # area x 2 pi r (x is the radius)
        n = len(x)
        self.particles = ParticleSet({
            "x": x, "x0": x.copy(),
            "v": cat(mat["v"], (0, dim)), "a": np.zeros((n, dim)),
            "F": np.broadcast_to(np.eye(3), (n, 3, 3)).copy(),
            "stress": np.zeros((n, 3, 3)),
            "volume0": volume0, "mass": volume0 * cat(mat["density"], (0,)),
            "half_size": cat(mat["half_size"], (0, dim)),
            "body": cat(mat["body"], (0,), np.int64), "id": cat(mat["id"], (0,), np.int64),
        })
        xr = cat(rig["x"], (0, dim))
        self.rigid = ParticleSet({
            "x": xr, "x0": xr.copy(), "v": cat(rig["v"], (0, dim)),
            "body": cat(rig["body"], (0,), np.int64), "id": cat(rig["id"], (0,), np.int64),
            "half_size": cat(rig["half_size"], (0, dim)),
        })
        for name, shape in self.history_fields().items():
            identity = name in ("deformation_gradient", "elastic_left_cauchy_green")
            initial = np.broadcast_to(np.eye(3), (n, 3, 3)) if identity else 0.0
            self.particles["h_" + name] = np.zeros((n,) + tuple(shape)) + initial
        self._sort_by_cell(self.particles)
        self._sort_by_cell(self.rigid)

    def history_fields(self):
        """History variables of all materials in use: name -> per-particle shape."""
        fields = {}
        for material in self.materials:
            fields.update(material.history)
        return fields

    def particle_history(self, index=slice(None)):
        return {name: self.particles["h_" + name][index] for name in self.history_fields()}

    def _sort_by_cell(self, pset):
        if len(pset):
            key = self.grid.local_cell_index(self.grid.cell_of(pset["x"]))
            pset.take(np.lexsort((pset["id"], key)))

    # ----------------------------------------------------------------- one step
    def footprint(self):
        """Shape functions of the material particles on the reset grid, and
        the grouping of particles that touch the same set of nodes (one
        element matrix per group): ``order`` sorts particles by group and
        ``starts`` marks the first of each group in that order."""
        p = self.particles
        nodes, S, G = self.shape.evaluate(p["x"], self.grid.lower, self.grid.spacing,
                                          self.grid.cells, self.particle_half_sizes())
        node_index = self.grid.local_node_index(nodes)
        # the first and last nodes identify the node set (also where GIMP's
        # stencil is clipped at the grid boundary)
        key = node_index[:, 0] * self.grid.n_local_nodes + node_index[:, -1]
        order = np.argsort(key, kind="stable")
        sorted_key = key[order]
        starts = (np.flatnonzero(np.r_[True, sorted_key[1:] != sorted_key[:-1]])
                  if len(key) else np.zeros(0, int))
        return node_index, S, G, (order, starts)

    def particle_half_sizes(self):
        """Current particle-domain half sizes for GIMP: the initial h/(2 ppc)
        stretched by the diagonal of F (convected-domain GIMP restricted to
        axis-aligned domains, so that the domains keep tiling the body under
        homogeneous deformation), at most half a cell."""
        p = self.particles
        stretch = np.abs(np.diagonal(p["F"], axis1=1, axis2=2)[:, :self.dim])
        return np.minimum(p["half_size"] * stretch, 0.5 * self.grid.spacing)

    def nodal_state(self, node_index, S):
        """G&W step 1 (eq. 2-4): lumped mass, v_g(t), a_g(t) and Fext_g on
        owned dofs."""
        p, grid = self.particles, self.grid
        nloc = grid.n_local_nodes
        m = p["mass"]
        mass = grid.sum_scalar_to_owned(particle_to_grid(node_index, S, m, nloc))
        momentum = grid.sum_to_owned(particle_to_grid(node_index, S, m[:, None] * p["v"], nloc))
        mass_acc = grid.sum_to_owned(particle_to_grid(node_index, S, m[:, None] * p["a"], nloc))
        fext = grid.sum_to_owned(particle_to_grid(node_index, S, m[:, None] * self.gravity, nloc))
        has_mass = mass > self.mass_floor
        safe = np.where(has_mass, mass, 1.0)
        velocity = np.where(has_mass, momentum / safe, 0.0)
        acceleration = np.where(has_mass, mass_acc / safe, 0.0)
        return mass, velocity, acceleration, fext

    def constraint_scale(self, dt):
        h = float(np.min(self.grid.spacing))
        k = max(m.bulk_modulus + 4.0 / 3.0 * m.shear_modulus for m in self.materials) * h ** (self.dim - 2)
        if self.dynamic:
            coefficient = 4.0 if self.integrator == "newmark" else 1.0
            k += coefficient / dt**2 * max(m.density for m in self.materials) * self.grid.cell_volume
        return k

    def prepare_step(self, dt):
        """Steps 1-2: P2G and the Newton state on the reset grid."""
        p = self.particles
        node_index, S, G, (order, starts) = self.footprint()
        mass, velocity, acceleration, fext = self.nodal_state(node_index, S)
        # sum_p m_p |h G_ip|^2: zero only where no particle gradient reaches
        stiffness_weight = self.grid.sum_scalar_to_owned(particle_to_grid(
            node_index, np.sum((G * self.grid.spacing) ** 2, axis=2), self.particles["mass"],
            self.grid.n_local_nodes))
        cons = bc.build_constraints(self.grid, self.shape, self.rigid, self.rigid_bodies,
                                    self.boundary, mass, dt, self.mass_floor, stiffness_weight)
        groups = self.material_groups()
        state = StepState(
            dt=dt, dynamic=self.dynamic, scheme=self.integrator, node_index=node_index, S=S, G=G,
            F_n=p["F"], volume_n=p["volume0"] * np.linalg.det(p["F"]),
            material_groups=groups, group_order=order, group_starts=starts,
            group_nodes=node_index[order][starts],
            mass=mass, velocity=velocity, acceleration=acceleration, external_force=fext,
            history=self.particle_history(), plane_stress=self.plane_stress,
            radius=p["x"][:, 0].copy() if self.axisymmetric else None,
            particle_mass=p["mass"], projection_floor=1e4 * self.mass_floor,
            fixed=cons.fixed, fixed_value=cons.value, constraint_scale=self.constraint_scale(dt))
        return state, cons

    def predictor(self, state):
        """Initial Newton guess for the free dofs. G&W step 2 starts from u = 0;
        starting from the expected increment is closer and saves Newton
        iterations without changing the converged answer: dt v_g + dt^2/2 a_g
        with the grid velocity and acceleration interpolated from the
        particles (in quasi-statics v_p is the last increment over dt)."""
        if self.integrator == "backward_euler":
            return state.dt * state.velocity
        return state.dt * state.velocity + 0.5 * state.dt**2 * state.acceleration

    def advance(self, dt):
        """One implicit step (G&W section 3.3), or one explicit step. Returns
        a dict of step data. Raises StepFailed, leaving the particles as they were."""
        if self.explicit:
            return self.advance_explicit(dt)
        t0 = wallclock.perf_counter()
        with log_stage(self.stages["P2G"]):
            state, cons = self.prepare_step(dt)                   # steps 1-2

        guess = np.where(state.fixed, state.fixed_value, self.predictor(state))
        if self.solver.inverts(state, guess):                    # G&W step 2: u = 0
            guess = np.where(state.fixed, state.fixed_value, 0.0)
        u, info = self.solver.solve(state, guess)                 # steps 3-6
        if not info["converged"]:
            why = "a particle inverted (det F <= 0)" if info["inverted"] else info["reason_name"]
            raise StepFailed(f"Newton did not converge at step {self.step_index + 1} "
                             f"(t = {self.time + dt:.6g}, dt = {dt:.6g}): {why} after "
                             f"{info['newton_iterations']} iterations")
        with log_stage(self.stages["G2P"]):
            forces, v_new, a_new = self.update_particles(state, cons, u, dt)   # step 7
        with log_stage(self.stages["Migration"]):
            self.migrate()                                        # step 8

        self.time += dt
        self.step_index += 1
        self.last_grid = {"mass": state.mass, "velocity": v_new, "acceleration": a_new,
                          "displacement_increment": u}
        history = info["residual_history"]
        return {
            "step": self.step_index, "time": self.time, "dt": dt,
            "newton_iterations": info["newton_iterations"],
            "linear_iterations": info["linear_iterations"],
            "backtracks": info["backtracks"],
            "linear_fallbacks": info["linear_fallbacks"],
            "residual_initial": float(history[0]) if len(history) else 0.0,
            "residual_final": float(history[-1]) if len(history) else 0.0,
            "residual_history": history,
            "forces": forces,
            "external_work": self.external_work,
            "kinetic_energy": self.kinetic_energy(),
            "strain_energy": self.strain_energy(),
            "wall_time": wallclock.perf_counter() - t0,
        }

    def update_particles(self, state, cons, u, dt):
        """G&W step 7: reactions, a_g(t+dt) from eq. 16, and the particle
        update. Raises StepFailed (particles untouched) if a particle would
        leave the grid or move farther than the Lagrangian limit."""
        comm, grid, p = self.comm, self.grid, self.particles
        u_local = grid.owned_to_local(u)
        raw = self.solver.unconstrained_residual(u, u_local)      # Fint + M a - Fext
        forces = {}
        for name, mask in cons.body_dofs.items():
            local = np.where(mask, raw, 0.0).reshape(-1, self.dim).sum(axis=0)
            forces[name] = comm.allreduce(local, op=MPI.SUM)

        # converged state (kinematics and stress of the residual just evaluated),
        # a_g(t+dt) from eq. 16, interpolate to particles
        F_inc, F, sigma = state.extra["kinematics"]
        v_new, a_new = state.grid_kinematics(u)
        a_local = grid.owned_to_local(a_new)
        u_p = grid_to_particle(state.node_index, state.S, u_local)
        a_p = grid_to_particle(state.node_index, state.S, a_local)
        new_x = p["x"] + u_p
        new_rigid_x = self.rigid["x"] + self.rigid["v"] * dt
        outside = int(np.sum(~grid.inside(new_x))) + int(np.sum(~grid.inside(new_rigid_x)))
        if comm.allreduce(outside) > 0:
            raise StepFailed(f"particles would leave the grid at step {self.step_index + 1} "
                             f"(t = {self.time + dt:.6g}); enlarge grid.lower/upper")
        limit = self.config["time"]["max_particle_displacement"]
        if limit is not None:
            moved = np.max(np.abs(u_p) / grid.spacing) if len(u_p) else 0.0
            moved = comm.allreduce(float(moved), op=MPI.MAX)
            if moved > limit:
                raise StepFailed(f"a particle would move {moved:.3g} cells at step "
                                 f"{self.step_index + 1} (t = {self.time + dt:.6g}, dt = {dt:.6g}); "
                                 f"time.max_particle_displacement is {limit:g}")
        self._add_external_work(forces, u_p, dt)
        p["x"] = new_x
        if self.integrator == "newmark":                # G&W step 7
            p["v"] = p["v"] + 0.5 * dt * (p["a"] + a_p)
            p["a"] = a_p
        elif self.integrator == "backward_euler":       # Sulsky & Kaul: v += dt a (FLIP)
            p["v"] = p["v"] + dt * a_p
            p["a"] = a_p
        else:
            p["v"] = u_p / dt
            p["a"] = np.zeros_like(u_p)
        p["F"] = F
        p["stress"] = sigma
        for name, values in state.extra["history"].items():     # commit the history
            p["h_" + name] = values
        self.rigid["x"] = new_rigid_x
        return forces, v_new, a_new

    def _add_external_work(self, forces, displacement, dt):
        """Work done on the material during a step: rigid bodies, force
        (trapezoidal in time) times their prescribed velocity, and gravity,
        sum_p m_p g . du_p. Collective."""
        work = 0.0
        for _, name, velocity, _ in self.rigid_bodies:
            previous = self._body_forces.get(name, np.zeros(self.dim))
            work += 0.5 * float(np.dot(previous + forces[name], velocity)) * dt
        if len(displacement) and np.any(self.gravity):
            local = float(np.sum(self.particles["mass"] * (displacement @ self.gravity)))
        else:
            local = 0.0
        self.external_work += work + self.comm.allreduce(local, op=MPI.SUM)
        self._body_forces = {name: np.array(f) for name, f in forces.items()}

    # ----------------------------------------------------------------- explicit MPM
    def stable_time_step(self):
        """CFL limit dt = cfl * h / max_p (c + |v_p|) (MPM intro), with c the
        dilatational wave speed of each particle's material. Collective."""
        p = self.particles
        h = float(np.min(self.grid.spacing))
        speed = 0.0
        for material, index in self.material_groups():
            if len(index):
                v = np.sqrt(np.max(np.sum(p["v"][index] ** 2, axis=1)))
                speed = max(speed, material.wave_speed() + v)
        speed = self.comm.allreduce(speed, op=MPI.MAX)
        return self.config["time"]["cfl"] * h / speed

    def _check_explicit_time_step(self):
        dt = self.config["time"]["dt"]
        if dt is not None:
            limit = self.stable_time_step() / self.config["time"]["cfl"]
            if dt > limit:
                raise SetupError(f"time.dt = {dt!r}: expected at most the explicit stability limit "
                                 f"h / (c + |v|) = {limit:.6g} (omit time.dt for an automatic "
                                 f"step of time.cfl = {self.config['time']['cfl']} times it)")

    def material_groups(self):
        """[(material, particle index)] for the deformable particles."""
        p = self.particles
        groups = []
        for mi, material in enumerate(self.materials):
            bodies_of = [b for b, m in self.body_material.items() if m == mi]
            groups.append((material, np.flatnonzero(np.isin(p["body"], bodies_of))))
        return groups

    def update_stress_explicit(self, node_index, S, G, v_local, dt):
        """F(t+dt) = (1 + dt grad v) F(t) (MPM intro eq. 13-14) and the
        stress of every particle; axisymmetric: hoop stretch 1 + dt v_r / r."""
        p = self.particles
        L = gradient_at_particles(node_index, G, v_local)
        F_inc = deformation_increment(dt * L)
        if self.axisymmetric:
            F_inc[:, 2, 2] = 1.0 + dt * grid_to_particle(node_index, S, v_local)[:, 0] / p["x"][:, 0]
        F = np.matmul(F_inc, p["F"])
        if len(F) and not np.all(smallmat.det(F_inc) > 0):     # full 3x3 (hoop stretch)
            return False
        sigma = np.zeros((len(F), 3, 3))
        history = self.particle_history()
        new_history = {k: v.copy() for k, v in history.items()}
        for material, index in self.material_groups():
            if len(index):
                old = {k: history[k][index] for k in material.history}
                Fi = F[index]
                sigma[index], _, new = material_update(material, Fi, old, False, self.plane_stress)
                F[index] = Fi
                for k, v in new.items():
                    new_history[k][index] = v
        p["F"], p["stress"] = F, sigma
        for name, values in new_history.items():
            p["h_" + name] = values
        return True

    def _explicit_stress(self, node_index, S, G, v_local, dt, saved):
        ok = self.update_stress_explicit(node_index, S, G, v_local, dt)
        if self.comm.allreduce(int(not ok)):
            self.particles.fields.update(saved)
            raise StepFailed(f"a particle inverted at step {self.step_index + 1} "
                             f"(t = {self.time + dt:.6g}, dt = {dt:.6g})")

    def advance_explicit(self, dt):
        """One explicit MPM step (MPM intro eq. 1-10): update-stress-last
        (``usl``, the intro's eq. 5 with the new grid velocity), its modified
        form (``musl``, the default) or update-stress-first (``usf``)."""
        t0 = wallclock.perf_counter()
        comm, grid, p, dim = self.comm, self.grid, self.particles, self.dim
        with log_stage(self.stages["P2G"]):
            node_index, S, G, _ = self.footprint()
            mass, velocity, _, fext = self.nodal_state(node_index, S)              # eq. 2-4
            cons = bc.build_constraints(grid, self.shape, self.rigid, self.rigid_bodies,
                                        self.boundary, mass, dt, self.mass_floor)
            velocity = np.where(cons.fixed, cons.value / dt, velocity)
            update = self.config["time"]["stress_update"]
            saved = {k: p[k] for k in ["F", "stress"] + ["h_" + n for n in self.history_fields()]}
            if update == "usf":                                   # stress from the velocity at t
                self._explicit_stress(node_index, S, G, grid.owned_to_local(velocity), dt, saved)
            # current volume: full det F (thickness in plane stress, hoop in axisymmetry)
            volume = p["volume0"] * smallmat.det(p["F"]) if len(p["F"]) else np.zeros(0)
            pairs = internal_force_pairs(p["stress"][:, :dim, :dim], G, volume)   # eq. 6
            if self.axisymmetric:                                 # hoop term sigma_thth N_i / r
                pairs[:, :, 0] += hoop_force_pairs(p["stress"], np.broadcast_to(np.eye(3), p["F"].shape),
                                                   S, volume, p["x"][:, 0])
            fint = grid.sum_to_owned(scatter(node_index, pairs, grid.n_local_nodes))
        with log_stage(self.stages["G2P"]):
            has_mass = mass > self.mass_floor
            acceleration = np.where(has_mass, (fext - fint) / np.where(has_mass, mass, 1.0), 0.0)  # eq. 1
            v_new = velocity + acceleration * dt                                     # eq. 7
            v_new = np.where(cons.fixed, cons.value / dt, v_new)
            acceleration = np.where(cons.fixed, 0.0, acceleration)
            forces = {}
            reaction = mass * (v_new - velocity) / dt - fext + fint     # force the bodies apply
            for name, mask in cons.body_dofs.items():
                local = np.where(mask, reaction, 0.0).reshape(-1, dim).sum(axis=0)
                forces[name] = comm.allreduce(local, op=MPI.SUM)
            a_local = grid.owned_to_local((v_new - velocity) / dt)
            v_local = grid.owned_to_local(v_new)
            new_v = p["v"] + dt * grid_to_particle(node_index, S, a_local)             # eq. 9
            new_x = p["x"] + dt * grid_to_particle(node_index, S, v_local)             # eq. 10
            new_rigid_x = self.rigid["x"] + self.rigid["v"] * dt
            outside = int(np.sum(~grid.inside(new_x))) + int(np.sum(~grid.inside(new_rigid_x)))
            if comm.allreduce(outside) > 0:
                p.fields.update(saved)
                raise StepFailed(f"particles would leave the grid at step {self.step_index + 1} "
                                 f"(t = {self.time + dt:.6g}); enlarge grid.lower/upper")
            if update == "usl":                       # stress from the new grid velocity
                self._explicit_stress(node_index, S, G, v_local, dt, saved)
            elif update == "musl":
                # modified USL: the velocity gradient comes from the updated
                # particle momenta mapped back to the grid, which keeps nodes
                # with tiny mass (body edges) from driving huge strain rates
                m = p["mass"]
                momentum = grid.sum_to_owned(particle_to_grid(node_index, S, m[:, None] * new_v,
                                                              grid.n_local_nodes))
                remapped = np.where(has_mass, momentum / np.where(has_mass, mass, 1.0), 0.0)
                remapped = np.where(cons.fixed, cons.value / dt, remapped)
                self._explicit_stress(node_index, S, G, grid.owned_to_local(remapped), dt, saved)
            self._add_external_work(forces, new_x - p["x"], dt)
            p["v"], p["x"] = new_v, new_x
            p["a"] = np.zeros_like(new_v)
            self.rigid["x"] = new_rigid_x
        with log_stage(self.stages["Migration"]):
            self.migrate()
        self.time += dt
        self.step_index += 1
        self.last_grid = {"mass": mass, "velocity": v_new, "acceleration": acceleration,
                          "displacement_increment": v_new * dt}
        return {
            "step": self.step_index, "time": self.time, "dt": dt, "explicit": True,
            "newton_iterations": 0, "linear_iterations": 0, "backtracks": 0, "linear_fallbacks": 0,
            "residual_initial": 0.0, "residual_final": 0.0, "residual_history": np.zeros(0),
            "forces": forces, "external_work": self.external_work,
            "kinetic_energy": self.kinetic_energy(),
            "strain_energy": self.strain_energy(), "wall_time": wallclock.perf_counter() - t0,
        }

    # ----------------------------------------------------------------- migration
    def migrate(self):
        """Send particles to the rank owning their cell, then check that the
        global particle count and mass are unchanged."""
        for pset in (self.particles, self.rigid):
            dest = self.grid.owner_of_cells(self.grid.cell_of(pset["x"]))
            migrate(self.comm, pset, dest)
            self._sort_by_cell(pset)
        count = self.particles.global_count(self.comm)
        rigid_count = self.rigid.global_count(self.comm)
        mass = float(self.particles.global_sum(self.comm, "mass"))
        if count != self.count0 or rigid_count != self.rigid_count0 \
                or abs(mass - self.mass0) > 1e-12 * abs(self.mass0):
            raise RuntimeError(f"particle migration lost particles: count {count} "
                               f"(expected {self.count0}), mass {mass!r} (expected {self.mass0!r})")

    # ----------------------------------------------------------------- diagnostics
    def kinetic_energy(self):
        p = self.particles
        return float(self.comm.allreduce(0.5 * np.sum(p["mass"] * np.sum(p["v"] ** 2, axis=1))))

    def strain_energy(self):
        p = self.particles
        total = 0.0
        for material, index in self.material_groups():
            if len(index):
                history = {k: p["h_" + k][index] for k in material.history}
                total += float(np.sum(p["volume0"][index]
                                      * material.strain_energy(p["F"][index], history)))
        return float(self.comm.allreduce(total))

    def particle_output(self):
        """Particle fields for output: material particles then rigid ones."""
        p, r = self.particles, self.rigid
        nr = len(r)
        J = np.linalg.det(p["F"])
        return {
            "position": np.concatenate([p["x"], r["x"]]),
            "displacement": np.concatenate([p["x"] - p["x0"], r["x"] - r["x0"]]),
            "velocity": np.concatenate([p["v"], r["v"]]),
            "stress": np.concatenate([p["stress"], np.zeros((nr, 3, 3))]),
            "von_mises": np.concatenate([von_mises(p["stress"]), np.zeros(nr)]),
            # sigma_1 - sigma_2 of the in-plane stress (photoelastic fringes, G&W eq. 22)
            "principal_stress_difference": np.concatenate([np.sqrt(
                (p["stress"][:, 0, 0] - p["stress"][:, 1, 1]) ** 2 + 4.0 * p["stress"][:, 0, 1] ** 2),
                np.zeros(nr)]),
            "J": np.concatenate([J, np.ones(nr)]),
            "body": np.concatenate([p["body"], r["body"]]),
            "id": np.concatenate([p["id"], r["id"]]),
            **{name: np.concatenate([p["h_" + name], np.zeros((nr,) + p["h_" + name].shape[1:])])
               for name in ("eq_plastic_strain", "plastic_work") if "h_" + name in p},
        }

    def grid_output(self):
        """Grid fields of the last step on owned nodes, x axis first."""
        grid = self.grid
        if self.last_grid is None:
            n = grid.n_owned_nodes * self.dim
            node_index, S, _, _ = self.footprint()
            mass, velocity, acceleration, _ = self.nodal_state(node_index, S)
            self.last_grid = {"mass": mass, "velocity": velocity, "acceleration": acceleration,
                              "displacement_increment": np.zeros(n)}
        out = {}
        for name, values in self.last_grid.items():
            view = grid.owned_view(values)
            out[name] = view[..., 0] if name == "mass" else view
        return out
