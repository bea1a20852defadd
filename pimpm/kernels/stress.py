"""What the particles' committed stresses and deformations give the grid and
the energy account, compiled:

* :func:`current_internal_force`: Fint_i = sum_p v_p sigma_p G_ip with v_p
  the current volume (MPM introduction eq. 6; the axisymmetric hoop force
  v_p sigma_thth S_ip / r_p), for the explicit step and for HHT's
  Fint(t) on the reset grid;
* :func:`strain_energy`: sum_p V0_p W(F_p, history_p), the stored energy;
* :func:`largest_speed_squared`: the particle speeds of the explicit CFL step.
"""
import numpy as np

from .jit import jit, jit_inline
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


@jit_inline
def _add_stress_force(kinematics, axes, footprint, node_index, S, G, radius, sigma, p, v, out, column):
    """Particle p's v sigma_p G_ip (plus the axisymmetric hoop force v
    sigma_22 S_ip / r_p in the radial component) added into the columns of
    ``out`` from ``column`` on. The footprint loop is the innermost: numba
    leaves loops of length dim rolled, and one inside the footprint loop
    made the explicit P2G three times slower (each node's sum is the same,
    in the same order)."""
    nn = len(footprint)
    for a in axes:
        for k in range(nn):
            out[node_index[p, k], column + a] += v * _row_dot(axes, G, p, k, sigma, a)
    if kinematics == AXISYMMETRIC:
        h = v * sigma[p, 2, 2] / radius[p]
        for k in range(nn):
            out[node_index[p, k], column] += h * S[p, k]


@jit_inline
def _row_dot(axes, G, p, k, sigma, a):
    """sum_b G[p, k, b] sigma[p, a, b], written out (a rolled loop of length
    dim costs more than the sum)."""
    if len(axes) == 2:
        return G[p, k, 0] * sigma[p, a, 0] + G[p, k, 1] * sigma[p, a, 1]
    return G[p, k, 0] * sigma[p, a, 0] + G[p, k, 1] * sigma[p, a, 1] + G[p, k, 2] * sigma[p, a, 2]


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
    f0 = 1 + dim
    nn = len(footprint)
    for p in range(S.shape[0]):
        for k in range(nn):
            out[node_index[p, k], 0] += S[p, k] * mass[p]
        _add_momentum(axes, footprint, node_index, S, p, mass[p], velocity, out, 1)
        copy3(F, p, Fp)
        _add_stress_force(kinematics, axes, footprint, node_index, S, G, radius, sigma, p,
                          volume0[p] * det3(Fp), out, f0)


@jit_inline
def _add_momentum(axes, footprint, node_index, S, p, m, velocity, out, column):
    """Particle p's momentum S_ip m v_p added into the columns of ``out``
    from ``column`` on (the footprint loop innermost, as in
    :func:`_add_stress_force`)."""
    nn = len(footprint)
    for a in axes:
        mv = m * velocity[p, a]
        for k in range(nn):
            out[node_index[p, k], column + a] += S[p, k] * mv


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
    nn = len(footprint)
    momentum[:] = 0.0
    for p in range(S.shape[0]):
        for c in range(2 * dim):
            s = 0.0
            for k in range(nn):
                s += S[p, k] * nodal[node_index[p, k], c]
            if c < dim:
                new_velocity[p, c] = velocity[p, c] + dt * s
            else:
                new_x[p, c - dim] = x[p, c - dim] + dt * s
        _add_momentum(axes, footprint, node_index, S, p, mass[p], new_velocity, momentum, 0)


@jit
def strain_energy(only_model, models, params, material_of, F, h, volume0):
    """sum_p V0_p W_p: each particle's stored energy per reference volume
    (:func:`pimpm.kernels.material_point.model_energy`) times its
    reference volume. ``only_model``: as in
    :func:`pimpm.kernels.particle_step.evaluate_particles`."""
    total = 0.0
    Fp, prm, hp = np.empty((3, 3)), np.empty(params.shape[1]), np.empty(h.shape[1])
    for p in range(F.shape[0]):
        total += volume0[p] * _energy(only_model, models, params, material_of, F, h, p, Fp, prm, hp)
    return total


@jit
def point_energies(only_model, models, params, material_of, F, h, out):
    """out[p] = W_p, each particle's stored energy per reference volume."""
    Fp, prm, hp = np.empty((3, 3)), np.empty(params.shape[1]), np.empty(h.shape[1])
    for p in range(F.shape[0]):
        out[p] = _energy(only_model, models, params, material_of, F, h, p, Fp, prm, hp)


@jit_inline
def _energy(only_model, models, params, material_of, F, h, p, Fp, prm, hp):
    """Particle p's stored energy per reference volume. Its F, parameters
    and history are copied into the scratch ``Fp``, ``prm``, ``hp``: views
    such as params[m] cost numba a reference-count pair per particle
    (measured: the explicit billet's energy 1.9 ms with views and dispatch,
    0.6 ms without)."""
    copy3(F, p, Fp)
    m = material_of[p]
    for k in range(prm.shape[0]):
        prm[k] = params[m, k]
    for k in range(hp.shape[0]):
        hp[k] = h[p, k]
    return model_energy(only_model, models[m], prm, Fp, hp)


@jit
def largest_speed_squared(velocity, material_of, out):
    """out[m] = the largest |v_p|^2 over the particles of material m (-1 if
    it has none here): the particle speeds of the explicit CFL step."""
    out[:] = -1.0
    dim = velocity.shape[1]
    for p in range(velocity.shape[0]):
        s = velocity[p, 0] * velocity[p, 0]
        for d in range(1, dim):
            s += velocity[p, d] * velocity[p, d]
        m = material_of[p]
        if s > out[m]:
            out[m] = s
