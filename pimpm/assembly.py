"""Residual and consistent tangent kernels of the implicit step (Guilkey &
Weiss 2003, section 3.3, steps 2 and 5), as pure functions over all particles.

The unknown of a step is the incremental grid displacement ``u`` from t to
t + dt. With shape-function gradients ``G`` evaluated at the particle
positions of time t (the grid is reset), each particle carries

    F_inc = 1 + sum_i u_i (x) G_ip,      F(t+dt) = F_inc F(t)        (step 5)

and contributes to the internal force through the first Piola-Kirchhoff
stress relative to the configuration at t, ``P = J_inc sigma F_inc^-T``:

    Fint_i = sum_p V_p(t) P_p G_ip  ( = sum_p v_p sigma_p g_ip, g = F_inc^-T G )

Its exact derivative is the material + geometric stiffness of step 2,
evaluated with current gradients ``g`` and current volume ``v``:

    K_(ia)(jb) = sum_p v_p g_ic (c_acbd + delta_ab sigma_cd) g_jd

where ``c`` is the spatial elasticity tensor (G&W eq. 21). In 2D (plane
strain) only the in-plane components enter.
"""
import numpy as np

from .materials import tensors


def deformation_increment(grad_u):
    """F_inc (n, 3, 3) = 1 + grad u, with grad u (n, dim, dim) padded to 3x3."""
    n, dim = grad_u.shape[0], grad_u.shape[1]
    F_inc = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    F_inc[:, :dim, :dim] += grad_u
    return F_inc


def incremental_first_piola(sigma, F_inc, dim):
    """In-plane part of P = J_inc sigma F_inc^-T, (n, dim, dim). J_inc is the
    full 3x3 determinant (in plane stress F_inc[2,2] is the thickness stretch)."""
    F2 = F_inc[:, :dim, :dim]
    J_inc = tensors.det(F_inc)
    F_inv_T = np.transpose(tensors.inv(F2), (0, 2, 1))
    return J_inc[:, None, None] * np.matmul(sigma[:, :dim, :dim], F_inv_T)


def internal_force_pairs(P, G, volume):
    """Per (particle, node) internal force V_p P_p G_ip, (n, nn, dim)."""
    return volume[:, None, None] * np.matmul(G, np.transpose(P, (0, 2, 1)))


def current_gradients(F_inc, G):
    """Shape-function gradients on the deformed grid, g = F_inc^-T G, (n, nn, dim)."""
    dim = G.shape[2]
    F_inv = tensors.inv(F_inc[:, :dim, :dim])
    return np.matmul(G, F_inv)


def spatial_tangent(sigma, c, dim):
    """In-plane a_acbd = c_acbd + delta_ab sigma_cd (material + geometric
    stiffness density, spatial form), (n, dim, dim, dim, dim)."""
    a = c[:, :dim, :dim, :dim, :dim].copy()
    for k in range(dim):
        a[:, k, :, k, :] += sigma[:, :dim, :dim]
    return a


def element_tangents(sigma, c, F_inc, G, volume):
    """Per-particle stiffness blocks (n, nn*dim, nn*dim): material + geometric
    stiffness of G&W step 2 (row index i*dim + a, column j*dim + b)."""
    n, nn, dim = G.shape
    J_inc = tensors.det(F_inc)            # full 3x3: thickness change in plane stress
    v = volume * J_inc
    g = current_gradients(F_inc, G)
    a = spatial_tangent(sigma, c, dim)
    # T_(i,abd) = g_ic a_acbd, then K_(iab),j = T_(iab),d g_jd (batched matmuls)
    a_c_first = np.transpose(a, (0, 2, 1, 3, 4)).reshape(n, dim, dim**3)
    T = np.matmul(g, a_c_first).reshape(n, nn * dim * dim, dim)
    K = np.matmul(T, np.transpose(g, (0, 2, 1))).reshape(n, nn, dim, dim, nn)
    K = np.transpose(K, (0, 1, 2, 4, 3)) * v[:, None, None, None, None]
    return K.reshape(n, nn * dim, nn * dim)


def hoop_force_pairs(sigma, F_inc, S, volume, radius):
    """Axisymmetric hoop term of the internal force (radial component):
    V_p P_thth S_ip / r_p with P_thth = J_inc sigma_thth / F_inc_thth (r_p
    the radius at t, where the grid is reset), (n, nn)."""
    J_inc = tensors.det(F_inc)
    P_hoop = J_inc * sigma[:, 2, 2] / F_inc[:, 2, 2]
    return (volume * P_hoop / radius)[:, None] * S


def hoop_tangents(sigma, c, F_inc, G, S, volume, radius):
    """Axisymmetric additions to the element stiffness (n, nn*2, nn*2): the
    hoop strain increment du_r S_j / r couples with the in-plane gradients
    through c_ab22, c_22bd and c_2222 + sigma_22 (r the current radius)."""
    n, nn, dim = G.shape
    v = volume * tensors.det(F_inc)
    g = current_gradients(F_inc, G)
    r = radius * F_inc[:, 2, 2]
    w = S / r[:, None]                                       # (n, nn): hoop "gradient"
    K = np.zeros((n, nn, dim, nn, dim))
    # row hoop (a = r) x column in-plane: w_i c_22bd g_jd
    K[:, :, 0, :, :] += np.einsum("pi,pbd,pjd->pijb", w, c[:, 2, 2, :dim, :dim], g)
    # row in-plane x column hoop (b = r): g_ic c_ac22 w_j
    K[:, :, :, :, 0] += np.einsum("pic,pac,pj->piaj", g, c[:, :dim, :dim, 2, 2], w)
    # hoop x hoop
    K[:, :, 0, :, 0] += np.einsum("pi,p,pj->pij", w, c[:, 2, 2, 2, 2] + sigma[:, 2, 2], w)
    return (K * v[:, None, None, None, None]).reshape(n, nn * dim, nn * dim)


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
