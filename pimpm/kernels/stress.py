"""What the particles' committed stresses and deformations give the grid and
the energy account, compiled:

* :func:`current_internal_force`: Fint_i = sum_p v_p sigma_p G_ip with v_p
  the current volume (MPM introduction eq. 6; the axisymmetric hoop force
  v_p sigma_thth S_ip / r_p), for the explicit step and for HHT's
  Fint(t) on the reset grid;
* :func:`strain_energy`: sum_p V0_p W(F_p, history_p), the stored energy.
"""
import numpy as np

from .jit import jit
from .material_point import model_energy
from .particle_step import AXISYMMETRIC
from .small import copy3, det3


@jit
def current_internal_force(kinematics, axes, footprint, node_index, S, G, radius, sigma, F, volume0,
                           force):
    """Add sum_p v_p sigma_p G_ip (v_p = V0_p det F_p, in-plane components)
    into ``force`` (n_nodes, dim; zeroed here); axisymmetric: plus the hoop
    force v_p sigma_22 S_ip / r_p in the radial component. ``axes`` =
    tuple(range(dim)), ``footprint`` = tuple(range(nodes per particle)) (loops
    of lengths known when compiling)."""
    force[:] = 0.0
    Fp = np.empty((3, 3))
    for p in range(S.shape[0]):
        copy3(F, p, Fp)
        _add_stress_force(kinematics, axes, footprint, node_index, S, G, radius, sigma, p,
                          volume0[p] * det3(Fp), force, 0)


@jit
def _add_stress_force(kinematics, axes, footprint, node_index, S, G, radius, sigma, p, v, out, column):
    """Particle p's v sigma_p G_ip (plus the axisymmetric hoop force v
    sigma_22 S_ip / r_p in the radial component) added into the columns of
    ``out`` from ``column`` on."""
    for k in footprint:
        node = node_index[p, k]
        for a in axes:
            s = 0.0
            for b in axes:
                s += G[p, k, b] * sigma[p, a, b]
            out[node, column + a] += v * s
    if kinematics == AXISYMMETRIC:
        h = v * sigma[p, 2, 2] / radius[p]
        for k in footprint:
            out[node_index[p, k], column] += h * S[p, k]


@jit
def strain_energy(models, params, material_of, F, h, volume0):
    """sum_p V0_p W_p: each particle's stored energy per reference volume
    (:func:`pimpm.kernels.material_point.model_energy`) times its
    reference volume."""
    total = 0.0
    Fp = np.empty((3, 3))
    for p in range(F.shape[0]):
        total += volume0[p] * _energy(models, params, material_of, F, h, p, Fp)
    return total


@jit
def _energy(models, params, material_of, F, h, p, Fp):
    """Particle p's stored energy per reference volume (``Fp``: scratch)."""
    copy3(F, p, Fp)
    m = material_of[p]
    return model_energy(models[m], params[m], Fp, h[p])


@jit
def explicit_p2g(kinematics, axes, footprint, node_index, S, G, radius, mass, velocity, sigma, F, volume0,
                 out):
    """The particle-to-grid pass of an explicit step in one loop (MPM intro
    eq. 2-3 and 6): ``out`` (n_nodes, 1 + 2 dim; zeroed here) gets the
    lumped mass sum_p S_ip m_p (column 0), the momentum sum_p S_ip m_p v_p
    (columns 1 to dim) and the internal force of the current stresses as
    :func:`current_internal_force` (the last dim columns)."""
    dim = len(axes)
    out[:] = 0.0
    Fp = np.empty((3, 3))
    mv = np.empty(dim)
    f0 = 1 + dim
    for p in range(S.shape[0]):
        for k in footprint:
            out[node_index[p, k], 0] += S[p, k] * mass[p]
        _add_momentum(axes, footprint, node_index, S, p, mass[p], velocity, mv, out, 1)
        copy3(F, p, Fp)
        _add_stress_force(kinematics, axes, footprint, node_index, S, G, radius, sigma, p,
                          volume0[p] * det3(Fp), out, f0)


@jit
def _add_momentum(axes, footprint, node_index, S, p, m, velocity, mv, out, column):
    """Particle p's momentum S_ip m v_p added into the columns of ``out``
    from ``column`` on (``mv``: scratch of length dim)."""
    for a in axes:
        mv[a] = m * velocity[p, a]
    for k in footprint:
        node = node_index[p, k]
        wk = S[p, k]
        for a in axes:
            out[node, column + a] += wk * mv[a]


@jit
def explicit_g2p(axes, footprint, node_index, S, dt, nodal, mass, velocity, x, new_velocity, new_x,
                 momentum):
    """The grid-to-particle pass of an explicit step in one loop (MPM intro
    eq. 9-10): with ``nodal`` (n_nodes, 2 dim) the grid's velocity change
    rate and new velocity, v_p += dt sum_i S_ip a_i and x_p += dt sum_i S_ip
    v_i (into ``new_velocity``, ``new_x``); ``momentum`` (n_nodes, dim;
    zeroed here) gets sum_p S_ip m_p v_p(t+dt), the modified update's
    remapped momentum."""
    dim = len(axes)
    momentum[:] = 0.0
    mv = np.empty(dim)
    for p in range(S.shape[0]):
        for c in range(2 * dim):
            s = 0.0
            for k in footprint:
                s += S[p, k] * nodal[node_index[p, k], c]
            if c < dim:
                new_velocity[p, c] = velocity[p, c] + dt * s
            else:
                new_x[p, c - dim] = x[p, c - dim] + dt * s
        _add_momentum(axes, footprint, node_index, S, p, mass[p], new_velocity, mv, momentum, 0)


@jit
def point_energies(models, params, material_of, F, h, out):
    """out[p] = W_p, each particle's stored energy per reference volume."""
    Fp = np.empty((3, 3))
    for p in range(F.shape[0]):
        out[p] = _energy(models, params, material_of, F, h, p, Fp)
