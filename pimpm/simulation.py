"""The simulation: its state (grid, particles, bodies, time) and its
set-up; its steps are :mod:`pimpm.steps` (the implicit step of Guilkey &
Weiss 2003, section 3.3, and the explicit step). The swappable pieces are
chosen by lookup from the input: the time integrator
(:mod:`pimpm.integrators`), the kinematics (:mod:`pimpm.kinematics`), the
materials (:mod:`pimpm.materials`) and the shape functions
(:mod:`pimpm.shape`).
"""
import time as wallclock

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from . import energy, faults, fbar, resources
from .errors import SetupError, StepFailed
from .grid import Grid
from .implicit import StepProblem, TangentPattern, residual_scale
from .implicit.formulation import make_formulation
from .integrators import make_integrator
from .integrators.explicit import stable_time_step
from .functions import lookup, make_functions
from .kernels import pattern as kernel_pattern
from .kernels import transfer as transfer_kernels
from .kinematics import make_kinematics
from .materials import make_material
from .materials.table import MaterialTable
from .loads import displacement as load_displacement
from .loads import make_loads, particle_forces
from .options import with_command_line
from .partition import balanced_grid, particle_imbalance
from .particles import ParticleSet, migrate, sort_by_footprint
from .seeding import MATERIAL_FIELDS, RIGID_FIELDS, overlapping_bodies, particles_per_body, seed_bodies
from .shape import make_shape
from .solver import NewtonSolver, diagnose_solver_options
from .stages import log_stage, log_stages
from .terms import BondedRigidBody, ContactTool, StepContext, make_terms
from .steps import explicit as explicit_step
from .steps import implicit as implicit_step
from .fields import BodyFields, FieldGrid
from .terms.pairs import FieldContact
from .transfer import particle_to_grid

_NO_INT = np.zeros(0, dtype=np.int64)
_NO_PRESENCE = np.zeros((0, 1))

__all__ = ["Simulation", "SetupError", "StepFailed"]


class Simulation:
    def __init__(self, config, comm=MPI.COMM_WORLD, checkpoint=None):
        """``checkpoint``: a :class:`pimpm.io.checkpoint.Checkpoint` to continue
        from instead of seeding the bodies (``--restart``)."""
        try:                           # the command line's -pimpm_* aliases of input keys
            self.config = config = with_command_line(config)
        except ValueError as err:
            raise SetupError(str(err)) from None
        self.comm = comm
        self.dim = dim = config["dim"]
        self._material_table = None            # (particles' body array, its MaterialTable)
        problem = resources.check(config, comm.size, 8 * np.dtype(PETSc.IntType).itemsize)
        if problem:                   # before anything is allocated
            raise SetupError(problem)
        g = config["grid"]
        self.shape = make_shape(g["shape_functions"], dim)
        same_layout = checkpoint is not None and checkpoint.same_ranks
        if same_layout:
            self._check_ownership_ranges(checkpoint, np.asarray(g["cells"]) + 1)
        self.grid = Grid(comm, g["lower"], g["upper"], g["cells"], stencil_width=self.shape.stencil_width,
                         ownership_ranges=checkpoint.ownership_ranges if same_layout else None,
                         proc_sizes=checkpoint.proc_sizes if same_layout else None)
        self.boundary = dict(g.get("boundary", {}))
        self.kinematics = make_kinematics(config["kinematics"])
        self.integrator = make_integrator(config["time"])
        self.material_names = list(config["materials"])
        self.materials = [make_material(config["materials"][k]) for k in self.material_names]
        self.functions = make_functions(config)
        self.gravity = np.asarray(config["time"].get("gravity", [0.0] * dim), dtype=float)
        self.gravity_function = lookup(self.functions, config["time"].get("gravity_function"))
        self.body_names = [b["name"] for b in config["bodies"]]
        #: what a step adds beside the particles: rigid bodies bonded to the material (pimpm.terms)
        self.terms = make_terms(config, self.functions)
        #: the deformable bodies' grid velocity fields and their contact pairs (pimpm.fields)
        self.fields = BodyFields(config)
        if not self.fields.single and not self.integrator.explicit:     # the pairs' law inside Newton
            self.terms.append(FieldContact(self.fields, dim, max(m.p_wave_modulus for m in self.materials),
                                           float(np.min(self.grid.spacing))))
        self.loads = make_loads(config, self.functions, self.body_names)
        self.body_material = {i: self.material_names.index(b["material"])
                              for i, b in enumerate(config["bodies"]) if not b.get("rigid", False)}
        self.work = energy.WorkAccount(comm)     # work of rigid bodies and gravity so far
        if checkpoint is None:
            densities = {i: self.materials[m].density for i, m in self.body_material.items()}
            initial = {}
            for material in self.materials:
                initial.update(material.model.initial_history())
            self.particles, self.rigid = seed_bodies(config, self.grid, self.kinematics, densities, initial,
                                                     comm)
            self._check_every_body_has_particles()
            overlap = overlapping_bodies(config, self.particles, self.grid, comm)
            if overlap:
                i, j, n = overlap
                b = config["bodies"]
                raise SetupError(f"bodies[{j}].geometry = {b[j]['geometry']}: {n} particles of body "
                                 f"{b[j]['name']!r} lie inside body {b[i]['name']!r}: expected deformable "
                                 f"bodies that do not overlap (the mass of the overlap would count twice)")
            self.time = 0.0
            self.step_index = 0
            for load in self.loads:       # each particle's share, fixed on the reference configuration
                self.particles[load.field] = load.share(self.particles, comm)
            self.count0 = self.particles.global_count(comm)
            self.rigid_count0 = self.rigid.global_count(comm)
            self.mass0 = float(self.particles.global_sum(comm, "mass"))
        else:
            self._restore(checkpoint)
        self._add_term_fields()
        largest = float(np.max(self.particles["mass"])) if len(self.particles) else 0.0
        self.mass_floor = 1e-10 * comm.allreduce(largest, op=MPI.MAX)
        self.stages = log_stages()
        self.solver = None
        self.last_grid = None
        #: ownership ranges from the particles (false: PETSc's even split)
        self.balance = config["parallel"]["balance"]
        #: repartition before a step when the particle imbalance exceeds this
        self.rebalance_threshold = config["parallel"]["rebalance_threshold"]
        #: nodes with less support than this fraction of a cell are extended out (implicit)
        self.weak_fraction = config["grid"]["weak_node_fraction"]
        if self.balance and not same_layout:
            self.balance_ranks()
        if self.integrator.explicit:
            problem = self.integrator.check_time_step(self)
            if problem:
                raise SetupError(problem)
        else:
            self._make_solver()
        #: what the whole run will need (bytes, its parts): the summary prints it,
        #: the run's last line compares it with the peak
        self.memory_estimate, self.memory_parts = resources.run_estimate(self)
        problem = resources.run_memory_problem(self, self.memory_estimate, self.memory_parts)
        if problem:
            raise SetupError(problem)

    def _term_fields(self):
        """The particle fields the contact tools carry from step to step (each
        domain corner's elastic slip, state and depth, each particle's status and
        force): name -> (shape of one particle's value, dtype)."""
        dim, corners = self.dim, 1 << self.dim
        fields = {}
        for term in self.terms:
            if getattr(term, "field", None) is not None:
                fields.update({term.field: ((corners, dim), np.float64),
                               term.touching_field: ((corners,), np.int8),
                               term.depth_field: ((corners,), np.float64),
                               term.output_fields[0]: ((), np.int8),
                               term.output_fields[1]: ((dim,), np.float64)})
        return fields

    def _add_term_fields(self):
        """The contact tools' particle fields, zero where a run starts."""
        for name, (shape, dtype) in self._term_fields().items():
            if name not in self.particles:
                self.particles[name] = np.zeros((len(self.particles),) + shape, dtype=dtype)

    def _check_ownership_ranges(self, checkpoint, nodes):
        """The checkpoint's ownership ranges cover the grid's nodes, each at
        least a stencil wide (a DMDA would stop some ranks otherwise)."""
        ranges = checkpoint.ownership_ranges
        if len(ranges) != self.dim or any(int(np.sum(r)) != n or int(np.min(r)) < self.shape.stencil_width
                                          for r, n in zip(ranges, nodes)):
            raise SetupError(f"the checkpoint's ownership ranges {[np.asarray(r).tolist() for r in ranges]} "
                             f"do not split the grid's {nodes.tolist()} nodes: expected an intact checkpoint")

    def _field_shapes(self):
        """Each particle set's fields a checkpoint of this input holds (the
        seeded ones, MATERIAL_FIELDS and RIGID_FIELDS, the materials' history,
        the loads' shares, the contact tools' fields): name -> (shape of one
        particle's value, dtype kind: 'f' float, 'i' integer)."""
        dim = self.dim
        vector, scalar, index = ((dim,), "f"), ((), "f"), ((), "i")
        seeded = {"x": vector, "x0": vector, "v": vector, "a": vector, "F": ((3, 3), "f"),
                  "stress": ((3, 3), "f"), "volume0": scalar, "mass": scalar, "half_size": vector,
                  "body": index, "id": index, "surface": ((2 * dim,), "f")}
        particles = {name: seeded[name] for name in MATERIAL_FIELDS}
        for material in self.materials:
            particles.update({"h_" + k: (tuple(shape), "f") for k, shape in material.model.history.items()})
        particles.update({load.field: scalar for load in self.loads})
        particles.update({name: (shape, np.dtype(dtype).kind)
                          for name, (shape, dtype) in self._term_fields().items()})
        return {"particles": particles, "rigid": {name: seeded[name] for name in RIGID_FIELDS}}

    def _check_fields(self, sets):
        """A problem of this rank's checkpointed particles, or None: a field
        missing or of another shape or type, a body index out of range, a
        particle outside the grid, without mass or volume, with det F <= 0 or
        a GIMP half-width beyond the grid (seeding clips it to the grid's edge;
        a mesh element's particle may be wider than a cell)."""
        lower, upper = self.grid.lower, self.grid.upper
        for name, spec in self._field_shapes().items():
            data = sets[name]
            missing = sorted(set(spec) - set(data))
            if missing:
                return f"the checkpoint's {name} have no {', '.join(missing)}"
            for field in sorted(data):
                if field not in spec:
                    return f"the checkpoint's {name}' {field} is not a field of this input's run"
                shape, kind = spec[field]
                if data[field].shape[1:] != shape or data[field].dtype.kind != kind:
                    return (f"the checkpoint's {name}' {field} holds {data[field].dtype} of shape "
                            f"{data[field].shape[1:]} per particle: expected "
                            f"{'floats' if kind == 'f' else 'integers'} of shape {shape}")
            x, body = data["x"], data["body"]
            if np.any(x < lower) or np.any(x > upper):
                return f"the checkpoint's {name} are not all inside the grid"
            if np.any(body < 0) or np.any(body >= len(self.body_names)):
                return f"the checkpoint's {name}' body indices are not all bodies of the input"
            if np.any(data["half_size"] < 0.0) or np.any(data["half_size"] > upper - lower):
                return f"the checkpoint's {name}' half_size are not all in [0, the grid's size]"
        p = sets["particles"]
        if np.any(p["mass"] <= 0.0) or np.any(p["volume0"] <= 0.0):
            return "the checkpoint's particles do not all have a positive mass and volume"
        if np.any(np.linalg.det(p["F"]) <= 0.0):
            return "the checkpoint's particles' deformation gradients F do not all have det F > 0"
        for term in self.contact_tools:
            if np.any(p[term.depth_field] < 0.0):
                return f"the checkpoint's particles' {term.depth_field} are not all >= 0"
        return None

    def _restore(self, checkpoint):
        """The state of a checkpoint: particles (on the same number of ranks,
        each rank's own in their order; otherwise the ones in this rank's
        cells), time, step, work and the initial count and mass. Collective;
        SetupError on every rank if the checkpoint is not one of this input's run."""
        problems = [p for p in self.comm.allgather(self._check_fields(checkpoint.sets)) if p]
        if problems:
            raise SetupError(f"{problems[0]}: expected the checkpoint of a run of this input, intact")
        fields = {}
        for name, data in checkpoint.sets.items():
            pset = ParticleSet(data)
            if not checkpoint.same_ranks:
                keep = self.grid.owner_of_cells(self.grid.cell_of(pset["x"])) == self.comm.rank
                pset.take(np.flatnonzero(keep))
                sort_by_footprint(pset, self.grid)
            fields[name] = pset
        self.particles, self.rigid = fields["particles"], fields["rigid"]
        for load in self.loads:
            load.total_share = checkpoint.loads.get(load.name) if load.name in checkpoint.loads else \
                self.comm.allreduce(float(np.sum(self.particles[load.field])))
        self.time = checkpoint.time
        self.step_index = checkpoint.step
        for key in ("last_forces", "displacements"):
            for name, vector in checkpoint.work.get(key, {}).items():
                if len(vector) != self.dim:
                    raise SetupError(f"the checkpoint's work account ({key} of {name!r}: {vector}): expected "
                                     f"{self.dim} numbers, in an intact checkpoint")
        self.work.restore(checkpoint.work)
        try:
            self.fields.restore(checkpoint.fields)
        except (KeyError, ValueError, TypeError) as err:
            raise SetupError(f"the checkpoint's contact pairs ({err}): expected an intact checkpoint") from None
        for term in self.terms:
            if term.name in checkpoint.terms:
                try:
                    term.restore(checkpoint.terms[term.name])
                except (KeyError, ValueError, TypeError) as err:
                    raise SetupError(f"the checkpoint's state of {term.name!r} ({err}): expected an "
                                     "intact checkpoint") from None
        self.count0 = checkpoint.initial["count"]
        self.rigid_count0 = checkpoint.initial["rigid_count"]
        self.mass0 = checkpoint.initial["mass"]
        count = self.particles.global_count(self.comm)
        if count != self.count0 or self.rigid.global_count(self.comm) != self.rigid_count0:
            raise SetupError(f"the checkpoint holds {count} particles where its run had {self.count0}: "
                             f"expected an intact checkpoint")
        mass = float(self.particles.global_sum(self.comm, "mass"))
        if abs(mass - self.mass0) > 1e-9 * max(abs(mass), abs(self.mass0)):
            raise SetupError(f"the checkpoint's particles weigh {mass:.9g} where its run's weighed "
                             f"{self.mass0:.9g}: expected an intact checkpoint")

    @property
    def solve_grid(self):
        """The grid whose nodes carry a step's nodal values: the grid, or with
        several velocity fields their field nodes (pimpm.fields.FieldGrid)."""
        if self.fields.single:
            return self.grid
        if getattr(self, "_field_grid", None) is None or self._field_grid.grid is not self.grid:
            self._field_grid = FieldGrid(self.grid, self.fields.count)
        return self._field_grid

    def _make_solver(self):
        """The step problem and its Newton solver on the current grid."""
        config = self.config
        self.problem = StepProblem(self.solve_grid, residual_scale(config, self.materials),
                                   formulation=make_formulation(config["time"]["formulation"]),
                                   stages=self.stages,
                                   nonsymmetric_materials=[m.name for m in self.materials
                                                           if not m.symmetric_tangent],
                                   terms=self.terms, f_bar=self.f_bar)
        try:
            self.solver = NewtonSolver(self.solve_grid, self.problem, config["solver"], self.stages)
        except (PETSc.Error, ValueError) as err:
            raise SetupError(diagnose_solver_options(config, err)) from None

    def _check_every_body_has_particles(self):
        counts = particles_per_body(self.config, self.particles, self.rigid, self.comm)
        for i, (b, n) in enumerate(zip(self.config["bodies"], counts)):
            if n == 0:
                raise SetupError(
                    f"bodies[{i}].geometry = {b['geometry']}: body {b['name']!r} gets no particles "
                    f"with particles_per_cell {b['particles_per_cell']} on cells of "
                    f"{', '.join(f'{h:g}' for h in self.grid.spacing)}: expected a geometry that "
                    f"contains at least one particle position (enlarge it or refine)")

    # ----------------------------------------------------------------- state
    def history_fields(self):
        """History variables of all materials in use: name -> per-particle shape."""
        fields = {}
        for material in self.materials:
            fields.update(material.history)
        return fields

    def particle_history(self, index=slice(None)):
        return {name: self.particles["h_" + name][index] for name in self.history_fields()}

    def material_groups(self):
        """[(material, particle index)] for the deformable particles."""
        return self.material_table().groups

    def material_table(self):
        """The particles' materials as the kernels take them
        (:class:`pimpm.materials.table.MaterialTable`), made again only when
        migration or sorting has replaced the particle arrays."""
        body = self.particles["body"]
        if self._material_table is None or self._material_table[0] is not body:
            lookup = np.full(len(self.body_names), -1, dtype=np.int64)
            for b, material in self.body_material.items():
                lookup[b] = material
            material_of = lookup[body]
            groups = [(material, np.flatnonzero(material_of == mi)) for mi, material in enumerate(self.materials)]
            self._material_table = (body, MaterialTable(groups, len(body)))
        return self._material_table[1]

    def kinetic_energy(self):
        return energy.kinetic_energy(self.particles, self.comm)

    def strain_energy(self):
        return energy.strain_energy(self.particles, self.material_table(), self.comm)

    @property
    def external_work(self):
        return self.work.total

    def stable_time_step(self):
        """The explicit CFL step (MPM intro) of the current state. Collective."""
        return stable_time_step(self.particles, self.material_table(), self.grid,
                                self.config["time"]["cfl"], self.comm)

    # ----------------------------------------------------------------- the reset grid
    def footprint(self):
        """Shape functions of the material particles on the reset grid:
        ghosted-local node of each (particle, node) pair, weights and
        gradients."""
        return self.shape.footprint(self.particles["x"], self.grid, self.particle_half_sizes())

    def particle_half_sizes(self):
        """Current particle-domain half sizes for GIMP: the initial h/(2 ppc)
        stretched by the diagonal of F (convected-domain GIMP restricted to
        axis-aligned domains, so that the domains keep tiling the body under
        homogeneous deformation), at most half a cell."""
        p = self.particles
        out = np.empty_like(p["half_size"])
        transfer_kernels.gimp_half_sizes(p["half_size"], p["F"], 0.5 * self.grid.spacing, out)
        return out

    @property
    def f_bar(self):
        """Does some material average its volume change (F-bar)?"""
        return any(m.f_bar for m in self.materials)

    @property
    def f_bar_average(self):
        """What F-bar averages over ("cells" or "nodes", the same for every
        averaged material), None without F-bar (pimpm.fbar)."""
        kinds = {m.f_bar for m in self.materials if m.f_bar}
        return kinds.pop() if kinds else None

    def pattern_width(self):
        """The tangent's stencil half-width: a particle's footprint; with
        F-bar on the cells one node more, whose coupling reaches the union of
        the footprints of a cell's particles, on the nodes twice a
        footprint, whose coupling joins the nodes of the particles that
        reach a node (pimpm.kernels.fbar); with F velocity fields, F times
        that on their virtual grid (pimpm.fields.FieldGrid)."""
        reach = self.shape.nodes_per_axis - 1
        extra = {None: 0, "cells": 1, "nodes": reach}[self.f_bar_average]
        return (reach + extra) * self.fields.count

    def tangent_pattern(self, node_index, active, cells=None, pairs=None):
        """The couplings of this step's tangent (pimpm.kernels.pattern);
        ``cells``: F-bar's averaging (pimpm.fbar.AveragedCells, whose
        particles couple every node they reach, or AveragedNodes); ``pairs`` (k, 2): ghosted-local field
        nodes that the contact pairs couple (pimpm.terms.pairs)."""
        grid = self.solve_grid
        width = self.pattern_width()
        cells = cells if cells is not None else fbar.NONE
        if pairs is not None and len(pairs):          # each pair as a footprint of its two field nodes
            extra = np.zeros((len(pairs), node_index.shape[1]), dtype=node_index.dtype)
            extra[:, :2] = pairs
            on = np.zeros(extra.shape, dtype=np.bool_)
            on[:, :2] = True
            node_index, active = np.vstack([node_index, extra]), np.vstack([active, on])
        if cells.kind == "nodes":
            order, start = _NO_INT, _NO_INT
            centres, presence, half = cells.centres, cells.presence, cells.half
        else:
            order, start = cells.order, cells.start
            centres, presence, half = _NO_INT, _NO_PRESENCE, 0
        indptr, indices, slots = kernel_pattern.block_pattern(
            node_index, active, grid.ghost_ijk, grid.dim, width, grid.owned_local_nodes,
            grid.n_local_nodes, int(grid.ghost_shape[0]), int(grid.ghost_shape[1]), order, start, centres, presence,
            half)
        scalar_indptr, scalar_indices = kernel_pattern.scalar_csr(indptr, indices, grid.dim)
        return TangentPattern(width, indptr, indices, slots,
                              scalar_indptr.astype(PETSc.IntType), scalar_indices.astype(PETSc.IntType))

    def nodal_state(self, node_index, S, time=None, grid=None):
        """G&W step 1 (eq. 2-4): lumped mass, v_g(t), a_g(t) and Fext_g at
        ``time`` (the end of the step) on owned dofs: one scatter of m, m v
        and m a; gravity is uniform, so its force is m_g g f(time); loads on
        particles are scattered with the shape functions. ``grid``: the
        grid of ``node_index`` (the solve grid's field nodes; default the grid)."""
        p, grid = self.particles, grid or self.grid
        dim = self.dim
        m = p["mass"]
        moments = particle_to_grid(node_index, S, np.column_stack([m, m[:, None] * p["v"],
                                                                   m[:, None] * p["a"]]),
                                   grid.n_local_nodes)
        mass = grid.sum_scalar_to_owned(moments[:, 0])
        momentum = grid.sum_to_owned(moments[:, 1:1 + dim])
        mass_acc = grid.sum_to_owned(moments[:, 1 + dim:])
        fext = self.nodal_external_force(node_index, S, mass, self.time if time is None else time, grid)
        has_mass = mass > self.mass_floor
        safe = np.where(has_mass, mass, 1.0)
        velocity = np.where(has_mass, momentum / safe, 0.0)
        acceleration = np.where(has_mass, mass_acc / safe, 0.0)
        return mass, velocity, acceleration, fext

    def nodal_external_force(self, node_index, S, mass, time, grid=None):
        """Fext_g at ``time`` on owned dofs: gravity (m_g g f(time)) and the
        loads on particles. ``grid``: the grid of ``node_index`` and ``mass``
        (the solve grid's field nodes with several velocity fields, pimpm.fields;
        default the grid). Collective."""
        grid = grid or self.grid
        fext = mass * np.tile(self.gravity * self.gravity_function(time), len(mass) // self.dim)
        forces = particle_forces(self.loads, self.particles, time, self.dim)
        if forces is not None:
            fext = fext + grid.sum_to_owned(particle_to_grid(node_index, S, forces, grid.n_local_nodes))
        return fext

    def particle_external_force(self, time):
        """The force on every material particle at ``time``: gravity and loads,
        (n, dim); None where there are neither."""
        if not self.loads and not np.any(self.gravity):
            return None
        force = self.particles["mass"][:, None] * (self.gravity * self.gravity_function(time))
        loads = particle_forces(self.loads, self.particles, time, self.dim)
        return force if loads is None else force + loads

    @property
    def rigid_bodies(self):
        """The terms that are rigid bodies (each has a force column in the history)."""
        return [t for t in self.terms if isinstance(t, (BondedRigidBody, ContactTool))]

    @property
    def contact_tools(self):
        """The rigid bodies in unilateral contact (contact columns in the history)."""
        return [t for t in self.terms if isinstance(t, ContactTool)]

    @property
    def contact_names(self):
        """The contact tools' and the contact pairs' names (their columns in history.csv)."""
        return [t.name for t in self.contact_tools] + self.fields.names

    def begin_terms(self, dt):
        """Set every nodal term up for the step of size dt from self.time. Collective."""
        context = StepContext(self.grid, self.shape, self.rigid, self.time, dt, self.particles,
                              self.particle_half_sizes)
        for term in self.terms:
            term.begin_step(context)

    def rigid_increments(self, dt):
        """Each moving term's displacement over the step (name -> vector), and
        every rigid particle's (n_rigid, dim). After :meth:`begin_terms`."""
        increments = {t.name: t.increment() for t in self.terms}
        increments = {name: step for name, step in increments.items() if step is not None}
        moves = np.zeros((len(self.rigid), self.dim))
        for term in self.terms:
            displacement = term.particle_displacement(self.rigid)
            if displacement is not None:
                moves += displacement
        return increments, moves

    # ----------------------------------------------------------------- one step
    def advance(self, dt):
        """One step of the run's kind: implicit (:mod:`pimpm.steps.implicit`,
        G&W section 3.3) or explicit (:mod:`pimpm.steps.explicit`), after a
        repartition if the ranks' particle counts have drifted apart.
        Returns a dict of step data. Raises StepFailed, leaving the
        particles as they were."""
        faults.checkpoint("step", self.comm.rank, self.step_index + 1)
        self.step_imbalance = self.particle_imbalance()
        if self.balance and self.step_imbalance > self.rebalance_threshold:
            with log_stage(self.stages["Migration"]):
                self.rebalance()
        step = explicit_step if self.integrator.explicit else implicit_step
        return step.advance(self, dt)

    def check_stays_on_grid(self, new_x, new_rigid_x, dt):
        """StepFailed on every rank if a particle would leave the grid. Collective."""
        outside = not (self.grid.contains(new_x) and self.grid.contains(new_rigid_x))
        if self.comm.allreduce(outside, op=MPI.LOR):
            raise StepFailed(f"particles would leave the grid at step {self.step_index + 1} "
                             f"(t = {self.time + dt:.6g}); enlarge grid.lower/upper")

    def finish_step(self, dt, t0, forces, grid_fields, explicit=False, **solve_info):
        """Advance the clock, keep the grid fields for output, and return
        the step's data (the history row). Collective (energies)."""
        self.time += dt
        self.step_index += 1
        self.last_grid = grid_fields
        info = {"step": self.step_index, "time": self.time, "dt": dt,
                "newton_iterations": 0, "linear_iterations": 0, "backtracks": 0,
                "linear_fallbacks": 0, "residual_initial": 0.0, "residual_final": 0.0,
                "residual_history": np.zeros(0)}
        info.update(solve_info)
        if explicit:
            info["explicit"] = True
        zero = np.zeros(self.dim)
        info.update(displacements={b.name: self.work.displacements.get(b.name, zero)
                                   for b in self.rigid_bodies},
                    load_forces={load.name: load.resultant(self.time) for load in self.loads},
                    load_displacements={load.name: load_displacement(load, self.particles, self.comm)
                                        for load in self.loads})
        if self.contact_names:
            contact = {t.name: dict(t.last) for t in self.contact_tools}
            contact.update({name: dict(values) for name, values in self.fields.last.items()})
            info.update(contact=contact, frictional_dissipation=sum(t.dissipation for t in self.contact_tools)
                        + self.fields.dissipation)
        kinetic, stored = energy.energies(self.particles, self.material_table(), self.comm)
        info.update(forces=forces, external_work=self.work.total,
                    kinetic_energy=kinetic, strain_energy=stored,
                    particle_imbalance=self.step_imbalance,
                    wall_time=wallclock.perf_counter() - t0)
        return info

    # ----------------------------------------------------------------- migration
    def particle_imbalance(self):
        """Largest local particle count over the mean (1 = balanced). Collective."""
        return particle_imbalance(len(self.particles), self.comm)

    def balance_ranks(self):
        """Move the run onto a grid whose ownership ranges balance the
        particles (:func:`pimpm.partition.balanced_grid`), with the last
        step's grid fields and the particles. Collective; only between steps
        (the grid holds no state then)."""
        old = self.grid
        new = balanced_grid(old, (self.particles, self.rigid), self.comm)
        if new is None:
            return
        self.grid = new
        if self.last_grid is not None:      # the last step's grid fields, for output
            self.last_grid = {k: old.transfer_owned(v, new) for k, v in self.last_grid.items()}
        self.fields.transfer(old, new)
        old.destroy()
        self.migrate()

    def rebalance(self):
        """Repartition between steps (the grid carries no state then): new
        ownership ranges, DMDA, matrix and solver. Collective."""
        old = self.grid
        self.balance_ranks()
        if self.grid is not old and self.solver is not None:
            self.solver.destroy()
            self._make_solver()
        self.step_imbalance = self.particle_imbalance()    # what the step will run with

    def migrate(self, disorder=0.0, lazy=False):
        """Send particles to the rank owning their cell and sort them by
        footprint (while more than the fraction ``disorder`` of them is out of
        order), then check that the global particle count and mass are
        unchanged. ``lazy`` (the explicit step): nothing moves while every
        particle's footprint stays in its rank's ghosted nodes, where the
        rank can still scatter and gather it (its sums then reach the owner
        of those nodes through the ghost exchange); one reduction decides.
        Collective."""
        sets = (self.particles, self.rigid)
        if lazy and self.comm.size > 1:
            kind = self.shape.kernel_kind
            stay = all(self.grid.footprints_in_ghosts(pset["x"], kind) for pset in sets)
            if self.comm.allreduce(stay, op=MPI.LAND):
                for pset in sets:
                    sort_by_footprint(pset, self.grid, disorder)
                return
        migrate(self.comm, [(pset, self.grid.owner_of_positions(pset["x"])) for pset in sets])
        for pset in sets:
            sort_by_footprint(pset, self.grid, disorder)
        p = self.particles
        count, rigid_count, mass = self.comm.allreduce(
            np.array([len(p), len(self.rigid), np.sum(p["mass"]) if len(p) else 0.0]), op=MPI.SUM)
        count, rigid_count, mass = int(count), int(rigid_count), float(mass)
        if count != self.count0 or rigid_count != self.rigid_count0 \
                or abs(mass - self.mass0) > 1e-12 * abs(self.mass0):
            raise RuntimeError(f"particle migration lost particles: count {count} "
                               f"(expected {self.count0}), mass {mass!r} (expected {self.mass0!r})")

