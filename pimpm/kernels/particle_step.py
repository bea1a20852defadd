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

* :func:`tangent_product`, :func:`tangent_diagonal`: the same stiffness
  applied to a vector, and its diagonal, without forming it (the
  matrix-free tangent, :mod:`pimpm.implicit.shell`).

The numpy references are in tests/reference/kinematics.py.
"""
import numpy as np

from .jit import jit
from .material_point import WORKSPACE, model_point, solve_thickness
from .pattern import stencil_slot
from .small import copy3, det3, inv2, inv3, matmul3

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
def evaluate_particles(kinematics, axes, footprint, u, node_index, active, S, G, radius, F_n, volume_n,
                       only_model, models, params, material_of, h_in, want_tangent, want_force,
                       fbar_cell, n_cells, F_inc, F, sigma, h_out, force, tangent, hoop, fbar_q, fbar_weight,
                       jbar, fbar_alpha):
    """Kinematics, material points and (``want_force``) the internal force
    for the ghosted-local nodal displacement ``u`` (n_nodes, dim); footprint
    entries that are not ``active`` (no weight, no gradient) are skipped.

    Writes F_inc, F, sigma, h_out, force (n_nodes, dim; zeroed here) and, if
    ``want_tangent``, what the tangent needs per particle: ``tangent`` (n,
    dim, dim, dim, dim) = v (c_acbd + delta_ab sigma_cd), the material +
    geometric stiffness density times the current volume v, in the plane;
    ``hoop`` (n, 2 dim^2 + 1) in axisymmetry: v c_22bd, v c_ac22 and
    v (c_2222 + sigma_22) (:func:`_hoop_terms`). Returns the
    number of particles whose increment inverts them (det F_inc <= 0, full
    3x3) and the number whose plane-stress thickness solve did not converge. ``axes`` = tuple(range(dim)) and ``footprint`` = tuple(range(nodes
    per particle)): a tuple's length is known when compiling, so each
    dimension and footprint size gets loops of fixed length (measured: the
    linear billet's evaluation 6% faster than with the footprint's length
    read at run time, GIMP 2-5%). ``only_model``:
    :func:`.material_point.model_tag` of the model every particle's
    material shares (compiled once per model, with only its code), or of
    MIXED.

    F-bar (:mod:`pimpm.kernels.fbar`; de Souza Neto et al. 1996, Coombs et
    al. 2018): ``fbar_cell`` (n,) holds each particle's cell among the
    ``n_cells`` cells averaged on this rank, -1 for particles of materials
    without it (an empty array: none at all). The material then sees
    F_inc_bar = (J_bar / J_inc)^(1/n) F_inc, n the number of stretched
    axes (2 in plane strain, 3 otherwise), J_bar = sum_q V_q J_inc,q /
    sum_q V_q over the cell; F_inc and the force keep the true increment,
    F is F_inc_bar F(t). With ``want_tangent``, ``tangent`` and ``hoop``
    include the particle's own F-bar term and ``fbar_q`` (n, 3, 3) = v Q,
    ``fbar_weight`` (n,) = v / sum_q v_q are what the cell coupling needs.
    ``jbar`` (n,), if not empty, is J_bar averaged on the nodes instead
    (:func:`pimpm.kernels.fbar.node_average`; ``n_cells`` is then 0 and
    fbar_weight 0), and ``F_inc`` holds the increments of ``u`` already
    (:func:`increments`, which the average needed). ``fbar_alpha`` (per material): the exponent alpha of
    F_inc_bar = (J_bar / J_inc)^(alpha / n) F_inc, 1 - the material's
    f_bar_blend (det F_inc_bar = J_bar^alpha J_inc^(1 - alpha)); Q is alpha
    times de Souza Neto's."""
    dim = len(axes)
    n = S.shape[0]
    nn = len(footprint)
    w = np.empty((WORKSPACE, 3, 3))
    D = np.empty((3, 3, 3, 3))
    c_scratch = np.empty((3, 3, 3, 3))
    # plane strain uses only the in-plane entries of the material tangent;
    # the hoop terms (axisymmetric) and the thickness solve (plane stress) use them all
    in_plane = dim == 2 and kinematics == GENERAL
    grad = np.empty((3, 3))
    Finv = np.zeros((3, 3))
    P = np.empty((3, 3))
    # One particle's data is copied into these scratch arrays, allocated once:
    # a view such as F[p] made inside the loop costs numba a reference-count
    # increment and decrement per view and particle (measured: the stress of
    # the billet's 25,600 particles 5.5 ms with views, 4.4 ms without).
    Fi = np.empty((3, 3))
    Fn = np.empty((3, 3))
    Fp = np.empty((3, 3))
    sp = np.empty((3, 3))
    n_history = h_in.shape[1]
    hi = np.empty(n_history)
    ho = np.empty(n_history)
    n_params = params.shape[1]
    prm = np.empty(n_params)
    if want_force:
        force[:] = 0.0
    inverted = 0
    unconverged = 0
    # F-bar: each averaged cell's volume at t and at the iterate
    fbar = len(fbar_cell) > 0 and kinematics != PLANE_STRESS
    nodal = len(jbar) > 0                # J_bar given, averaged on the nodes
    cellwise = fbar and not nodal
    stretched = 2 if (dim == 2 and kinematics == GENERAL) else 3
    cell_volume_n = np.zeros(n_cells if cellwise else 0)
    cell_volume = np.zeros(n_cells if cellwise else 0)
    Fb = np.empty((3, 3))
    if cellwise:                         # every increment first (kept in F_inc), then the cells' sums
        for p in range(n):
            _increment(kinematics, dim, nn, u, node_index, active, S, G, radius, p, grad, Fi)
            for a in range(3):
                for b in range(3):
                    F_inc[p, a, b] = Fi[a, b]
            c = fbar_cell[p]
            if c >= 0:
                cell_volume_n[c] += volume_n[p]
                cell_volume[c] += volume_n[p] * det3(Fi)
    for p in range(n):
        if cellwise or nodal:            # F_inc already holds the increments (nodal: the caller's)
            copy3(F_inc, p, Fi)
        else:
            _increment(kinematics, dim, nn, u, node_index, active, S, G, radius, p, grad, Fi)
        J_inc = det3(Fi)                 # full 3x3: thickness (plane stress), hoop (axisymmetric)
        increment_inverts = not (J_inc > 0.0)
        if increment_inverts:
            inverted += 1
        Fb[:, :] = Fi
        averaged = fbar and fbar_cell[p] >= 0 and not increment_inverts
        if averaged:
            if nodal:
                ratio = jbar[p] / J_inc
            else:
                c = fbar_cell[p]
                ratio = cell_volume[c] / cell_volume_n[c] / J_inc
            if ratio > 0.0:
                scale = ratio ** (fbar_alpha[material_of[p]] / stretched)
                for a in range(stretched):
                    for b in range(stretched):
                        Fb[a, b] = scale * Fi[a, b]
            else:
                averaged = False
        copy3(F_n, p, Fn)
        matmul3(Fb, Fn, Fp)
        m = material_of[p]
        for k in range(n_history):
            hi[k] = h_in[p, k]
            ho[k] = hi[k]
        for k in range(n_params):
            prm[k] = params[m, k]
        if kinematics == PLANE_STRESS:
            converged = solve_thickness(only_model, models[m], prm, Fp, Fi, hi, ho, sp, c_scratch, want_tangent,
                                        w, D)
            if not converged and not increment_inverts:
                unconverged += 1
        else:
            model_point(only_model, models[m], prm, Fp, hi, ho, sp, c_scratch, want_tangent, w, D,
                        in_plane)
        for a in range(3):
            for b in range(3):
                F_inc[p, a, b] = Fi[a, b]
                F[p, a, b] = Fp[a, b]
                sigma[p, a, b] = sp[a, b]
        for k in range(n_history):
            h_out[p, k] = ho[k]
        if kinematics == PLANE_STRESS:
            J_inc = det3(Fi)             # the thickness solve has set F_inc's thickness stretch
        if want_tangent:
            v = volume_n[p] * J_inc      # current volume
            for a in range(dim):
                for cc in range(dim):
                    for b in range(dim):
                        for d in range(dim):
                            tangent[p, a, cc, b, d] = v * (c_scratch[a, cc, b, d]
                                                           + (sp[cc, d] if a == b else 0.0))
            if kinematics == AXISYMMETRIC:
                _hoop_terms(c_scratch, sp, v, dim, hoop[p])
            if fbar:
                if averaged:
                    fbar_weight[p] = 0.0 if nodal else v / cell_volume[fbar_cell[p]]
                    _fbar_own_terms(c_scratch, sp, fbar_alpha[m] * v, dim, stretched, kinematics == AXISYMMETRIC,
                                    fbar_q, p, tangent, hoop)
                else:
                    fbar_weight[p] = 0.0
                    for a in range(3):
                        for b in range(3):
                            fbar_q[p, a, b] = 0.0
        if not want_force:
            continue
        _in_plane_inverse(Fi, dim, Finv)
        for a in range(dim):                         # P = J_inc sigma F_inc^-T (in-plane)
            for b in range(dim):
                s = 0.0
                for cc in range(dim):
                    s += sp[a, cc] * Finv[b, cc]
                P[a, b] = J_inc * s
        V = volume_n[p]
        _scatter_stress(force, node_index, active, p, G, p, P, V, nn, dim)
        if kinematics == AXISYMMETRIC:              # hoop force V P_thth S_ip / r
            h = V * (J_inc * sp[2, 2] / Fi[2, 2]) / radius[p]
            for k in range(nn):
                force[node_index[p, k], 0] += h * S[p, k]
    return inverted, unconverged


@jit
def increments(kinematics, axes, footprint, u, node_index, active, S, G, radius, F_inc):
    """F_inc (n, 3, 3) of every particle for the ghosted-local displacement
    u (:func:`_increment`): what F-bar's nodal average needs before the
    material points are evaluated."""
    grad = np.empty((3, 3))
    Fi = np.empty((3, 3))
    for p in range(S.shape[0]):
        _increment(kinematics, len(axes), len(footprint), u, node_index, active, S, G, radius, p, grad, Fi)
        for a in range(3):
            for b in range(3):
                F_inc[p, a, b] = Fi[a, b]


@jit
def _increment(kinematics, dim, nn, u, node_index, active, S, G, radius, p, grad, Fi):
    """Fi = F_inc of particle p for the ghosted-local displacement u: 1 +
    sum_i u_i (x) G_ip (G&W step 5), and the axisymmetric hoop stretch
    1 + u_r / r."""
    grad[:] = 0.0
    for k in range(nn):
        if not active[p, k]:
            continue
        node = node_index[p, k]
        if dim == 2:              # written out: numba leaves loops of length dim rolled
            u0, u1, g0, g1 = u[node, 0], u[node, 1], G[p, k, 0], G[p, k, 1]
            grad[0, 0] += u0 * g0
            grad[0, 1] += u0 * g1
            grad[1, 0] += u1 * g0
            grad[1, 1] += u1 * g1
        else:
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


@jit
def _fbar_own_terms(c, sigma, v, dim, stretched, axisymmetric, fbar_q, p, tangent, hoop):
    """Particle p's share of the F-bar tangent (de Souza Neto et al. 1996):
    with Q = (c_acbb - (n - 2) sigma_ac) / n (b over the n stretched axes),
    the internal force varies by v g_kc Q_ac (div_bar - div) besides the
    standard terms, div the particle's divergence of the variation and
    div_bar its cell's volume-weighted mean. fbar_q[p] = v Q; the
    -v Q (x) div part is the particle's own (it joins ``tangent`` and, in
    axisymmetry, the hoop couplings: -v Q_ac delta_bd, in-plane row x hoop
    column -v Q_ac, hoop row -v Q_22 delta_bd and -v Q_22); the mean's part
    couples the cell's particles (:mod:`pimpm.kernels.fbar`)."""
    for a in range(3):
        for cc in range(3):
            s = 0.0
            for b in range(stretched):
                s += c[a, cc, b, b]
            fbar_q[p, a, cc] = v * (s - (stretched - 2) * sigma[a, cc]) / stretched
    for a in range(dim):
        for cc in range(dim):
            q = fbar_q[p, a, cc]
            for b in range(dim):
                tangent[p, a, cc, b, b] -= q
    if axisymmetric:
        q22 = fbar_q[p, 2, 2]
        for b in range(dim):
            hoop[p, dim * b + b] -= q22
            for cc in range(dim):
                hoop[p, dim * dim + dim * b + cc] -= fbar_q[p, b, cc]
        hoop[p, 2 * dim * dim] -= q22


@jit
def _hoop_terms(c, sigma, v, dim, out):
    """The axisymmetric tangent's hoop couplings times the current volume:
    out[2 b + d] = v c_22bd, out[2 dim + 2 a + cc] = v c_ac22 (in-plane
    indices, flattened), and the last entry v (c_2222 + sigma_22)."""
    for b in range(dim):
        for d in range(dim):
            out[dim * b + d] = v * c[2, 2, b, d]
            out[dim * dim + dim * b + d] = v * c[b, d, 2, 2]
    out[2 * dim * dim] = v * (c[2, 2, 2, 2] + sigma[2, 2])


@jit
def _scatter_stress(out, node_index, active, p, gradients, q, M, scale, nn, dim):
    """out[node_k, a] += scale sum_b gradients[q, k, b] M[a, b] over particle
    p's active footprint entries k: a stress-like M (P = J_inc sigma F_inc^-T,
    or a stress rate) against its shape-function gradients."""
    for k in range(nn):
        if not active[p, k]:
            continue
        node = node_index[p, k]
        for a in range(dim):
            s = 0.0
            for b in range(dim):
                s += gradients[q, k, b] * M[a, b]
            out[node, a] += scale * s


@jit
def _gradient_scratch(nn):
    """Scratch for :func:`_current_gradients`: F_inc, its in-plane inverse
    (zero outside the plane) and g for a footprint of ``nn`` nodes."""
    return np.empty((3, 3)), np.zeros((3, 3)), np.empty((1, nn, 3))


@jit
def _current_gradients(F_inc, G, p, Fi, Finv, g, nn, dim):
    """Particle p's increment in ``Fi``, its in-plane inverse in ``Finv``
    and its current gradients g = F_inc^-T G: g_kd = G_kc Finv_cd."""
    copy3(F_inc, p, Fi)
    _in_plane_inverse(Fi, dim, Finv)
    for k in range(nn):
        for d in range(dim):
            s = 0.0
            for cc in range(dim):
                s += G[p, k, cc] * Finv[cc, d]
            g[0, k, d] = s


@jit
def tangent_blocks(kinematics, axes, footprint, symmetric, node_index, active, S, G, radius, F_inc, tangent,
                   hoop, node_ijk, width, indptr, slot_position, values):
    """Add every particle's stiffness blocks (G&W step 3, module docstring)
    into ``values`` (zeroed here): the row-oriented values of the block CSR
    ``indptr``/``slot_position`` of :func:`pimpm.kernels.pattern.block_pattern`
    (``node_ijk``: each ghosted-local node's multi-index; ``width``: the
    pattern's stencil half-width). ``tangent`` and ``hoop`` come from
    :func:`evaluate_particles`. ``axes`` = tuple(range(dim)) and ``footprint``
    = tuple(range(nodes per particle)): their lengths are known when
    compiling, so the loops over them have fixed lengths (measured: the
    linear billet's tangent 16% faster than with the footprint's length
    read at run time; one compiled version per footprint size). ``symmetric``:
    the stiffness density has major symmetry (hyperelastic materials), so
    each particle's element matrix is symmetric and only the blocks on and
    above its diagonal are computed, the others added as their transposes.

    Consecutive particles with the same footprint nodes (particles are
    sorted by the nodes they touch: :func:`pimpm.particles.sort_by_footprint`)
    are summed into one dense element matrix first, which
    is then added into ``values`` once: the scattered additions and the
    pattern look-ups are made per group, not per particle."""
    dim = len(axes)
    nn = len(footprint)
    n = S.shape[0]
    values[:] = 0.0
    Finv = np.zeros((3, 3))
    g = np.empty((1, nn, 3))
    B = np.empty((dim, dim * dim))                  # B[d, a dim + b] of one footprint entry
    group_nodes = np.full(nn, -1, dtype=np.int64)   # the footprint of the group being summed
    K = np.zeros((nn, nn, dim * dim))               # its element matrix: block (k, m), entry a dim + b
    used = np.zeros((nn, nn), dtype=np.bool_)       # couplings some particle of the group has
    on = np.empty(nn, dtype=np.int64)               # the particle's active footprint entries
    Fi = np.empty((3, 3))
    axisymmetric = kinematics == AXISYMMETRIC
    for p in range(n):
        same = True
        for k in range(nn):
            if node_index[p, k] != group_nodes[k]:
                same = False
                break
        if not same:
            _add_group(symmetric, group_nodes, K, used, node_ijk, width, indptr, slot_position, values, dim)
            for k in range(nn):
                group_nodes[k] = node_index[p, k]
        _current_gradients(F_inc, G, p, Fi, Finv, g, nn, dim)   # g = F_inc^-T G (0 if inactive)
        r = radius[p] * Fi[2, 2] if axisymmetric else 1.0
        n_on = 0
        for k in range(nn):
            if active[p, k]:
                on[n_on] = k
                n_on += 1
        for i in range(n_on):
            k = on[i]
            for d in range(dim):                # B_abd = g_kc v a_acbd
                for a in range(dim):
                    for b in range(dim):
                        s = 0.0
                        for cc in range(dim):
                            s += g[0, k, cc] * tangent[p, a, cc, b, d]
                        B[d, a * dim + b] = s
            for j in range(i if symmetric else 0, n_on):
                m = on[j]
                used[k, m] = True
                # a block's dim^2 entries innermost and contiguous, over the
                # active entries only (measured on the 3D upsetting's Newton
                # matrices: 13% faster than (k, a, m, b) blocks over all entries;
                # the 2D billet's within 4%)
                for d in range(dim):
                    gm = g[0, m, d]
                    for ab in range(dim * dim):
                        K[k, m, ab] += B[d, ab] * gm
                if axisymmetric:
                    wk = S[p, k] / r
                    wm = S[p, m] / r
                    for b in range(dim):        # hoop row x in-plane column: w_k v c_22bd g_md
                        s = 0.0
                        for d in range(dim):
                            s += hoop[p, dim * b + d] * g[0, m, d]
                        K[k, m, b] += wk * s
                    for a in range(dim):        # in-plane row x hoop column: g_kc v c_ac22 w_m
                        s = 0.0
                        for cc in range(dim):
                            s += g[0, k, cc] * hoop[p, dim * dim + dim * a + cc]
                        K[k, m, a * dim] += s * wm
                    K[k, m, 0] += wk * hoop[p, 2 * dim * dim] * wm
    _add_group(symmetric, group_nodes, K, used, node_ijk, width, indptr, slot_position, values, dim)


@jit
def _add_group(symmetric, nodes, K, used, node_ijk, width, indptr, slot_position, values, dim):
    """Add one group's element matrix ``K`` (nn, nn, dim^2: block (k, m),
    entry (a, b) at a dim + b; its couplings ``used``; with ``symmetric``,
    only blocks k <= m are filled and block (m, k) is added as the transpose
    of block (k, m)) into ``values``, and zero ``K`` and ``used`` for the
    next group."""
    nn = len(nodes)
    for k in range(nn):
        i = nodes[k]
        row = dim * dim * indptr[i]
        stride = (indptr[i + 1] - indptr[i]) * dim   # from one component row to the next
        for m in range(nn):
            if not used[k, m]:
                continue
            used[k, m] = False
            j = nodes[m]
            base = row + (slot_position[i, stencil_slot(i, j, node_ijk, dim, width)] - indptr[i]) * dim
            for a in range(dim):
                for b in range(dim):
                    values[base + a * stride + b] += K[k, m, a * dim + b]
            if symmetric and m != k:            # block (m, k) = block (k, m)^T
                slot = stencil_slot(j, i, node_ijk, dim, width)
                base_t = dim * dim * indptr[j] + (slot_position[j, slot] - indptr[j]) * dim
                stride_t = (indptr[j + 1] - indptr[j]) * dim
                for a in range(dim):
                    for b in range(dim):
                        values[base_t + b * stride_t + a] += K[k, m, a * dim + b]
            for ab in range(dim * dim):
                K[k, m, ab] = 0.0


@jit
def tangent_product(kinematics, axes, footprint, node_index, active, S, G, radius, F_inc, tangent, hoop, x, out):
    """out = K x (out (n_nodes, dim), zeroed here) with K the particles'
    material + geometric stiffness of :func:`tangent_blocks`, without
    forming it (Sulsky & Kaul 2.4.4's matrix-free product, analytic):

        (K x)_ka = sum_p g_kc v a_acbd H_bd,   H = sum_m x_m (x) g_m,  g = F_inc^-T G

    plus the axisymmetric hoop couplings (``hoop`` of
    :func:`evaluate_particles`; w = S / r with r the current radius):
    (K x)_k0 += w_k (v c_22bd H_bd + v (c_2222 + sigma_22) e),
    (K x)_ka += g_kc v c_ac22 e, e = sum_m w_m x_m0. ``x`` is ghosted-local
    (n_nodes, dim); inactive footprint entries are skipped."""
    dim = len(axes)
    nn = len(footprint)
    out[:] = 0.0
    Fi, Finv, g = _gradient_scratch(nn)
    H = np.empty((3, 3))
    rate = np.empty((3, 3))
    axisymmetric = kinematics == AXISYMMETRIC
    for p in range(S.shape[0]):
        _current_gradients(F_inc, G, p, Fi, Finv, g, nn, dim)
        for b in range(dim):
            for d in range(dim):
                s = 0.0
                for m in range(nn):
                    if active[p, m]:
                        s += x[node_index[p, m], b] * g[0, m, d]
                H[b, d] = s
        for a in range(dim):                     # rate_ac = v a_acbd H_bd
            for cc in range(dim):
                s = 0.0
                for b in range(dim):
                    for d in range(dim):
                        s += tangent[p, a, cc, b, d] * H[b, d]
                rate[a, cc] = s
        e = 0.0
        hoop_rate = 0.0
        r = 1.0
        if axisymmetric:
            r = radius[p] * Fi[2, 2]
            for m in range(nn):
                if active[p, m]:
                    e += S[p, m] / r * x[node_index[p, m], 0]
            for b in range(dim):
                for d in range(dim):
                    hoop_rate += hoop[p, dim * b + d] * H[b, d]
            hoop_rate += hoop[p, 2 * dim * dim] * e
        if axisymmetric:                         # the in-plane rows' hoop column: v c_ac22 e
            for a in range(dim):
                for cc in range(dim):
                    rate[a, cc] += hoop[p, dim * dim + dim * a + cc] * e
        _scatter_stress(out, node_index, active, p, g, 0, rate, 1.0, nn, dim)
        if axisymmetric:
            for k in range(nn):
                if active[p, k]:
                    out[node_index[p, k], 0] += S[p, k] / r * hoop_rate


@jit
def _diagonal_block(tangent, p, a, g, k, dim):
    """sum_cd g_kc tangent_acad g_kd: the diagonal entry (k a, k a) of particle p's stiffness."""
    s = 0.0
    for cc in range(dim):
        for d in range(dim):
            s += g[0, k, cc] * tangent[p, a, cc, a, d] * g[0, k, d]
    return s


@jit
def tangent_diagonal(kinematics, axes, footprint, node_index, active, S, G, radius, F_inc, tangent, hoop, out):
    """The diagonal of the particles' stiffness K of :func:`tangent_product`
    (out (n_nodes, dim), zeroed here): K_(ka)(ka) = sum_p g_kc v a_acad g_kd
    plus the hoop terms of the radial component."""
    dim = len(axes)
    nn = len(footprint)
    out[:] = 0.0
    Fi, Finv, g = _gradient_scratch(nn)
    axisymmetric = kinematics == AXISYMMETRIC
    for p in range(S.shape[0]):
        _current_gradients(F_inc, G, p, Fi, Finv, g, nn, dim)
        r = radius[p] * Fi[2, 2] if axisymmetric else 1.0
        for k in range(nn):
            if not active[p, k]:
                continue
            node = node_index[p, k]
            for a in range(dim):
                out[node, a] += _diagonal_block(tangent, p, a, g, k, dim)
            if axisymmetric:
                w = S[p, k] / r
                s = 0.0
                for d in range(dim):
                    s += hoop[p, d] * g[0, k, d] + g[0, k, d] * hoop[p, dim * dim + d]
                out[node, 0] += w * s + w * w * hoop[p, 2 * dim * dim]
