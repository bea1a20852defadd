"""The matrix-free tangent (Sulsky & Kaul 2.4.4): the context of a PETSc
shell matrix whose product is the analytic directional derivative of the
residual, computed particle by particle without storing a matrix
(:func:`pimpm.kernels.particle_step.tangent_product`)."""
import numpy as np

from ..kernels import fbar as fbar_kernels
from ..kernels import particle_step
from .momentum import projection_diagonal
from ..fbar import cell_box_side, check_cell_boxes, check_node_boxes

_NO_RADIUS = np.zeros(0)


class TangentShell:
    """Context of a shell matrix: y = K x with K the exact tangent at the
    current Newton iterate (material + geometric + 4/dt^2 M, prescribed dofs
    eliminated), computed particle by particle without storing a matrix:

        (K x)_ia = sum_p v_p g_ic a_acbd H_bd,   H = sum_j x_j (x) g_j

    (the analytic directional derivative of the residual, cf. Sulsky & Kaul
    eq. 2.4.18 which approximates it by a finite difference), from the
    stiffness densities the particle evaluation of the iterate computed."""

    def __init__(self, grid, terms=()):
        self.grid = grid
        self.terms = list(terms)
        self.state = None
        self.evaluation = None  # pimpm.implicit.problem.ParticleEvaluation of the iterate
        self.scale = 1.0        # residual scale (dimensionless residual)
        self.project = None     # momentum formulation: x -> R x
        self.u = None           # the iterate
        self.node_coupling = None

    def release(self):
        """Drop the step's state and iterate (:meth:`update` sets them again)."""
        self.state = self.evaluation = self.node_coupling = None
        self.u = self.u_local = None

    def _term_blocks(self):
        """The nodal terms' derivative blocks at the iterate (pimpm.terms)."""
        blocks = (term.jacobian_blocks(self.u) for term in self.terms)
        return [b for b in blocks if b is not None]

    def update(self, state, evaluation, scale, project=None, u_owned=None, u_local=None):
        """``project`` (momentum formulation): owned u -> (owned, local) R u;
        ``u_owned``: the iterate (the nodal terms' derivatives are taken there)."""
        self.project = project
        self.u = u_owned
        self.u_local = u_local
        self.state = state
        self.evaluation = evaluation
        self.scale = scale
        cells = state.cells
        # F-bar on the nodes: its coupling's (R, D), summed over the ranks once per iterate (collective)
        self.node_coupling = (evaluation.node_coupling(state) if cells is not None and cells.kind == "nodes"
                              else None)

    def _add_coupled(self, apply, out):
        """Add the particle-coupled terms' share (``apply(term, out_local)``)
        to ``out`` (owned dofs). Collective when there are such terms."""
        coupled = [term for term in self.terms if term.couples_particles]
        if coupled:
            local = np.zeros((self.grid.n_local_nodes, self.grid.dim))
            for term in coupled:
                apply(term, local)
            out += self.grid.sum_to_owned(local)

    def _kernel_arguments(self):
        st, ev = self.state, self.evaluation
        return (st.kinematics.kernel_code, tuple(range(self.grid.dim)), tuple(range(st.S.shape[1])),
                st.node_index, st.active, st.S, st.G, st.radius if st.radius is not None else _NO_RADIUS,
                ev.F_inc, ev.tangent, ev.hoop)

    def _cell_arguments(self):
        """The F-bar cell coupling's kernel arguments (pimpm.kernels.fbar),
        or None without averaged cells on this rank."""
        st, ev = self.state, self.evaluation
        cells = st.cells
        if cells is None or not cells.count or cells.kind == "nodes":
            return None
        return (st.kinematics.kernel_code, tuple(range(self.grid.dim)), cell_box_side(st), cells.order,
                cells.start, st.node_index, st.active, st.S, st.G,
                st.radius if st.radius is not None else _NO_RADIUS, ev.F_inc, ev.fbar_q, ev.fbar_weight,
                self.grid.ghost_ijk)

    def mult(self, mat, x, y):
        st, grid = self.state, self.grid
        xs = x.getArray(readonly=True).copy()
        fixed = st.fixed
        xs_free = np.where(fixed, 0.0, xs)
        # K R x in the momentum formulation (prescribed rows of R x stay 0)
        x_local = grid.owned_to_local(xs_free) if self.project is None else self.project(xs_free)[1]
        local = np.empty((grid.n_local_nodes, grid.dim))
        particle_step.tangent_product(*self._kernel_arguments(), x_local, local)
        cell = self._cell_arguments()
        if cell is not None:
            check_cell_boxes(fbar_kernels.cell_product(*cell, x_local, local))
        if self.node_coupling is not None:
            cells = st.cells
            check_node_boxes(fbar_kernels.node_product(cells.half, cells.centres, *self.node_coupling,
                                                       *cells.ghost_shape(), x_local, local))
        out = grid.sum_to_owned(local)
        if st.integrator.stiffness_factor != 1.0:       # HHT: (1 + alpha) K
            out *= st.integrator.stiffness_factor
        if st.dynamic:
            out += st.mass_coefficient * st.mass * xs_free
        self._add_coupled(lambda term, out_local: term.add_product(self.u_local, grid, x_local, out_local),
                          out)
        for nodes, blocks in self._term_blocks():
            x_nodes = xs_free.reshape(-1, grid.dim)[nodes]
            np.add.at(out.reshape(-1, grid.dim), nodes, np.einsum("kab,kb->ka", blocks, x_nodes))
        out[fixed] = st.constraint_scale * xs[fixed]
        y.getArray()[:] = out / self.scale

    def getDiagonal(self, mat, d):
        st, grid = self.state, self.grid
        local = np.empty((grid.n_local_nodes, grid.dim))
        particle_step.tangent_diagonal(*self._kernel_arguments(), local)
        cell = self._cell_arguments()
        if cell is not None:
            check_cell_boxes(fbar_kernels.cell_diagonal(*cell, local))
        if self.node_coupling is not None:
            cells = st.cells
            check_node_boxes(fbar_kernels.node_diagonal(cells.half, cells.centres, *self.node_coupling,
                                                        *cells.ghost_shape(), local))
        out = grid.sum_to_owned(local)
        if self.project is not None:             # (collective: every rank takes this branch)
            # momentum formulation: diag(K) diag(R), a Jacobi approximation of diag(K R)
            out *= projection_diagonal(st, grid)
        if st.integrator.stiffness_factor != 1.0:
            out *= st.integrator.stiffness_factor
        if st.dynamic:
            out += st.mass_coefficient * st.mass
        self._add_coupled(lambda term, out_local: term.add_diagonal(self.u_local, grid, out_local), out)
        for nodes, blocks in self._term_blocks():
            np.add.at(out.reshape(-1, grid.dim), nodes, np.diagonal(blocks, axis1=1, axis2=2))
        out[st.fixed] = st.constraint_scale
        d.getArray()[:] = out / self.scale
