"""The interface of a nodal term: a contribution to a step that is not a
particle's (a rigid body bonded to the material today; unilateral and
frictional contact, penalties, stabilisations next). The steps call every
term of the run at the same places:

* :meth:`NodalTerm.begin_step` once per step, before the constraints are
  built (collective: a term may sum over ranks);
* :meth:`NodalTerm.prescribed`: the owned dofs it prescribes this step and
  their incremental displacements (the constraints of G&W step 2; later
  terms win over earlier ones, grid faces over all);
* :meth:`NodalTerm.begin_newton` once the step's footprint is final;
* :meth:`NodalTerm.add_residual` and :meth:`NodalTerm.jacobian_blocks`
  inside Newton: its force on the owned dofs at an iterate (force units,
  before the residual's scaling) and its derivative there as dim x dim
  blocks on owned nodes' diagonals, which the step's tangent pattern always
  holds (:meth:`pimpm.implicit.state.TangentPattern.block_positions`), so a
  term adds no nonzero to the matrix; the matrix-free product applies them too;
  a term whose derivative couples the nodes of each particle's footprint
  (``couples_particles``: contact at the particles' domain corners) adds
  its derivative itself (:meth:`NodalTerm.add_jacobian_values`,
  :meth:`NodalTerm.add_product`, :meth:`NodalTerm.add_diagonal`): the
  footprint couplings are in the pattern too;
* :meth:`NodalTerm.report` and :meth:`NodalTerm.commit` once the step has
  converged: its force on the material and what it keeps of the step;
* :meth:`NodalTerm.add_explicit_force` in the explicit step's grid update
  (MPM introduction eq. 1): its force on the owned dofs from the grid
  velocity at t;
* :meth:`NodalTerm.increment`: how far it moves over the step (the work it
  does is its force along it, :class:`pimpm.energy.WorkAccount`), and
  :meth:`NodalTerm.particle_displacement`: how its own particles move (the
  step moves them once it has succeeded);
* :meth:`NodalTerm.state` / :meth:`NodalTerm.restore` for checkpoints.

The force a prescribing term exerts on the material is the reaction on the
dofs it prescribes (:meth:`pimpm.bc.Constraints.reactions`)."""
import numpy as np


def moves_free_dofs(guess, fixed, comm):
    """Whether the step's Newton guess (owned dofs) moves any free dof on
    any rank: False for a body at rest when a tool starts to move.
    Collective."""
    return comm.allreduce(bool(np.any(np.where(fixed, 0.0, guess) != 0.0)))


class StepContext:
    """What a term sees of the step being set up: the grid, the shape
    functions, the rigid particles, the start of the step and its size."""

    def __init__(self, grid, shape, rigid, time, dt, particles=None, half_sizes=None):
        self.grid, self.shape, self.rigid, self.time, self.dt = grid, shape, rigid, time, dt
        #: the material particles, and a function giving their current GIMP domain half sizes
        self.particles, self.half_sizes = particles, half_sizes


class NodalTerm:
    """Base: a term that contributes nothing (each method says what a
    subclass may add)."""

    #: the term's name (the history's force columns)
    name = "term"
    #: does the term's derivative couple the nodes of each particle's footprint?
    couples_particles = False
    #: unilateral contact: "tool" (rigid tools), "pair" or "frictional pair"
    #: (between bodies), whose solver options it needs
    #: (pimpm.presets.CONTACT_OPTIONS); None otherwise
    contact_kind = None
    #: is the term's derivative symmetric?
    symmetric_tangent = True

    def begin_step(self, context):
        """Set the step up (``context``: a :class:`StepContext`). Collective."""

    def prescribed(self):
        """(owned dof mask, incremental displacement per owned dof) this step,
        or None."""
        return None

    def begin_newton(self, state):
        """The step's Newton state (a StepState) is made: its footprint is final."""

    def add_residual(self, u_owned, u_local, residual, grid):
        """Add the term's share of the residual at the iterate ``u_owned``
        (``u_local``: the same, ghosted-local) to ``residual`` (owned dofs,
        force units). Collective."""

    def predict(self, u_owned, grid, fixed):
        """The step's Newton guess ``u_owned`` as the term would improve it
        (owned dofs; ``fixed``: the prescribed ones, kept). Collective."""
        return u_owned

    def add_jacobian_values(self, u_local, grid, pattern, values):
        """``couples_particles``: add the derivative of :meth:`add_residual`
        into this rank's COO values of the step's ``pattern``."""

    def add_product(self, u_local, grid, x_local, out_local):
        """``couples_particles``: add the derivative times ``x_local`` (ghosted-local)."""

    def add_diagonal(self, u_local, grid, out_local):
        """``couples_particles``: add the derivative's diagonal (ghosted-local)."""

    def report(self, forces, comm, explicit=False):
        """The converged step: add the term's force on the material to
        ``forces`` (name -> vector) if it is not a reaction. Collective."""

    def settle(self, u_local):
        """The explicit step: where the step took the grid (dt times the new
        velocity, ghosted-local), before :meth:`report`."""

    def commit(self, particles):
        """The converged step: keep what the term carries to the next one."""

    def end_newton(self):
        """The implicit step is over (reported and committed, or failed):
        drop what :meth:`begin_step` and :meth:`begin_newton` kept of its
        particles, so that the next step's arrays are not made beside them."""

    def jacobian_blocks(self, u_owned):
        """The derivative of :meth:`add_residual` at the iterate ``u_owned``:
        (owned node indices (k,), blocks (k, dim, dim)), or None."""
        return None

    def add_explicit_force(self, velocity, dt, force, mass=None):
        """Add the term's force on the owned dofs to ``force`` (the external
        minus internal force of the explicit step's eq. 1) from the grid
        velocity at t (owned dofs; ``mass``: the nodal mass per dof, zero
        where there is none). Collective."""

    def increment(self):
        """The term's displacement over the step (dim,): zero if it does not move."""
        return None

    def particle_displacement(self, rigid):
        """The displacement of each rigid particle this term moves over the
        step (n_rigid, dim; zero for the others), or None."""
        return None

    def state(self):
        """What a checkpoint keeps of the term (JSON-able)."""
        return {}

    def restore(self, state):
        """Continue from :meth:`state`."""
