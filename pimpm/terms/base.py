"""The interface of a nodal term: a contribution to a step that is not a
particle's (a rigid body bonded to the material today; unilateral and
frictional contact, penalties, stabilisations next). The steps call every
term of the run at the same places:

* :meth:`NodalTerm.begin_step` once per step, before the constraints are
  built (collective: a term may sum over ranks);
* :meth:`NodalTerm.prescribed`: the owned dofs it prescribes this step and
  their incremental displacements (the constraints of G&W step 2; later
  terms win over earlier ones, grid faces over all);
* :meth:`NodalTerm.add_residual` and :meth:`NodalTerm.jacobian_blocks`
  inside Newton: its force on the owned dofs at an iterate (force units,
  before the residual's scaling) and its derivative there as dim x dim
  blocks on owned nodes' diagonals, which the step's tangent pattern always
  holds (:meth:`pimpm.implicit.state.TangentPattern.block_positions`), so a
  term adds no nonzero to the matrix; the matrix-free product applies them too;
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

class StepContext:
    """What a term sees of the step being set up: the grid, the shape
    functions, the rigid particles, the start of the step and its size."""

    def __init__(self, grid, shape, rigid, time, dt):
        self.grid, self.shape, self.rigid, self.time, self.dt = grid, shape, rigid, time, dt


class NodalTerm:
    """Base: a term that contributes nothing (each method says what a
    subclass may add)."""

    #: the term's name (the history's force columns)
    name = "term"

    def begin_step(self, context):
        """Set the step up (``context``: a :class:`StepContext`). Collective."""

    def prescribed(self):
        """(owned dof mask, incremental displacement per owned dof) this step,
        or None."""
        return None

    def add_residual(self, u_owned, residual):
        """Add the term's force at the iterate ``u_owned`` to ``residual``
        (owned dofs, force units)."""

    def jacobian_blocks(self, u_owned):
        """The derivative of :meth:`add_residual` at the iterate ``u_owned``:
        (owned node indices (k,), blocks (k, dim, dim)), or None."""
        return None

    def add_explicit_force(self, velocity, dt, force):
        """Add the term's force on the owned dofs to ``force`` (the external
        minus internal force of the explicit step's eq. 1) from the grid
        velocity at t (owned dofs)."""

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
