"""What stays fixed while Newton iterates on one implicit step (G&W 3.3
steps 1-2): the particle footprint on the reset grid, the grid state
interpolated from the particles, the constraints, the integrator and the
kinematics of the step."""
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np


@dataclass
class StepState:
    dt: float
    integrator: object            # pimpm.integrators.*: inertia, predictor, particle update
    kinematics: object            # pimpm.kinematics.*: increment, material point, hoop terms
    node_index: np.ndarray        # (n, nn) ghosted-local node of each (particle, node) pair
    S: np.ndarray                 # (n, nn) weights at x_p(t)
    G: np.ndarray                 # (n, nn, dim) gradients at x_p(t)
    F_n: np.ndarray               # (n, 3, 3) deformation gradient at t
    volume_n: np.ndarray          # (n,) volume at t
    material_groups: list         # [(material, particle index array)]
    materials: object             # pimpm.materials.table.MaterialTable: the kernels' view
    history_packed: np.ndarray    # (n, width) material history at t, packed for the kernels
    active: np.ndarray            # (n, nn) footprint entries with a weight or a gradient
    pattern: object               # TangentPattern: the tangent's couplings this step
    mass: np.ndarray              # owned dofs: lumped nodal mass (repeated per component)
    velocity: np.ndarray          # owned dofs: v_g(t) (eq. 3)
    acceleration: np.ndarray      # owned dofs: a_g(t)
    external_force: np.ndarray    # owned dofs: Fext_g(t+dt) (eq. 4)
    fixed: np.ndarray             # owned dofs: bool, prescribed
    fixed_value: np.ndarray       # owned dofs: prescribed incremental displacement
    constraint_scale: float       # diagonal used for prescribed rows

    radius: np.ndarray = None     # axisymmetric: particle radius at t (None otherwise)
    history: dict = field(default_factory=dict)   # material history at t (per particle)
    particle_mass: np.ndarray = None  # (n,) particle masses (momentum formulation)
    projection_floor: float = 0.0     # nodes with no more mass keep their own u (momentum formulation)
    previous_force: np.ndarray = None  # owned dofs: Fint(t) - Fext(t), for integrators that use it (HHT)
    group_order: np.ndarray = None    # momentum formulation: particles sorted by the node set they touch
    group_starts: np.ndarray = None   # first particle of each group in that order
    group_nodes: np.ndarray = None    # (n_groups, nn) ghosted-local nodes of each group
    cells: object = None              # pimpm.fbar.AveragedCells: F-bar's cells (None: no F-bar)

    # made while Newton iterates on the step (pimpm.implicit.problem)
    evaluation: object = None             # ParticleEvaluation: the particles at the last iterate
    residual_evaluation: object = None    # the evaluation of the last residual (converged: the particle update's)
    projection_base: tuple = None         # momentum formulation: (owned, local) free flight u0
    constraint_positions: tuple = None    # COO positions of prescribed entries and diagonals
    tangent_values: np.ndarray = None     # the tangent's COO values, reused every iterate

    @property
    def dynamic(self):
        return self.integrator.dynamic

    @property
    def mass_coefficient(self):
        """d(inertia)/du per unit mass: 4/dt^2 (trapezoidal), 1/dt^2 (backward Euler)."""
        return self.integrator.mass_coefficient(self.dt)

    def grid_kinematics(self, u):
        """v_g(t+dt) and a_g(t+dt) for the incremental displacement u."""
        return self.integrator.grid_kinematics(u, self.velocity, self.acceleration, self.dt)

    def free_flight(self):
        """The part of u set by the grid state at t alone (owned dofs)."""
        return self.integrator.free_flight(self.velocity, self.acceleration, self.dt)

    def predictor(self):
        """The integrator's initial Newton guess for every dof (owned)."""
        return self.integrator.predictor(self.velocity, self.acceleration, self.dt)

    def own_value_dofs(self):
        """Owned dofs that the momentum formulation's projection leaves alone:
        prescribed ones and those of nodes with (next to) no mass. A particle
        within round-off of a cell face gives the node across it a mass of
        ~1e-16 m_p made of round-off: projecting onto it would divide noise by
        noise (and leave a numerically zero Jacobian column)."""
        return self.fixed | ~(self.mass > self.projection_floor)

    def committed_history(self, packed):
        """The history dict (name -> per-particle array) after the step, from
        the kernels' packed rows."""
        return self.materials.unpack(packed, self.history)

    def inertia(self, u):
        """M a(t+dt) as a function of u (G&W eq. 16 for the trapezoidal rule)."""
        return self.mass * self.grid_kinematics(u)[1]


@dataclass
class TangentPattern:
    """The couplings of the tangent in one step, from the particle
    footprints (:func:`pimpm.kernels.pattern.block_pattern`): a block CSR
    over the ghosted-local nodes, each block's (row, stencil slot)
    position, and the scalar CSR PETSc takes the values in."""
    width: int                   # largest node distance within a footprint, per axis
    indptr: np.ndarray
    indices: np.ndarray
    slot_position: np.ndarray
    scalar_indptr: np.ndarray
    scalar_indices: np.ndarray

    @cached_property
    def scalar_rows(self):
        """The scalar row (ghosted-local dof) of each value: with
        ``scalar_indices``, the values' (row, column) pairs."""
        return np.repeat(np.arange(len(self.scalar_indptr) - 1), np.diff(self.scalar_indptr))

    def block_positions(self, local_nodes, dim):
        """Positions in the scalar CSR values of the diagonal dim x dim block
        of each ghosted-local node in ``local_nodes`` (k, dim, dim): every
        owned node's diagonal block is in the pattern. Block k of node row i,
        entry (a, b), is value dim^2 indptr[i] + a L_i dim + k dim + b, L_i the
        row's number of blocks (:func:`pimpm.kernels.pattern.scalar_csr`)."""
        nodes = np.asarray(local_nodes, dtype=np.int64)
        centre = (self.slot_position.shape[1] - 1) // 2
        slot = self.slot_position[nodes, centre]
        if np.any(slot < 0):
            raise RuntimeError("a node's diagonal block is not in the tangent's pattern")
        start = self.indptr[nodes]
        length = self.indptr[nodes + 1] - start
        a = np.arange(dim)[None, :, None]
        b = np.arange(dim)[None, None, :]
        return (dim * dim * start[:, None, None] + a * (length * dim)[:, None, None]
                + ((slot - start) * dim)[:, None, None] + b)
