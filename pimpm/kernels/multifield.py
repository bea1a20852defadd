"""Compiled kernels of contact between deformable bodies that each carry
their own grid velocity field (:mod:`pimpm.fields`; Bardenhagen, Brackbill &
Sulsky 2000, with the contact detected at the particles' true surfaces).

A body's field lives on "field nodes": grid node i of field f is field
node ``i * n_fields + f``, so the transfer kernels run unchanged on the
particles' field-node indices and a DMDA of ``n_fields`` times the dofs
holds every field of a node side by side.

At a node that two fields f and g both reach:

- each field's outward normal comes from its mass gradient
  (:func:`outward_normals`);
- the gap is the distance between the two bodies' surfaces near the node
  along a normal: each field's farthest particle-domain point along it over
  the particles that reach the node (the domains convected by F:
  :func:`surface_extents`), so contact
  engages where the particles' domains meet, not a cell early. Of the two
  fields' normals the one with the larger gap is the contact normal n (the
  separating axis: a flat face's normal, not that of a corner sliding on
  it);
- if over the step the relative normal velocity w_n = (v_f - v_g) . n would
  close more than the gap, equal and opposite impulses remove the excess
  (no interpenetration), and never pull (the bodies separate freely);
- tangentially Coulomb's law: the impulse that would stop the relative
  sliding, at most mu times the normal impulse (stick; otherwise slip);
- a bonded pair moves with its centre-of-mass velocity (one shared field).
"""
import numpy as np

from .contact import (CONTACT_WORK, HALF_SPACE, HELD, OPEN, SLIP, STICK,  # noqa: F401 (a pair's state: the law's)
                      contact_point_in)
from .jit import jit, jit_inline

BONDED, FRICTIONLESS, FRICTION = 0, 1, 2
#: candidate contact normals per field and node (:func:`outward_normals`)
AXES = 3
#: the per-pair sums kept by :func:`pair_impulses`: normal and tangential
#: impulse, nodes in contact, frictional dissipation
PAIR_SUMS = 4


@jit
def mass_gradients(axes, footprint, node_index, G, mass, out):
    """out[i] = sum_p m_p grad S_i(x_p) over the particles of each field node
    i (``out`` (n_field_nodes, dim), zeroed here): it points out of the
    body's particles, towards the node."""
    out[:] = 0.0
    for p in range(node_index.shape[0]):
        m = mass[p]
        for k in footprint:
            i = node_index[p, k]
            for a in axes:
                out[i, a] += m * G[p, k, a]


@jit
def outward_normals(mass, gradient, floor, out, partner):
    """At the owned nodes where fields meet (``mass`` (n, F), ``gradient``
    (n, F, dim)), field f's candidate contact normals (``out`` (n, F,
    AXES, dim)): ``out[:, f, 0]`` its own unit outward normal, ``out[:, f,
    1]`` the opposite of its partner's (the other field with the most mass
    there, ``partner`` (n, F); -1 where f meets no other field, and the
    normals zero), ``out[:, f, 2]`` the mean of the two. grad m_f = sum_p m_p grad S_i(x_p) points
    out of body f (each grad S_i(x_p) points from the particle towards the
    node)."""
    n, n_fields, dim = gradient.shape
    out[:] = 0.0
    partner[:] = -1
    for i in range(n):
        present = 0
        for f in range(n_fields):
            if mass[i, f] > floor:
                present += 1
        if present < 2:
            continue
        for f in range(n_fields):
            if mass[i, f] <= floor:
                continue
            length = 0.0
            for a in range(dim):
                length += gradient[i, f, a] * gradient[i, f, a]
            length = np.sqrt(length)
            if length > 0.0:
                for a in range(dim):
                    out[i, f, 0, a] = gradient[i, f, a] / length
            most = 0.0
            for g in range(n_fields):
                if g != f and mass[i, g] > most and mass[i, g] > floor:
                    most, partner[i, f] = mass[i, g], g
        for f in range(n_fields):
            g = partner[i, f]
            if g < 0:
                continue
            length = 0.0
            for a in range(dim):
                out[i, f, 1, a] = -out[i, g, 0, a]
                out[i, f, 2, a] = out[i, f, 0, a] - out[i, g, 0, a]
                length += out[i, f, 2, a] * out[i, f, 2, a]
            length = np.sqrt(length)
            for a in range(dim):
                out[i, f, 2, a] = out[i, f, 2, a] / length if length > 0.0 else 0.0


@jit
def surface_extents(axes, footprint, node_index, S, x, F, half, normal, out):
    """out[i, j] = the largest x_p . n + sum_d |n . F_p e_d| l_pd over the
    particles with a weight at field node i, for its field's candidate
    normals n = normal[i, j] (:func:`outward_normals`; l_p the particle
    domain's initial half sizes): the farthest point along n of the
    particle's domain convected by F (a parallelogram or parallelepiped: a
    rolling body's domains turn with it), so how far along n the body's
    surface reaches near the node. ``out`` holds -1e300 where no particle
    reaches or the normal is zero (set here)."""
    out[:] = -1e300
    for p in range(node_index.shape[0]):
        for k in footprint:
            if S[p, k] <= 0.0:
                continue
            i = node_index[p, k]
            for j in range(AXES):
                e = 0.0
                length = 0.0
                for a in axes:
                    e += x[p, a] * normal[i, j, a]
                    length += normal[i, j, a] * normal[i, j, a]
                for d in axes:
                    column = 0.0
                    for a in axes:
                        column += normal[i, j, a] * F[p, a, d]
                    e += abs(column) * half[p, d]
                if length > 0.0 and e > out[i, j]:
                    out[i, j] = e


@jit_inline
def _separating_axis(normal, extent, partner, i, f, g, axis):
    """The separating axis of fields f and g at node i: of f's own outward
    normal, the opposite of g's and their mean, the one along which the
    surfaces are farthest apart (a flat face's normal, not the rounded
    corner's of a block sliding on it), into ``axis`` (left as it is
    without one); returns the gap along it (-1e300: none)."""
    gap = -1e300
    if partner[i, f] == g and partner[i, g] == f:
        for j in range(AXES):
            # g's candidates are f's, reversed: its own is f's second
            opposite = 1 if j == 0 else (0 if j == 1 else 2)
            candidate = -(extent[i, f, j] + extent[i, g, opposite])
            if candidate > gap:
                gap = candidate
                for a in range(normal.shape[3]):
                    axis[a] = normal[i, f, j, a]
    return gap


@jit
def pair_impulses(mass, velocity, normal, extent, partner, law, mu, dt, floor, sums, orientation, node_status,
                  node_impulse):
    """Apply the contact law to the end-of-step velocities ``velocity`` (n,
    F, dim; in place) at every owned node two fields reach (``mass`` (n,
    F), ``normal``, ``partner``: :func:`outward_normals`, ``extent`` the
    surfaces' reach along the normals, ``law`` and ``mu`` (F, F) each pair's law and
    coefficient). Adds each pair's normal and tangential impulse, contact
    nodes and frictional dissipation into ``sums`` (F * F, PAIR_SUMS). The
    impulses are equal and opposite: momentum is kept exactly. Per node
    (the output; frictionless and frictional pairs), set here:
    ``node_status`` (n,) the most slipping state of its pairs (OPEN,
    STICK, SLIP; a frictionless pair in contact slips), and
    ``node_impulse`` (n, 1 + dim) the sum of its pairs' normal impulses
    and of the impulses on each pair's first listed body (the field whose
    ``orientation`` (F, F) is +1)."""
    n, n_fields, dim = velocity.shape
    w = np.empty(dim)
    nv = np.empty(dim)
    for i in range(n):
        node_status[i] = OPEN
        for a in range(node_impulse.shape[1]):
            node_impulse[i, a] = 0.0
        for f in range(n_fields):
            mf = mass[i, f]
            if mf <= floor:
                continue
            for g in range(f + 1, n_fields):
                mg = mass[i, g]
                if mg <= floor:
                    continue
                reduced = mf * mg / (mf + mg)
                row = f * n_fields + g
                if law[f, g] == BONDED:                  # one field: the centre-of-mass velocity
                    for a in range(dim):
                        dv = velocity[i, f, a] - velocity[i, g, a]
                        velocity[i, f, a] -= reduced * dv / mf
                        velocity[i, g, a] += reduced * dv / mg
                    continue
                for a in range(dim):
                    nv[a] = 0.0
                gap = _separating_axis(normal, extent, partner, i, f, g, nv)
                length = 0.0
                for a in range(dim):
                    length += nv[a] * nv[a]
                if gap <= -1e299 or length <= 0.0:
                    continue
                wn = 0.0
                for a in range(dim):
                    w[a] = velocity[i, f, a] - velocity[i, g, a]
                    wn += w[a] * nv[a]
                allowed = max(gap, 0.0) / dt
                if wn <= allowed:                        # not closing the gap over the step: open
                    continue
                pn = reduced * (wn - allowed)            # the normal impulse's size, on g along +n
                wt2 = 0.0
                for a in range(dim):
                    w[a] -= wn * nv[a]                   # tangential relative velocity
                    wt2 += w[a] * w[a]
                wt = np.sqrt(wt2)
                pt = 0.0                                 # the tangential impulse's size, against w_t
                if law[f, g] == FRICTION and wt > 0.0:
                    pt = min(reduced * wt, mu[f, g] * pn)    # what stops the sliding, at most mu pn
                for a in range(dim):
                    impulse = pn * nv[a] + (pt * w[a] / wt if wt > 0.0 else 0.0)
                    velocity[i, f, a] -= impulse / mf
                    velocity[i, g, a] += impulse / mg
                    node_impulse[i, 1 + a] -= orientation[f, g] * impulse
                node_impulse[i, 0] += pn
                # the friction force's work on the step's slip (the positions move
                # with the new velocities)
                wt_after = wt - pt / reduced
                sliding = law[f, g] != FRICTION or wt_after > 1e-12 * wt
                node_status[i] = max(node_status[i], SLIP if sliding else STICK)
                sums[row, 0] += pn
                sums[row, 1] += pt
                sums[row, 2] += 1.0
                sums[row, 3] += pt * wt_after


@jit
def pair_candidates(mass, density, normal, extent, partner, floor, nodes, fields, normals, gaps, shares):
    """The implicit step's contact candidates: every (owned node, f < g) that
    both fields reach, with the pair's separating axis n (from f towards g)
    and the gap along it at the start of the step, as in
    :func:`pair_impulses`; fills ``nodes`` (k,), ``fields`` (k, 2),
    ``normals`` (k, dim), ``gaps`` (k,) (sized for the worst case) and
    returns k; ``shares`` (k,): the smaller of the two fields' volumes at the
    node over the larger (their masses over their fields' densities
    ``density``), the pair's share of the node's surface. A pair without a
    usable axis (a field's normal is zero) gets a zero normal: only a bonded
    law acts there."""
    n, n_fields = mass.shape
    dim = normal.shape[3]
    k = 0
    for i in range(n):
        for f in range(n_fields):
            if mass[i, f] <= floor:
                continue
            for g in range(f + 1, n_fields):
                if mass[i, g] <= floor:
                    continue
                for a in range(dim):
                    normals[k, a] = 0.0
                gap = _separating_axis(normal, extent, partner, i, f, g, normals[k])
                nodes[k] = i
                fields[k, 0] = f
                fields[k, 1] = g
                gaps[k] = gap if gap > -1e299 else 0.0
                vf, vg = mass[i, f] / density[f], mass[i, g] / density[g]
                shares[k] = min(vf, vg) / max(vf, vg)
                k += 1
    return k


@jit
def pair_forces(nodes, fields, normals, gaps, law, mu, u, dim, n_fields, areas, kn, stick, kt, history, held, onset,
                force, D, status, pressure, slip, elastic_slip):
    """The contact law of each candidate pair at the iterate ``u`` (owned
    field dofs, flat): with d = u_f - u_g the relative displacement over the
    step, field f is a point at the signed distance gap - d . n from field
    g's surface, a half-space (:func:`pimpm.kernels.contact.contact_point`:
    the rigid tools' penalty and regularized Coulomb law, the penalty
    growing smoothly over its first ``onset`` of penetration; the elastic
    slip carried in from the last step at the same grid node: ``history``
    (k, dim); ``held`` (k,): the pair's status at the end of the last step,
    for the first Jacobian's hold, or OPEN); ``areas`` (k,): each pair's
    share of a node's surface. A bonded pair is held by the penalty kn in
    every direction. Fills the force on field f (``force`` (k, dim); field
    g gets its opposite), D = d force / d d (k, dim, dim), the status, the
    pressure, the slip beyond the elastic one and the elastic slip (the
    next step's history)."""
    params = np.zeros(12)
    y = np.zeros(3)
    d = np.zeros(3)
    carried = np.zeros(3)
    f = np.zeros(3)
    Dp = np.zeros((3, 3))
    traction = np.zeros(3)
    elastic = np.zeros(3)
    work = np.empty((CONTACT_WORK, 3, 3))
    for k in range(len(nodes)):
        f_field, g_field = fields[k, 0], fields[k, 1]
        base_f = (nodes[k] * n_fields + f_field) * dim
        base_g = (nodes[k] * n_fields + g_field) * dim
        for a in range(dim):
            d[a] = u[base_f + a] - u[base_g + a]
        kind = law[f_field, g_field]
        area = areas[k]
        length = 0.0
        for a in range(dim):
            length += normals[k, a] * normals[k, a]
        if kind == BONDED or length == 0.0:
            for a in range(dim):
                force[k, a] = -area * kn * d[a] if kind == BONDED else 0.0
                for b in range(dim):
                    D[k, a, b] = -area * kn if (a == b and kind == BONDED) else 0.0
            status[k] = STICK if kind == BONDED else OPEN
            pressure[k] = 0.0
            slip[k] = 0.0
            for a in range(dim):
                elastic_slip[k, a] = 0.0
            continue
        for a in range(dim):                 # the half-space of g: through the origin, normal -n
            params[a] = 0.0
            params[3 + a] = -normals[k, a]
            y[a] = -gaps[k] * normals[k, a] + d[a]
            carried[a] = history[k, a]
        state, p, plastic = contact_point_in(HALF_SPACE, params, y, d, carried, area, kn, stick, kt,
                                             mu[f_field, g_field], kind == FRICTION, dim, f, Dp, traction, elastic,
                                             -1, held[k], -1.0, onset, False, work)
        for a in range(dim):
            elastic_slip[k, a] = elastic[a]
        for a in range(dim):
            force[k, a] = f[a]
            for b in range(dim):
                D[k, a, b] = Dp[a, b]
        status[k] = state
        pressure[k] = p
        slip[k] = plastic


@jit
def pair_blocks(local_nodes, fields, D, n_fields, node_ijk, dim, width, indptr, slot_position, values):
    """Add each pair's four blocks (rows and columns f, g of its node:
    -D, +D / +D, -D, the derivative of the residual -force on f, +force on g)
    into the step's COO values (scalar CSR layout of
    :mod:`pimpm.kernels.pattern`); ``local_nodes``: the pairs' ghosted-local
    grid nodes."""
    side = 2 * width + 1
    for k in range(len(local_nodes)):
        for r in range(2):
            row = local_nodes[k] * n_fields + fields[k, r]
            length = indptr[row + 1] - indptr[row]
            for c in range(2):
                col = local_nodes[k] * n_fields + fields[k, c]
                slot = 0
                for ax in range(dim - 1, -1, -1):
                    slot = slot * side + node_ijk[col, ax] - node_ijk[row, ax] + width
                block = slot_position[row, slot] - indptr[row]
                sign = -1.0 if r == c else 1.0
                for a in range(dim):
                    start = dim * dim * indptr[row] + a * length * dim + block * dim
                    for b in range(dim):
                        values[start + b] += sign * D[k, a, b]


@jit
def pair_product(local_nodes, fields, D, n_fields, dim, x_local, out_local):
    """out += the pairs' blocks times ``x_local`` (ghosted-local field nodes, (n, dim))."""
    for k in range(len(local_nodes)):
        nf = local_nodes[k] * n_fields + fields[k, 0]
        ng = local_nodes[k] * n_fields + fields[k, 1]
        for a in range(dim):
            s = 0.0
            for b in range(dim):
                s += D[k, a, b] * (x_local[nf, b] - x_local[ng, b])
            out_local[nf, a] -= s
            out_local[ng, a] += s
