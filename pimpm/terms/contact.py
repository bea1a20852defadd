"""A rigid tool in unilateral contact with the material, with or without
Coulomb friction (``contact: frictionless`` or ``contact: friction``): it
pushes and never pulls, the material slides along it, sticks to it while the
tangential traction is below mu times the pressure, and lets go when it
withdraws. Inside Newton, with the exact tangent. Or welded to the material
at its surface (``contact: tied``): a corner that touches the tool (at the
start of a step, or pressed by it during one) is held for good, pushed and
pulled by the normal penalty and held tangentially by a spring of
tangential_stiffness x M / h: a no-slip tool without bonded contact's layer
of prescribed nodes below its surface.

Contact is found at the body's true surface: the corners of the particles'
domains, moved by the particles' own interpolation, against the tool's
exact geometry (a signed distance: box, ball, cylinder, half-space, or
the facets of a surface mesh or of a rigid volume mesh's boundary:
:mod:`pimpm.surfaces`). The
normal condition is a penalty p = -k_n phi with k_n = contact_stiffness x
(largest P-wave modulus) / h, so the tool penetrates the body by p h /
(contact_stiffness M): 1/contact_stiffness of a cell at a pressure equal
to the P-wave modulus. Friction is Coulomb's law regularized by an
elastic slip of at most a thousandth of a cell, carried from step to step
with the particles. The kernels are in :mod:`pimpm.kernels.contact`.

The tool moves as a bonded body does: its velocity times a function of
time; its own particles only show it (they prescribe nothing)."""
import numpy as np
from mpi4py import MPI

from .. import surfaces
from ..errors import StepFailed
from ..functions import ONE, lookup
from ..kernels import contact as kernels
from .base import NodalTerm, moves_free_dofs

#: the particle fields the contact of tool ``i`` carries: each corner's elastic
#: slip, and whether it was in contact at the end of the last step
SLIP_FIELD = "contact_slip_{}"
#: what the explicit step applied at its trial state: the forces it reports
APPLIED = ("force", "pressure", "traction", "corner_force")
#: the explicit step's stick length, in cells: so short that a sticking point's
#: stiffness is always the cap (the explicit penalty), see ContactTool._evaluate_with
STICK_EXPLICIT = 1e-9
#: each corner's state at the end of the last step (kernels.contact OPEN, STICK or SLIP)
TOUCHING_FIELD = "contact_touching_{}"
#: each corner's penetration at the end of the last step (p / k_n; 0: open): the
#: depth the next step's predictor keeps (ContactTool.predict)
DEPTH_FIELD = "contact_depth_{}"


def geometry_code(geometry, dim, h):
    """(kind, params) of :func:`pimpm.kernels.contact.tool_distance` for a
    body's validated geometry (``h``: the cell size)."""
    params = np.zeros(12)
    params[11] = 1e-3 * h          # how far beyond a face's edge a point still meets the face
    kind = geometry["type"]
    if kind in ("surface", "mesh"):             # the facets of a surface mesh or a mesh's boundary
        return kernels.MESH, surfaces.surface_params(geometry, dim, params[11])
    if kind == "half_space":
        params[:dim] = geometry["point"]
        params[3:3 + dim] = geometry["normal"]
        return kernels.HALF_SPACE, params
    if kind == "box":
        params[:dim] = geometry["lower"]
        params[3:3 + dim] = geometry["upper"]
        return kernels.BOX, params
    if kind == "ball":
        params[:dim] = geometry["center"]
        params[6] = geometry["radius"]
        return kernels.BALL, params
    if kind == "cylinder":
        params[:3] = geometry["lower"]
        params[3:6] = geometry["upper"]
        params[6] = geometry["radius"]
        params[7] = "xyz".index(geometry["axis"])
        params[8:11] = geometry["center"]
        return kernels.CYLINDER, params
    raise ValueError(f"no contact geometry for a {kind} tool")


class ContactTool(NodalTerm):
    #: the tangent of the contact term couples each particle's footprint nodes
    couples_particles = True
    contact_kind = "tool"

    def __init__(self, index, name, geometry, dim, h, velocity, stiffness, friction_coefficient=None,
                 function=ONE, axisymmetric=False, slip_tolerance=1e-3, tangential_stiffness=0.0, tied=False):
        self.index = index
        self.name = name
        self.kind, self.params = geometry_code(geometry, dim, h)
        self.dim = dim
        self.velocity = np.asarray(velocity, dtype=float)
        self.function = function
        self.kn = float(stiffness)                   # the normal penalty per unit area
        self.stick = slip_tolerance * h              # the elastic slip of a sticking point (at least)
        self.kt = float(tangential_stiffness)        # the cap of the tangential stiffness per area
        self.friction = friction_coefficient is not None or tied
        self.tied = bool(tied)
        self.mu = float(friction_coefficient or 0.0)
        self.axisymmetric = axisymmetric
        #: the tangent is symmetric without friction (the penalty has a potential)
        self.symmetric_tangent = not self.friction
        self.h = h
        self.field = SLIP_FIELD.format(index)
        self.touching_field = TOUCHING_FIELD.format(index)
        self.depth_field = DEPTH_FIELD.format(index)
        #: the particle fields of the last step's contact state and force, for the output
        self.output_fields = (f"contact_status_{index}", f"contact_force_{index}")
        self.offset = np.zeros(dim)                  # the tool's displacement so far
        self.dissipation = 0.0                       # the frictional dissipation so far
        self._increment = np.zeros(dim)
        self._step = None
        self._u = None
        self.last = {}

    @classmethod
    def from_config(cls, index, body, config, functions=None):
        dim = config["dim"]
        grid = config["grid"]
        h = min((u - lo) / n for lo, u, n in zip(grid["lower"], grid["upper"], grid["cells"]))
        modulus = max(m["bulk_modulus"] + 4.0 / 3.0 * m["shear_modulus"]
                      for m in config["materials"].values())
        friction = {}
        if body["contact"] == "tied":
            friction = {"tied": True, "tangential_stiffness": body["tangential_stiffness"] * modulus / h}
        elif body["contact"] == "friction":
            friction = {"friction_coefficient": body["friction_coefficient"],
                        "slip_tolerance": body["slip_tolerance"],
                        "tangential_stiffness": body["tangential_stiffness"] * modulus / h}
        return cls(index, body["name"], body["geometry"], dim, h, body["velocity"],
                   body["contact_stiffness"] * modulus / h, function=lookup(functions or {}, body.get("function")),
                   axisymmetric=config["kinematics"] == "axisymmetric", **friction)

    # ----------------------------------------------------------------- the step
    def begin_step(self, context):
        self._increment = self.velocity * self.function.integral(context.time, context.time + context.dt)
        particles = context.particles
        self._x = particles["x"]
        self._half = context.half_sizes()
        self._history = particles[self.field]
        self._density = particles["mass"] / particles["volume0"]
        self._grid, self._comm = context.grid, context.grid.comm
        self._touching = particles[self.touching_field]
        self._depth = particles[self.depth_field]
        self._step = None
        self._u = None
        self._rest_start = None      # the guess of a tied tool's start from rest (:meth:`predict`)

    def begin_newton(self, state):
        """The candidates (the particles whose domains can reach the tool
        this step: their centres within the tool's travel plus two cells plus
        their half diagonal of it) and their corners' weights, offsets and
        areas on the step's footprint (after the weak-node extension changed
        it). Only candidates are in contact: a corner extrapolated from a
        particle far from the tool into a barely supported node could
        otherwise be thrown into the tool by a Newton trial step (the
        frictional upsetting's outer surface at mid-height did)."""
        distance = np.empty(len(self._x))
        kernels.particle_distances(self.kind, self.params, state.node_index, state.S, self._x,
                                   np.zeros((self._grid.n_local_nodes, self.dim)), self.offset, distance)
        reach = float(np.linalg.norm(self._increment)) + 2.0 * self.h + np.linalg.norm(self._half, axis=1)
        self._candidates = np.flatnonzero(distance < reach)
        self._others = np.flatnonzero(~(distance < reach))
        c = self._candidates
        node_index, S, G, active = state.node_index[c], state.S[c], state.G[c], state.active[c]
        x, half = self._x[c], self._half[c]
        n, nn = S.shape
        corners = 1 << self.dim
        W = np.empty((n, corners, nn))
        offsets = np.empty((n, corners, self.dim))
        kernels.corner_weights(node_index, S, G, half, W, offsets)
        area = np.empty((n, corners))
        faces = np.empty(n, dtype=np.int64)
        # the face a particle meets the tool through: the side of the tool it is on at the
        # start of the step (a platen thinner than its step's travel would otherwise push
        # the particles it overtakes out through its far face)
        kernels.contact_faces(self.kind, self.params, x, self.offset, faces)
        kernels.corner_areas(self.kind, self.params, x, offsets, half,
                             self.offset + self._increment, self.axisymmetric, faces, area)
        self._faces = faces
        # a corner resting on a frictional tool deeper than the stick length keeps its
        # depth in the predictor (:meth:`predict`)
        depth = self._depth[c]
        self._start_depth = np.where(depth > self.stick, -depth, 0.0) if self.friction else np.zeros((n, corners))
        self._cand = {"node_index": node_index, "active": active, "x": x, "history": self._history[c], "S": S, "G": G}
        self._step = (state, W, offsets, area)
        self._u = None
        # the first Jacobian holds the corners that were touching (kernels.contact.HELD),
        # tangentially too where they stuck
        self._held = self._touching[c].copy()        # (its status then: STICK or SLIP)
        if self.tied:       # a tied tool holds the corners that touch it at the start of the step too
            gap = np.empty(n * corners)
            at_start = (x[:, None, :] + offsets - self.offset).reshape(-1, self.dim)
            kernels.point_distances(self.kind, self.params, at_start, gap)
            self._held[gap.reshape(n, corners) <= self.stick] = kernels.STICK
        self._holding = bool(np.any(self._held))

    def _evaluate(self, u_local, applied=None):
        """The corners at the iterate ``u_local`` (ghosted-local; cached per
        iterate: ``self._u`` is the iterate of ``self._local``); ``applied``:
        each corner's pressure instead of the penalty's (the explicit step's
        :meth:`settle`; not cached)."""
        if applied is None and self._u is not None and np.array_equal(self._u, u_local):
            return self._local
        state, W, offsets, area = self._step
        if self._rest_start is not None and np.array_equal(u_local, self._rest_start):
            # a tied tool's start from rest: the held corners alone (:meth:`predict`)
            area = np.where(self._held != kernels.OPEN, area, 0.0)
        n, corners = area.shape
        force = np.zeros((self._grid.n_local_nodes, self.dim))
        D = np.empty((n, corners, self.dim, self.dim))
        status = np.empty((n, corners), dtype=np.int8)
        pressure = np.empty((n, corners))
        traction = np.empty((n, corners, self.dim))
        elastic = np.empty((n, corners, self.dim))
        dissipation = np.empty((n, corners))
        corner_force = np.empty((n, corners, self.dim))
        held = self._held if (self._holding or self.tied) else np.zeros_like(self._held)
        cand = self._cand
        kernels.contact_forces(self.kind, self.params, cand["node_index"], cand["S"], cand["G"], W, cand["x"],
                               offsets, u_local, self.offset + self._increment, self._increment,
                               cand["history"], area, self._faces, self.kn, self.stick, self.kt, self.mu,
                               self.friction, held, force, D, status, pressure, traction, elastic,
                               dissipation, corner_force,
                               np.full((n, corners), -1.0) if applied is None else applied,
                               self.tied)
        self._local = {"force": force, "D": D, "status": status, "pressure": pressure,
                       "traction": traction, "elastic": elastic, "dissipation": dissipation,
                       "corner_force": corner_force}
        self._u = u_local.copy() if applied is None else None
        return self._local

    def add_residual(self, u_owned, u_local, residual, grid):
        """The force on the body enters the residual as an external force
        does (-f). Collective."""
        local = self._evaluate(u_local)
        residual -= grid.sum_to_owned(local["force"])

    def _first_jacobian_done(self):
        """Holding is for the step's first Jacobian only: later iterates are
        evaluated without it (the residual never depends on it)."""
        if self._holding:
            self._holding = False
            self._u = None

    def add_jacobian_values(self, u_local, grid, pattern, values):
        local = self._evaluate(u_local)
        W, cand = self._step[1], self._cand
        kernels.contact_blocks(cand["node_index"], cand["active"], W, local["D"], local["status"],
                               grid.ghost_ijk, pattern.width, pattern.indptr, pattern.slot_position,
                               values)
        self._first_jacobian_done()

    def add_product(self, u_local, grid, x_local, out_local):
        self._first_jacobian_done()          # the matrix-free product is always the exact one
        local = self._evaluate(u_local)
        kernels.contact_product(self._cand["node_index"], self._step[1], local["D"], local["status"], x_local,
                                out_local)

    def add_diagonal(self, u_local, grid, out_local):
        self._first_jacobian_done()
        local = self._evaluate(u_local)
        kernels.contact_diagonal(self._cand["node_index"], self._step[1], local["D"], local["status"], out_local)

    def predict(self, u_owned, grid, fixed):
        """The contact predictor: the Newton guess ``u_owned`` with the
        nodes under corners that it pushes into the tool by more than the
        stick length (a thousandth of a cell) beyond their depth at the start
        of the step moved back out to that depth along the tool's normal
        (each node by the |w|-weighted mean of its corners' way out;
        prescribed dofs kept). Only the guess: the converged answer does not
        depend on it. A platen that moves half a cell into a body at rest
        otherwise starts Newton with a penalty force of k_n h / 2 per area
        (1e7 times the flow stress in the upsetting), and the first steps
        inverted particles.

        The depth kept: a frictional tool's corner that rested deeper than
        the stick length at the end of the last step (its p / k_n) keeps that
        depth; every other corner is pushed out to the surface. Pushing the
        deep ones out too threw their pressure away, so the first iterate let
        them slip, and Newton found the stick zone again a few corners an
        iteration (the 0.5 cm frictional billet, mu = 0.3, 2 ranks: 280
        Newton iterations, 236 now; docs/PERFORMANCE.md). Keeping every
        frictional corner's depth (p / k_n below the stick length too: the
        steel of the upsetting rests 4e-5 cells deep) took 220 there, but
        the first Newton direction then met the slip tangent's coupling
        mu k_n e n^T at corners over weakly held nodes and inverted
        particles (the 1 mm upsetting with linear shape functions and
        mu = 0.1 failed; with GIMP and mu = 0.3 a step was cut); without
        friction the pressure comes back in one iteration, and keeping it
        tipped two marginal runs the other way (the frictionless upsetting
        at 2 mm with linear shape functions failed; the plate that lets go
        at 0.05 m and dt = 0.5 took a cut). A tied tool keeps a guess that
        moves no free dof (a body at rest): Newton's first iterate from it is
        the body's linearized response to the held corners' motion (the tied
        law is linear at a held corner), as the bonded tools' linear predictor
        (:meth:`pimpm.solver.NewtonSolver.linear_predictor`), where the
        push-out put the whole increment into the cell layer under the tool:
        the 0.5 mm 3D upsetting's first step then took one cut, not two
        (and none once only the held corners count at that guess). At that
        guess only the held corners are in contact (:meth:`_evaluate`):
        the tool has moved past the corners inside the body below them by
        up to its travel, and their penalty crushed the layer under it (the
        1 mm 3D upsetting, half a cell of travel: nodes a cell below the
        platen moved 0.4 mm up, a particle to J = 0.12, and the step was cut;
        with the held corners alone no cut up to a whole cell).
        Keeping every step's guess cut fewer steps there too, but the 0.25
        mm axisymmetric upsetting then failed at 59.6%. Collective."""
        if self.tied and not moves_free_dofs(u_owned, fixed, self._comm):
            self._rest_start = grid.owned_to_local(u_owned)
            self._u = None
            return u_owned
        state, W, offsets, area = self._step
        moved = np.zeros((grid.n_local_nodes, self.dim))
        weight = np.zeros(grid.n_local_nodes)
        kernels.push_out(self.kind, self.params, self._cand["node_index"], W, self._cand["x"], offsets,
                         grid.owned_to_local(u_owned), self.offset + self._increment, self._faces,
                         self._start_depth, self.stick, moved, weight)
        moved = grid.sum_to_owned(moved)
        weight = grid.sum_scalar_to_owned(weight)             # repeated per component
        push = np.where(weight > 0.0, moved / np.where(weight > 0.0, weight, 1.0), 0.0)
        return np.where(fixed, u_owned, u_owned + push)

    def add_explicit_force(self, velocity, dt, force, mass=None):
        """The same law in the explicit step, at the step's trial state: the
        corners moved by dt times the grid velocity the step would reach
        without contact (v + dt (Fext - Fint) / m), their contact forces
        added to ``force`` (the next step starts from where they left the
        corners' elastic slip). An explicit penalty must not outrun the step:
        its stiffness is at most half of rho 2 l / dt^2 (the stiffness that
        would undo a corner's penetration over one step on its particle's
        mass per area of its face: rho the least density, l the least half
        size), below which it keeps the implicit one. Collective."""
        if mass is None:
            raise ValueError("contact in the explicit step needs the nodal mass")
        has_mass = mass > 0.0
        trial = dt * (velocity + dt * np.where(has_mass, force / np.where(has_mass, mass, 1.0), 0.0))
        kn = self.kn
        if len(self._candidates):
            density = float(np.min(self._density[self._candidates]))
            reach = 2.0 * float(np.min(self._half[self._candidates]))
            kn = min(kn, 0.5 * density * reach / dt ** 2)
        self._explicit_kn = self._comm.allreduce(kn, op=MPI.MIN)
        local = self._evaluate_with(self._explicit_kn, self._grid.owned_to_local(trial))
        force += self._grid.sum_to_owned(local["force"])
        self._applied = {key: local[key].copy() for key in APPLIED}

    def _evaluate_with(self, kn, u_local, applied=None):
        """The explicit step's evaluation: penalty ``kn`` and a sticking
        point's tangential stiffness kn as well (an elastic slip of at most
        mu p / kn). The implicit regularization, an elastic slip of a
        thousandth of a cell, is about five explicit steps of the ramp's
        sliding block: each corner that came into contact stuck at a fraction
        of mu p while it built up, and the block slid 16% too fast."""
        saved = self.kn, self.kt, self.stick
        self.kn, self.kt, self.stick = kn, kn, STICK_EXPLICIT * self.h
        try:
            return self._evaluate(u_local, applied)
        finally:
            self.kn, self.kt, self.stick = saved

    def settle(self, u_local):
        """The explicit step's corners where the step really took them
        (``u_local``: dt times the new grid velocity, ghosted-local), pressed
        with the pressures the step applied: the elastic slips and states the
        next step starts from, and Coulomb's dissipation over the slip the
        step really made. The forces reported are those applied.
        (The trial state of :meth:`add_explicit_force` would store the slip
        the step would have made without friction: a sticking block's elastic
        slip would grow by dt^2 g every step until it slipped. And the
        penalty's pressure where the corner is now is what the step left of
        the penetration, about half the applied one: Coulomb's limit on it let
        the ramp's block slip 10-60% too easily.)"""
        local = self._evaluate_with(self._explicit_kn, u_local, self._applied["pressure"])
        local.update(self._applied)

    def increment(self):
        return self._increment

    def particle_displacement(self, rigid):
        return np.where((rigid["body"] == self.index)[:, None], self._increment, 0.0)

    # ----------------------------------------------------------------- after convergence
    def report(self, forces, comm, explicit=False):
        """The converged step's contact force on the material (into
        ``forces``, by name) and its summary: normal and tangential force,
        contact area, corners in contact (``self.last``). StepFailed on every
        rank if a particle that was not a candidate ends the step with its
        centre inside the tool (it came more than two cells in one step).
        Collective."""
        local = self._local
        state, others = self._step[0], self._others
        reached = 0
        if len(others) and not explicit:     # an explicit step moves nothing a cell
            distance = np.empty(len(others))
            kernels.particle_distances(self.kind, self.params, state.node_index[others], state.S[others],
                                       self._x[others], self._u, self.offset + self._increment,
                                       distance)
            reached = int(np.sum(distance < 0.0))
        if comm.allreduce(reached):
            raise StepFailed(f"particles reached the tool {self.name} from more than two cells away in "
                             "one step: expected a smaller step")
        area = self._step[3]
        touching = self._in_contact(local)
        n_force = np.sum(area * local["pressure"])
        t_force = np.sum(area[..., None] * local["traction"], axis=(0, 1))
        # this rank's corners' force on the body: the weights of a corner sum to one
        # (partition of unity), so the sum over its local nodes is the sum over its corners
        total = np.sum(local["force"], axis=0)
        dim = self.dim
        sums = comm.allreduce(np.concatenate([
            total, [n_force, float(np.sum(area[touching])), float(np.sum(touching)),
                    float(np.sum(local["dissipation"]))], t_force]), op=MPI.SUM)
        forces[self.name] = sums[:dim]
        self.last = {"normal_force": float(sums[dim]), "contact_area": float(sums[dim + 1]),
                     "contact_points": int(round(sums[dim + 2])),
                     "tangential_force": float(np.linalg.norm(sums[dim + 4:])),
                     "step_dissipation": float(sums[dim + 3])}

    def _in_contact(self, local):
        """The corners in contact: those that press, and a tied tool's
        corners that it holds (pulling too)."""
        if self.tied:
            return local["status"] == kernels.STICK
        return local["pressure"] > 0.0

    def commit(self, particles):
        """The converged step: the tool moves on, the corners keep their
        elastic slip (particle order is the step's: before migration)."""
        c = self._candidates                 # the others are not in contact: zero
        status = self._local["status"]
        fields = {self.field: self._local["elastic"],
                  self.touching_field: np.where((status == kernels.STICK) | (status == kernels.SLIP), status,
                                                kernels.OPEN).astype(np.int8),
                  self.depth_field: self._local["pressure"] / self.kn,
                  # what the output shows of the step: each particle's state (0 open, 1 stick,
                  # 2 slip: of its corners that press, the one that slips wins) and the force on it
                  self.output_fields[0]: np.max(np.where(self._in_contact(self._local), status, kernels.OPEN),
                                                axis=1, initial=0).astype(np.int8),
                  self.output_fields[1]: np.sum(self._local["corner_force"], axis=1)}
        for name, values in fields.items():
            full = np.zeros_like(particles[name])
            full[c] = values
            particles[name] = full
        self.offset = self.offset + self._increment
        self.dissipation += self.last.get("step_dissipation", 0.0)

    def end_newton(self):
        """Drop the step's candidates, corner weights (8 x 27 values a
        candidate in 3D with GIMP) and iterate, and the last step's particle
        arrays (:meth:`begin_step`)."""
        self._x = self._half = self._history = self._density = self._touching = self._depth = None
        self._step = self._cand = self._local = self._u = self._held = None
        self._candidates = self._others = self._faces = self._start_depth = self._rest_start = None

    def state(self):
        return {"offset": [float(v) for v in self.offset], "dissipation": self.dissipation}

    def restore(self, state):
        offset = np.asarray(state["offset"], dtype=float)
        if offset.shape != self.offset.shape or not np.all(np.isfinite(offset)):
            raise ValueError(f"offset {state['offset']!r}: expected {len(self.offset)} finite numbers")
        self.offset = offset
        self.dissipation = float(state.get("dissipation", 0.0))
