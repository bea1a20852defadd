"""F-bar in numpy (the reference of pimpm.kernels.fbar and of the F-bar
branch of pimpm.kernels.particle_step.evaluate_particles), written from the
formulas rather than from the kernels' loops:

    F_inc_bar,p = (J_bar_c / J_inc,p)^(1/n) F_inc,p   (the n stretched axes)
    J_bar_c = sum_{q in c} V_q J_inc,q / sum_{q in c} V_q

and the tangent's F-bar part (de Souza Neto et al. 1996), for a variation
du with divergence div_p = sum_m du_m . g_mp (+ du_r S_m / r):

    dFint_k = ... + sum_p v_p (g_kp . Q_p) (div_bar_c(p) - div_p),
    Q = (c : I_n - (n - 2) sigma) / n,  div_bar_c = sum_q v_q div_q / sum_q v_q.
"""
import numpy as np

from pimpm.materials import tensors

from . import kinematics as RK


def stretched_axes(kinematics, dim):
    return 2 if (dim == 2 and kinematics.name == "plane_strain") else 3


def averaged_increment(kinematics, F_inc, volume, cell):
    """F_inc_bar for particles grouped by ``cell`` (-1: not averaged)."""
    dim = 3 if kinematics.name == "3d" else 2
    n_ax = stretched_axes(kinematics, dim)
    J = tensors.det(F_inc)
    out = F_inc.copy()
    on = cell >= 0
    J_bar = np.zeros(cell.max() + 1 if np.any(on) else 0)
    V = np.zeros_like(J_bar)
    np.add.at(J_bar, cell[on], volume[on] * J[on])
    np.add.at(V, cell[on], volume[on])
    ratio = (J_bar[cell[on]] / V[cell[on]] / J[on]) ** (1.0 / n_ax)
    out[on, :n_ax, :n_ax] *= ratio[:, None, None]
    return out


def fbar_tangent(kinematics, sigma, c, F_inc, G, S, volume, radius, cell, node_index, n_nodes):
    """The F-bar part of the tangent as a dense (n_nodes dim)^2 matrix."""
    n, nn, dim = G.shape
    n_ax = stretched_axes(kinematics, dim)
    v = volume * tensors.det(F_inc)
    g = RK.current_gradients(F_inc, G)                            # (n, nn, dim)
    I = np.eye(3)[:n_ax, :n_ax]
    Q = (np.einsum("pacbd,bd->pac", c[:, :, :, :n_ax, :n_ax], I) - (n_ax - 2) * sigma) / n_ax
    R = np.einsum("pkc,pac->pka", g, Q[:, :dim, :dim]) * v[:, None, None]     # rows
    d = g.copy()                                                  # columns: the divergence
    if kinematics.name == "axisymmetric":
        w = S / (radius * F_inc[:, 2, 2])[:, None]
        R[:, :, 0] += w * (v * Q[:, 2, 2])[:, None]
        d[:, :, 0] += w
    dofs = (node_index[:, :, None] * dim + np.arange(dim)).reshape(n, nn * dim)
    on = cell >= 0
    V = np.zeros(cell.max() + 1 if np.any(on) else 0)
    np.add.at(V, cell[on], v[on])
    K = np.zeros((n_nodes * dim,) * 2)
    mean = {}                                                     # cell -> dense div_bar row
    for p in np.flatnonzero(on):                                  # test code: loops are fine here
        row = mean.setdefault(cell[p], np.zeros(n_nodes * dim))
        np.add.at(row, dofs[p], (v[p] / V[cell[p]]) * d[p].reshape(-1))
    for p in np.flatnonzero(on):
        own = np.zeros(n_nodes * dim)
        np.add.at(own, dofs[p], d[p].reshape(-1))
        rows = np.zeros(n_nodes * dim)
        np.add.at(rows, dofs[p], R[p].reshape(-1))
        K += np.outer(rows, mean[cell[p]] - own)
    return K


# ------------------------------------------------------------------ averaged on the nodes
#
#   J_bar_p = sum_I S+_Ip J_I / sum_I S+_Ip,  J_I = sum_q S+_Iq V_q J_q / sum_q S+_Iq V_q  (S+ = max(S, 0))
#   F_inc_bar,p = (J_bar_p / J_p)^(alpha / n) F_inc,p,  Q = alpha (c : I_n - (n - 2) sigma) / n
#   div_bar_p = dJ_bar_p / J_bar_p = sum_I S+_Ip (sum_q S+_Iq V_q J_q div_q / W_I) / (s_p J_bar_p)

def nodal_mean(F_inc, volume, S, node_index, on, n_nodes):
    """J_bar (n,) of the averaged particles ``on`` (1 elsewhere), and the nodal J_I and W_I."""
    J = tensors.det(F_inc)
    Sp = np.where(on[:, None], np.maximum(S, 0.0), 0.0)
    W = np.zeros(n_nodes)
    Y = np.zeros(n_nodes)
    np.add.at(W, node_index, Sp * volume[:, None])
    np.add.at(Y, node_index, Sp * (volume * J)[:, None])
    J_node = np.divide(Y, W, out=np.ones(n_nodes), where=W > 0)
    share = Sp.sum(axis=1)
    J_bar = np.where(on, (Sp * J_node[node_index]).sum(axis=1) / np.where(share > 0, share, 1.0), 1.0)
    return J_bar, J_node, W


def nodal_increment(kinematics, F_inc, volume, S, node_index, on, alpha, n_nodes):
    dim = 3 if kinematics.name == "3d" else 2
    n_ax = stretched_axes(kinematics, dim)
    J_bar, _, _ = nodal_mean(F_inc, volume, S, node_index, on, n_nodes)
    out = F_inc.copy()
    ratio = (J_bar[on] / tensors.det(F_inc[on])) ** (alpha / n_ax)
    out[on, :n_ax, :n_ax] *= ratio[:, None, None]
    return out


def nodal_tangent(kinematics, sigma, c, F_inc, G, S, volume, radius, on, alpha, node_index, n_nodes):
    """The F-bar part of the tangent with J averaged on the nodes, dense."""
    n, nn, dim = G.shape
    n_ax = stretched_axes(kinematics, dim)
    J = tensors.det(F_inc)
    v = volume * J
    g = RK.current_gradients(F_inc, G)
    I = np.eye(3)[:n_ax, :n_ax]
    Q = alpha * (np.einsum("pacbd,bd->pac", c[:, :, :, :n_ax, :n_ax], I) - (n_ax - 2) * sigma) / n_ax
    R = np.einsum("pkc,pac->pka", g, Q[:, :dim, :dim]) * v[:, None, None]
    d = g.copy()
    if kinematics.name == "axisymmetric":
        w = S / (radius * F_inc[:, 2, 2])[:, None]
        R[:, :, 0] += w * (v * Q[:, 2, 2])[:, None]
        d[:, :, 0] += w
    dofs = (node_index[:, :, None] * dim + np.arange(dim)).reshape(n, nn * dim)
    J_bar, _, W = nodal_mean(F_inc, volume, S, node_index, on, n_nodes)
    Sp = np.where(on[:, None], np.maximum(S, 0.0), 0.0)
    node_rows = np.zeros((n_nodes, n_nodes * dim))              # d J_I / J_I-free: sum_q S+ V J div_q / W_I
    for q in np.flatnonzero(on):                                  # test code: loops are fine here
        for k in range(nn):
            if Sp[q, k] > 0:
                I_ = node_index[q, k]
                np.add.at(node_rows[I_], dofs[q], (Sp[q, k] * volume[q] * J[q] / W[I_]) * d[q].reshape(-1))
    K = np.zeros((n_nodes * dim,) * 2)
    for p in np.flatnonzero(on):
        mean = (Sp[p][:, None] * node_rows[node_index[p]]).sum(axis=0) / (Sp[p].sum() * J_bar[p])
        own = np.zeros(n_nodes * dim)
        np.add.at(own, dofs[p], d[p].reshape(-1))
        rows = np.zeros(n_nodes * dim)
        np.add.at(rows, dofs[p], R[p].reshape(-1))
        K += np.outer(rows, mean - own)
    return K
