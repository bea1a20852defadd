"""The momentum formulation of Sulsky & Kaul (3.2.1): the particles are
deformed by the mass-weighted projection of the grid displacement, and its
derivative R enters the tangent as K R."""
import numpy as np
from petsc4py import PETSc

from ..transfer import grid_to_particle, particle_to_grid


def project_displacement(state, grid, u_owned, u_local, base=None):
    """The mass-weighted projection of the particle displacements,

        u~_i = u0_i + sum_p m_p N_ip du_p / m_i,   du_p = sum_j N_jp (u_j - u0_j),

    the displacement form of eq. 3.2.7: the grid velocity remapped from the
    updated particle velocities v_p + dt sum_i N_ip a_i (eq. 3.2.6), whose
    old part m_p v_p maps back to the grid velocity of eq. 3.2.3 unchanged.
    ``base`` = (owned, local) u0 is that old part (the integrator's free
    flight: dt v_g + dt^2/4 a_g for the trapezoidal rule, dt v_g for
    backward Euler, 0 in quasi-statics); None projects u itself (the linear
    map R of the Jacobian). A node that a particle has only just entered gets
    that particle's displacement instead of an unbalanced force over a tiny
    mass. Prescribed dofs, and nodes with no mass to speak of (a particle
    exactly on a cell face: the projection is 0/0), keep their own values
    (rows of R: identity). Returns owned and ghosted-local u~. Collective."""
    if base is not None:
        u_owned, u_local = u_owned - base[0], u_local - base[1]
    du = grid_to_particle(state.node_index, state.S, u_local)
    weighted = particle_to_grid(state.node_index, state.S, state.particle_mass[:, None] * du,
                                grid.n_local_nodes)
    keep = state.own_value_dofs()
    projected = grid.sum_to_owned(weighted) / np.where(keep, 1.0, state.mass)
    projected[keep] = u_owned[keep]
    if base is not None:
        projected += base[0]
    return projected, grid.owned_to_local(projected)


def assemble_projection(state, R, diag, row_offset, dim):
    """R = M^-1 S^T m S with identity rows at prescribed and massless dofs
    (the derivative of :func:`project_displacement`), into the DMDA matrix
    ``R``; ``diag`` is a work vector. Collective."""
    R.zeroEntries()
    if len(state.particle_mass):
        blocks = projection_blocks(state.particle_mass, state.S, state.group_order,
                                            state.group_starts, dim)
        nodes = state.group_nodes.astype(PETSc.IntType)
        R.setValuesBlockedLocalRCV(nodes, nodes, blocks.reshape(len(nodes), -1),
                                   addv=PETSc.InsertMode.ADD_VALUES)
    R.assemble()
    keep = state.own_value_dofs()
    diag.getArray()[:] = np.where(keep, 0.0, 1.0 / np.where(keep, 1.0, state.mass))
    R.diagonalScale(L=diag)
    rows = (np.nonzero(keep)[0] + row_offset).astype(PETSc.IntType)
    R.zeroRows(rows, diag=1.0)


def projection_diagonal(state, grid):
    """diag(R) on owned dofs (1 where the projection leaves a dof alone): a
    Jacobi approximation for the matrix-free preconditioner. Collective."""
    r_diag = grid.sum_scalar_to_owned(
        particle_to_grid(state.node_index, state.S**2, state.particle_mass, grid.n_local_nodes))
    keep = state.own_value_dofs()
    return np.where(keep, 1.0, r_diag / np.where(keep, 1.0, state.mass))


def group_by_node_set(node_index, n_nodes):
    """Group particles that touch the same list of nodes (one element matrix
    per group): ``order`` sorts particles by group, ``starts`` marks the
    first of each group in that order. Groups are ordered by their first and
    last node, then by the whole list: the first and last node alone do not
    identify the list where a stencil is clipped at the grid boundary (an
    axis one cell wide with GIMP or B-splines: nodes (0, 0, 1) and (0, 1, 1)).
    Within a group, particles keep their order."""
    n, nn = node_index.shape
    if n == 0:
        return np.zeros(0, int), np.zeros(0, int)
    key = node_index[:, 0] * n_nodes + node_index[:, -1]
    order = np.argsort(key, kind="stable")
    rows = node_index[order]
    same_key = key[order][1:] == key[order][:-1]
    differs = np.any(rows[1:] != rows[:-1], axis=1)
    if np.any(same_key & differs):
        # clipped stencils share a key: sort by the whole list too (np.lexsort
        # sorts by its last key first, and is stable)
        order = np.lexsort(tuple(node_index[:, j] for j in range(nn - 1, -1, -1)) + (key,))
        rows = node_index[order]
        differs = np.any(rows[1:] != rows[:-1], axis=1)
    starts = np.flatnonzero(np.r_[True, differs])
    return order, starts


def sum_by_group(values, starts):
    """Sum consecutive rows of ``values`` that share a group (particles sorted
    by cell; ``starts`` = first row of each group)."""
    if len(starts) == 0:
        return values[:0]
    return np.add.reduceat(values, starts, axis=0)


def projection_blocks(particle_mass, S, order, starts, dim):
    """Blocks of S^T m S (the particle-mass-weighted "consistent mass" of the
    momentum formulation's projection, Sulsky & Kaul 3.2.1), summed over the
    particles of each footprint group, as (n_groups, nn*dim, nn*dim) with
    rows i*dim + a and columns j*dim + b (identity in a, b)."""
    scalar = particle_mass[:, None, None] * S[:, :, None] * S[:, None, :]     # (n, nn, nn)
    scalar = sum_by_group(scalar[order], starts)
    return np.einsum("gij,ab->giajb", scalar, np.eye(dim)).reshape(
        len(scalar), S.shape[1] * dim, S.shape[1] * dim)
