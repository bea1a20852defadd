"""Particle <-> grid transfers as vectorized scatters and gathers.

Scatters use ``np.bincount`` over (particle, node) pairs (PLATFORM.md: ~40x
faster than ``np.add.at``); the result lives on this rank's ghosted local
nodes and is summed across ranks by the caller with DMDA localToGlobal(ADD).
"""
import numpy as np


def scatter(node_index, values, n_nodes):
    """Sum per-pair ``values`` into nodes.

    node_index (n, nn) ghosted-local node index of each pair;
    values (n, nn) or (n, nn, k); returns (n_nodes,) or (n_nodes, k).
    """
    idx = node_index.ravel()
    if values.ndim == 2:
        return np.bincount(idx, weights=values.ravel(), minlength=n_nodes)
    k = values.shape[2]
    flat = values.reshape(-1, k)
    out = np.empty((n_nodes, k))
    for c in range(k):  # loop over vector components only
        out[:, c] = np.bincount(idx, weights=flat[:, c], minlength=n_nodes)
    return out


def particle_to_grid(node_index, S, particle_values, n_nodes):
    """MPM intro eq. 2-4: sum_p S_ip q_p for per-particle ``particle_values``
    (n,) or (n, k)."""
    if particle_values.ndim == 1:
        return scatter(node_index, S * particle_values[:, None], n_nodes)
    return scatter(node_index, S[:, :, None] * particle_values[:, None, :], n_nodes)


def grid_to_particle(node_index, S, nodal_values):
    """sum_i S_ip q_i for nodal values (n_nodes, k) -> (n, k)."""
    return np.matmul(S[:, None, :], nodal_values[node_index])[:, 0, :]


def gradient_at_particles(node_index, G, nodal_values):
    """sum_i q_i (x) G_ip: (n, k, dim) gradient of a nodal field (MPM intro eq. 5)."""
    return np.matmul(np.transpose(nodal_values[node_index], (0, 2, 1)), G)
