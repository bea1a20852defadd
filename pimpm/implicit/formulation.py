"""The two formulations of the implicit step, as objects chosen by
``time.formulation``: what deforms the particles, and what that makes of
the tangent. The step problem (:mod:`.problem`) and the matrix-free
tangent (:mod:`.shell`) ask the run's formulation instead of testing a
flag.

* :class:`VelocityFormulation` (Guilkey & Weiss): the particles are deformed
  by the grid displacement u itself; the tangent is d Fint / du = K,
  symmetric for hyperelastic materials, assembled on each step's particle
  pattern through COO values.
* :class:`MomentumFormulation` (Sulsky & Kaul 3.2.1): the particles are
  deformed by the mass-weighted projection R u of their own displacements
  (eq. 3.2.7, :mod:`.momentum`); the tangent is K R, not symmetric, on the
  DMDA's full stencil.
"""
from petsc4py import PETSc

from .momentum import assemble_projection, group_by_node_set, project_displacement


class VelocityFormulation:
    name = "velocity"
    #: why this formulation's tangent is not symmetric ("" if it is)
    asymmetry = ""
    #: the tangent is a matrix on the step's own pattern, made anew per step
    assembles_on_pattern = True

    def begin_step(self, state, grid):
        """Prepare what the step's Newton iterations need (nothing here)."""

    def kinematic_displacement(self, state, grid, u_owned, u_local):
        """The ghosted-local displacement that deforms the particles: u."""
        return u_local

    def projector(self, state, grid):
        """x -> (owned, local) R x for the matrix-free product, or None (R = 1)."""
        return None

    def create_matrix(self, da):
        """The tangent when it is not made on the step's pattern (never here)."""
        raise NotImplementedError("the velocity formulation's tangent is made on the step's pattern")

    def stiffness_matrix(self, P):
        """The matrix the particles' stiffness K is assembled into: the tangent itself."""
        return P

    def finish_stiffness(self, state, P, diag, row_offset, dim):
        """Turn the assembled K into the tangent's stiffness part (it is already)."""

    def destroy(self):
        pass


class MomentumFormulation:
    name = "momentum"
    asymmetry = "time.formulation: momentum (its tangent K R is not symmetric)"
    assembles_on_pattern = False        # K R keeps the DMDA's (wider) pattern

    def __init__(self):
        self.K = self.projection = None

    def begin_step(self, state, grid):
        """The projection's blocks: particles grouped by the nodes they touch
        (once per step: the problem begins a step more than once)."""
        if state.group_order is not None:
            return
        order, starts = group_by_node_set(state.node_index, grid.n_local_nodes)
        state.group_order, state.group_starts = order, starts
        state.group_nodes = state.node_index[order][starts]

    def kinematic_displacement(self, state, grid, u_owned, u_local):
        """R u about the integrator's free flight (eq. 3.2.7)."""
        if state.projection_base is None:
            base = state.free_flight()
            state.projection_base = (base, grid.owned_to_local(base))
        return project_displacement(state, grid, u_owned, u_local, state.projection_base)[1]

    def projector(self, state, grid):
        return lambda v: project_displacement(state, grid, v, grid.owned_to_local(v))

    def create_matrix(self, da):
        """K and R on the DMDA's full stencil, fixed once, and their product."""
        self.K = da.createMat()
        self.K.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
        self.projection = da.createMat()
        self.projection.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
        self.projection.setOption(PETSc.Mat.Option.KEEP_NONZERO_PATTERN, True)
        return self.K.matMult(self.projection)

    def stiffness_matrix(self, P):
        return self.K

    def finish_stiffness(self, state, P, diag, row_offset, dim):
        """P = K R (d Fint / du through the projection). Collective."""
        assemble_projection(state, self.projection, diag, row_offset, dim)
        self.K.matMult(self.projection, result=P)

    def destroy(self):
        for obj in (self.K, self.projection):
            if obj is not None:
                obj.destroy()
        self.K = self.projection = None


#: ``time.formulation`` -> its class
FORMULATIONS = {f.name: f for f in (VelocityFormulation, MomentumFormulation)}


def make_formulation(name):
    return FORMULATIONS[name]()
