"""The fused per-particle kernels of the implicit step (Guilkey & Weiss 2003,
section 3.3, steps 3 and 5), one loop over the particles each:

* :func:`evaluate_particles`: for the nodal incremental displacement u,
  F_inc = 1 + sum_i u_i (x) G_ip (step 5; the axisymmetric hoop stretch
  1 + u_r / r), F = F_inc F(t), the material point (stress, tangent,
  history; plane stress solves F33 first) and the internal force
  Fint_i = sum_p V_p(t) P_p G_ip with P = J_inc sigma F_inc^-T (plus the
  axisymmetric hoop force), accumulated into the nodes;
* :func:`tangent_blocks`: the material + geometric stiffness of step 3,
  K_(ia)(jb) = sum_p v_p g_ic (c_acbd + delta_ab sigma_cd) g_jd with
  g = F_inc^-T G and v_p the current volume (plus the hoop terms), added
  block by block into the values of the tangent's block CSR
  (:mod:`.pattern`).

The numpy references are :mod:`pimpm.assembly` and :mod:`pimpm.kinematics`.
"""
import numpy as np

from .jit import jit
from .material_point import WORKSPACE, material_point, solve_thickness
from .small import det3, inv2, inv3, matmul3

#: kinematics codes (pimpm.kinematics classes carry theirs)
GENERAL, PLANE_STRESS, AXISYMMETRIC = 0, 1, 2


@jit
def _in_plane_inverse(F, dim, out):
    """out[:dim, :dim] = (F[:dim, :dim])^-1."""
    if dim == 2:
        inv2(F, out)
    else:
        inv3(F, out)


@jit
def evaluate_particles(kinematics, axes, u, node_index, S, G, radius, F_n, volume_n,
                       models, params, material_of, h_in, want_c, want_force,
                       F_inc, F, sigma, c, h_out, force):
    """Kinematics, material points and (``want_force``) the internal force
    for the ghosted-local nodal displacement ``u`` (n_nodes, dim). Writes
    F_inc, F, sigma, c (if ``want_c``), h_out and force (n_nodes, dim,
    zeroed here). Returns the number of particles whose increment inverts
    them (det F_inc <= 0, full 3x3). ``axes`` = tuple(range(dim)): a tuple's
    length is known when compiling, so each dimension gets loops of fixed
    length."""
    dim = len(axes)
    n, nn = S.shape
    w = np.empty((WORKSPACE, 3, 3))
    D = np.empty((3, 3, 3, 3))
    c_scratch = np.empty((3, 3, 3, 3))
    grad = np.empty((3, 3))
    Finv = np.zeros((3, 3))
    P = np.empty((3, 3))
    if want_force:
        force[:] = 0.0
    inverted = 0
    for p in range(n):
        Fi = F_inc[p]
        grad[:] = 0.0
        for k in range(nn):
            node = node_index[p, k]
            for a in range(dim):
                for b in range(dim):
                    grad[a, b] += u[node, a] * G[p, k, b]
        for a in range(3):
            for b in range(3):
                Fi[a, b] = (1.0 if a == b else 0.0) + (grad[a, b] if (a < dim and b < dim) else 0.0)
        if kinematics == AXISYMMETRIC:
            u_r = 0.0
            for k in range(nn):
                u_r += S[p, k] * u[node_index[p, k], 0]
            Fi[2, 2] = 1.0 + u_r / radius[p]
        if not (det3(Fi) > 0.0):
            inverted += 1
        matmul3(Fi, F_n[p], F[p])
        m = material_of[p]
        cp = c[p] if want_c else c_scratch
        if kinematics == PLANE_STRESS:
            solve_thickness(models[m], params[m], F[p], Fi, h_in[p], h_out[p], sigma[p], cp,
                            want_c, w, D)
        else:
            material_point(models[m], params[m], F[p], h_in[p], h_out[p], sigma[p], cp,
                           want_c, w, D)
        if not want_force:
            continue
        J_inc = det3(Fi)
        _in_plane_inverse(Fi, dim, Finv)
        for a in range(dim):                         # P = J_inc sigma F_inc^-T (in-plane)
            for b in range(dim):
                s = 0.0
                for cc in range(dim):
                    s += sigma[p, a, cc] * Finv[b, cc]
                P[a, b] = J_inc * s
        V = volume_n[p]
        for k in range(nn):
            node = node_index[p, k]
            for a in range(dim):
                s = 0.0
                for b in range(dim):
                    s += G[p, k, b] * P[a, b]
                force[node, a] += V * s
        if kinematics == AXISYMMETRIC:              # hoop force V P_thth S_ip / r
            hoop = V * (J_inc * sigma[p, 2, 2] / Fi[2, 2]) / radius[p]
            for k in range(nn):
                force[node_index[p, k], 0] += hoop * S[p, k]
    return inverted


@jit
def tangent_blocks(kinematics, axes, node_index, active, S, G, radius, volume_n, F_inc, sigma, c,
                   node_ijk, width, indptr, slot_position, values):
    """Add every particle's stiffness blocks (G&W step 3, module docstring)
    into ``values`` (zeroed here): the row-oriented values of the block CSR
    ``indptr``/``slot_position`` of :func:`pimpm.kernels.pattern.block_pattern`
    (``node_ijk``: each ghosted-local node's multi-index; ``width``: the
    pattern's stencil half-width). ``axes`` = tuple(range(dim)) (see
    :func:`evaluate_particles`)."""
    dim = len(axes)
    n, nn = S.shape
    side = 2 * width + 1
    values[:] = 0.0
    Finv = np.zeros((3, 3))
    g = np.empty((nn, 3))
    a4 = np.empty((3, 3, 3, 3))
    B = np.empty((3, 3, 3))
    entry = np.empty(nn, dtype=np.int64)            # the particle's active footprint entries
    ijk = np.empty((nn, 3), dtype=np.int64)
    for p in range(n):
        na = 0
        for k in range(nn):
            if active[p, k]:
                entry[na] = k
                for d in range(dim):
                    ijk[na, d] = node_ijk[node_index[p, k], d]
                na += 1
        Fi = F_inc[p]
        v = volume_n[p] * det3(Fi)              # current volume (full 3x3: plane-stress thickness)
        _in_plane_inverse(Fi, dim, Finv)
        for q in range(na):                     # g = F_inc^-T G: g_kd = G_kc Finv_cd
            k = entry[q]
            for d in range(dim):
                s = 0.0
                for cc in range(dim):
                    s += G[p, k, cc] * Finv[cc, d]
                g[q, d] = s
        for a in range(dim):                    # v (c_acbd + delta_ab sigma_cd)
            for cc in range(dim):
                for b in range(dim):
                    for d in range(dim):
                        a4[a, cc, b, d] = v * (c[p, a, cc, b, d] + (sigma[p, cc, d] if a == b else 0.0))
        hoop = kinematics == AXISYMMETRIC
        r = radius[p] * Fi[2, 2] if hoop else 1.0
        for q in range(na):
            i = node_index[p, entry[q]]
            for a in range(dim):                # B_abd = g_qc a_acbd
                for b in range(dim):
                    for d in range(dim):
                        s = 0.0
                        for cc in range(dim):
                            s += g[q, cc] * a4[a, cc, b, d]
                        B[a, b, d] = s
            row = dim * dim * indptr[i]
            stride = (indptr[i + 1] - indptr[i]) * dim   # from one component row to the next
            for m in range(na):
                slot = 0
                for d in range(dim - 1, -1, -1):
                    slot = slot * side + ijk[m, d] - ijk[q, d] + width
                base = row + (slot_position[i, slot] - indptr[i]) * dim
                for a in range(dim):
                    for b in range(dim):
                        s = 0.0
                        for d in range(dim):
                            s += B[a, b, d] * g[m, d]
                        values[base + a * stride + b] += s
                if hoop:
                    wk = S[p, entry[q]] / r
                    wm = S[p, entry[m]] / r
                    for b in range(dim):        # hoop row x in-plane column: w_k c_22bd g_md
                        s = 0.0
                        for d in range(dim):
                            s += c[p, 2, 2, b, d] * g[m, d]
                        values[base + b] += v * wk * s
                    for a in range(dim):        # in-plane row x hoop column: g_kc c_ac22 w_m
                        s = 0.0
                        for cc in range(dim):
                            s += g[q, cc] * c[p, a, cc, 2, 2]
                        values[base + a * stride] += v * s * wm
                    values[base] += v * wk * (c[p, 2, 2, 2, 2] + sigma[p, 2, 2]) * wm
