"""The implicit step's particle kinematics and element kernels in numpy
(vectorised over particles): the references of
pimpm.kernels.particle_step's evaluate_particles, tangent_blocks,
tangent_product and tangent_diagonal, and of pimpm.kernels.stress's
internal force. They were pimpm's production code before the compiled
kernels replaced them.

With shape-function gradients ``G`` at the particle positions of time t
(the grid is reset), each particle carries

    F_inc = 1 + sum_i u_i (x) G_ip,      F(t+dt) = F_inc F(t)        (G&W step 5)

and contributes to the internal force through the first Piola-Kirchhoff
stress relative to the configuration at t, ``P = J_inc sigma F_inc^-T``:

    Fint_i = sum_p V_p(t) P_p G_ip  ( = sum_p v_p sigma_p g_ip, g = F_inc^-T G )

Its exact derivative is the material + geometric stiffness of step 2,
evaluated with current gradients ``g`` and current volume ``v``:

    K_(ia)(jb) = sum_p v_p g_ic (c_acbd + delta_ab sigma_cd) g_jd

plus, in axisymmetry, the hoop terms. ``kinematics`` is a
pimpm.kinematics object (its ``name``)."""
import numpy as np

from pimpm.materials import tensors


def deformation_increment(kinematics, grad_u, radius, displacement):
    """F_inc (n, 3, 3) = 1 + grad u (padded to 3x3); axisymmetric: the hoop
    stretch (r + u_r) / r (``displacement``: a callable giving the
    particles' displacement over the step)."""
    n, dim = grad_u.shape[0], grad_u.shape[1]
    F_inc = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    F_inc[:, :dim, :dim] += grad_u
    if kinematics.name == "axisymmetric":
        F_inc[:, 2, 2] = 1.0 + displacement()[:, 0] / radius
    return F_inc


def incremental_first_piola(sigma, F_inc, dim):
    """In-plane part of P = J_inc sigma F_inc^-T, (n, dim, dim). J_inc is the
    full 3x3 determinant (in plane stress F_inc[2,2] is the thickness stretch)."""
    J_inc = tensors.det(F_inc)
    F_inv_T = np.transpose(tensors.inv(F_inc[:, :dim, :dim]), (0, 2, 1))
    return J_inc[:, None, None] * np.matmul(sigma[:, :dim, :dim], F_inv_T)


def internal_force_pairs(kinematics, sigma, F_inc, G, S, volume, radius):
    """Per (particle, node) internal force (n, nn, dim): V_p P_p G_ip with
    P = J_inc sigma F_inc^-T relative to the configuration at t (volume at
    t), or with ``F_inc`` None the current stress over current volumes
    (explicit MPM, eq. 6); axisymmetric: plus the hoop force V P_thth S / r."""
    dim = G.shape[2]
    P = sigma[:, :dim, :dim] if F_inc is None else incremental_first_piola(sigma, F_inc, dim)
    pairs = volume[:, None, None] * np.matmul(G, np.transpose(P, (0, 2, 1)))
    if kinematics.name == "axisymmetric":
        F = np.broadcast_to(np.eye(3), sigma.shape) if F_inc is None else F_inc
        P_hoop = tensors.det(F) * sigma[:, 2, 2] / F[:, 2, 2]
        pairs[:, :, 0] += (volume * P_hoop / radius)[:, None] * S
    return pairs


def current_gradients(F_inc, G):
    """Shape-function gradients on the deformed grid, g = F_inc^-T G, (n, nn, dim)."""
    dim = G.shape[2]
    return np.matmul(G, tensors.inv(F_inc[:, :dim, :dim]))


def spatial_tangent(sigma, c, dim):
    """In-plane a_acbd = c_acbd + delta_ab sigma_cd (material + geometric
    stiffness density, spatial form), (n, dim, dim, dim, dim)."""
    a = c[:, :dim, :dim, :dim, :dim].copy()
    for k in range(dim):
        a[:, k, :, k, :] += sigma[:, :dim, :dim]
    return a


def element_tangents(kinematics, sigma, c, F_inc, G, S, volume, radius):
    """Per-particle stiffness blocks (n, nn*dim, nn*dim): material + geometric
    stiffness of G&W step 2 (row index i*dim + a, column j*dim + b), plus
    the axisymmetric hoop terms."""
    n, nn, dim = G.shape
    v = volume * tensors.det(F_inc)          # full 3x3: thickness change in plane stress
    g = current_gradients(F_inc, G)
    a = spatial_tangent(sigma, c, dim)
    # T_(i,abd) = g_ic a_acbd, then K_(iab),j = T_(iab),d g_jd (batched matmuls)
    a_c_first = np.transpose(a, (0, 2, 1, 3, 4)).reshape(n, dim, dim**3)
    T = np.matmul(g, a_c_first).reshape(n, nn * dim * dim, dim)
    K = np.matmul(T, np.transpose(g, (0, 2, 1))).reshape(n, nn, dim, dim, nn)
    K = (np.transpose(K, (0, 1, 2, 4, 3)) * v[:, None, None, None, None]).reshape(n, nn * dim, nn * dim)
    if kinematics.name == "axisymmetric":
        K += hoop_tangents(sigma, c, F_inc, G, S, volume, radius)
    return K


def dense_tangent(kinematics, sigma, c, F_inc, G, S, volume, radius, node_index, n_nodes):
    """The particles' element tangents summed into a dense (n_nodes dim)^2 matrix."""
    n, nn, dim = G.shape
    blocks = element_tangents(kinematics, sigma, c, F_inc, G, S, volume, radius)
    dense = np.zeros((n_nodes * dim,) * 2)
    dofs = (node_index[:, :, None] * dim + np.arange(dim)).reshape(n, nn * dim)
    for p in range(n):                      # test code: a loop over particles is fine here
        dense[np.ix_(dofs[p], dofs[p])] += blocks[p]
    return dense


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
    K[:, :, 0, :, :] += np.einsum("pi,pbd,pjd->pijb", w, c[:, 2, 2, :dim, :dim], g)
    K[:, :, :, :, 0] += np.einsum("pic,pac,pj->piaj", g, c[:, :dim, :dim, 2, 2], w)
    K[:, :, 0, :, 0] += np.einsum("pi,p,pj->pij", w, c[:, 2, 2, 2, 2] + sigma[:, 2, 2], w)
    return (K * v[:, None, None, None, None]).reshape(n, nn * dim, nn * dim)


def scatter_pairs(node_index, pairs, n_nodes):
    """Sum per-(particle, node) values ``pairs`` (n, nn, k) into the nodes (n_nodes, k)."""
    out = np.zeros((n_nodes, pairs.shape[2]))
    np.add.at(out, node_index.reshape(-1), pairs.reshape(-1, pairs.shape[2]))
    return out


def gradient(node_index, G, nodal):
    """sum_i q_i (x) G_ip: (n, k, dim) gradient of a nodal field (MPM intro eq. 5)."""
    return np.einsum("pka,pkb->pab", nodal[node_index], G)


def expected_couplings(groups, node_index, active, owned_nodes, n_nodes):
    """(n_nodes, n_nodes) bool: the node pairs that particles of one group
    (``groups``: lists of particle indices; a group per particle, or per
    F-bar cell) reach, and the owned diagonals: what the tangent's pattern
    must hold."""
    coupled = np.zeros((n_nodes, n_nodes), dtype=bool)
    for members in groups:
        on = np.unique(np.concatenate([node_index[p][active[p]] for p in members]))
        coupled[np.ix_(on, on)] = True
    coupled[owned_nodes, owned_nodes] = True
    return coupled


def pattern_couplings(pattern, n_nodes):
    """(n_nodes, n_nodes) bool: the block couplings a TangentPattern holds."""
    in_pattern = np.zeros((n_nodes, n_nodes), dtype=bool)
    block_rows = np.repeat(np.arange(len(pattern.indptr) - 1), np.diff(pattern.indptr))
    in_pattern[block_rows, pattern.indices] = True
    return in_pattern
