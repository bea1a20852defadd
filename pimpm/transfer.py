"""Particle <-> grid transfers: scatters of particle quantities to the
ghosted-local nodes and gathers of nodal quantities at the particles
(MPM introduction eq. 2-10), run by the compiled kernels of
:mod:`pimpm.kernels.transfer`. A scatter's result lives on this rank's
ghosted local nodes; the caller sums it across ranks with DMDA
localToGlobal(ADD) (:meth:`pimpm.grid.Grid.sum_to_owned`).
"""
import numpy as np

from .kernels import transfer as kernels


def _c(a):
    return np.ascontiguousarray(a, dtype=float)


def particle_to_grid(node_index, S, particle_values, n_nodes):
    """MPM intro eq. 2-4: sum_p S_ip q_p for per-particle ``particle_values``
    (n,) or (n, k)."""
    values = _c(particle_values)
    scalar = values.ndim == 1
    if scalar:
        values = values[:, None]
    out = np.empty((n_nodes, values.shape[1]))
    kernels.scatter(np.ascontiguousarray(node_index), _c(S), values, n_nodes, out)
    return out[:, 0] if scalar else out


def grid_to_particle(node_index, S, nodal_values):
    """sum_i S_ip q_i for nodal values (n_nodes, k) -> (n, k)."""
    nodal = _c(nodal_values)
    out = np.empty((len(node_index), nodal.shape[1]))
    kernels.gather(np.ascontiguousarray(node_index), _c(S), nodal, out)
    return out
