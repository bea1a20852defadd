"""Compiled kernels of unilateral, frictional contact between the material
and a rigid tool (:mod:`pimpm.contact`): the tool's exact geometry as a
signed distance, the contact law at one point, and the contact term's force,
tangent blocks and matrix-free product over the particles' domain corners.

Where contact acts. Each particle's domain (GIMP's box of half sizes l_p,
convected by the diagonal of F) has 2^dim corners x_p + r_c, r_c = (+-l_1,
+-l_2(, +-l_3)).
Over the step a corner moves with the particle's own interpolation, to
first order about x_p (the domain deforms with F_inc, as the particle's
stress does):

    c(u) = x_p + r_c + sum_I w_cI u_I,   w_cI = S_Ip + G_Ip . r_c

so the corner lies where the body's surface lies, and its weights touch
only the particle's own footprint nodes: the contact tangent adds no
nonzero to the step's pattern. A corner inside the tool (signed distance
phi < 0) carries the penalty pressure p = -k_n phi over its share a_c of
the particle's surface; tangentially Coulomb's law (|t| <= mu p: stick;
otherwise slip, t = mu p e) regularized by an elastic slip of at most a
thousandth of a cell (:func:`contact_point`).
"""
import numpy as np

from .jit import jit, jit_inline
from .particle_step import _add_group

HALF_SPACE, BOX, BALL, CYLINDER, MESH = 0, 1, 2, 3, 4
#: a MESH tool's params: the 12 common ones, then (facets, vertices per facet,
#: record length, where the hierarchy starts), then one record per facet
#: (:func:`pimpm.surfaces.pack`): its vertices (3 per vertex), unit normal (3),
#: vertex pseudo-normals (3 per vertex) and, for triangles, edge
#: pseudo-normals (3 per edge: 0-1, 1-2, 2-0); then the
#: bounding-volume hierarchy of the facets, NODE numbers per node: its box
#: (lower 3, upper 3), its children (-1: a leaf) and its facets (first, count)
MESH_HEADER = 16
NODE = 10
#: the nearest feature of a facet: its interior, a vertex (VERTEX + i), an edge (EDGE + i)
INTERIOR, VERTEX, EDGE = 0, 1, 4
#: a point's state; HELD: open, but in contact at the end of the last step and
#: within ``stick`` of the tool (the first Newton iteration keeps its stiffness)
OPEN, STICK, SLIP, HELD = 0, 1, 2, 3


@jit_inline
def _radial_hessian(H, e, d, axes_mask, dim):
    """H += (P - e e^T) / d on the axes of ``axes_mask`` (the Hessian of
    the distance |y| from an axis or a point, e its unit direction)."""
    for a in range(dim):
        for b in range(dim):
            H[a, b] += ((1.0 if (a == b and axes_mask[a]) else 0.0) - e[a] * e[b]) / d


@jit
def _segment_nearest(params, base, y, q):
    """The point ``q`` of segment ``base`` (2D) nearest to ``y``; returns
    (squared distance, feature)."""
    ax, ay = params[base], params[base + 1]
    tx, ty = params[base + 3] - ax, params[base + 4] - ay
    length2 = tx * tx + ty * ty
    s = ((y[0] - ax) * tx + (y[1] - ay) * ty) / length2 if length2 > 0.0 else 0.0
    feature = INTERIOR
    if s <= 0.0:
        s, feature = 0.0, VERTEX
    elif s >= 1.0:
        s, feature = 1.0, VERTEX + 1
    q[0], q[1] = ax + s * tx, ay + s * ty
    return (y[0] - q[0]) ** 2 + (y[1] - q[1]) ** 2, feature


@jit
def _triangle_nearest(params, base, y, q):
    """The point ``q`` of triangle ``base`` nearest to ``y`` (Ericson,
    Real-Time Collision Detection 5.1.5, by Voronoi regions); returns
    (squared distance, feature)."""
    ab = np.empty(3)
    ac = np.empty(3)
    d1 = d2 = d3 = d4 = d5 = d6 = 0.0
    for a in range(3):
        A, B, C = params[base + a], params[base + 3 + a], params[base + 6 + a]
        ab[a], ac[a] = B - A, C - A
        d1 += ab[a] * (y[a] - A)
        d2 += ac[a] * (y[a] - A)
        d3 += ab[a] * (y[a] - B)
        d4 += ac[a] * (y[a] - B)
        d5 += ab[a] * (y[a] - C)
        d6 += ac[a] * (y[a] - C)
    vc = d1 * d4 - d3 * d2
    vb = d5 * d2 - d1 * d6
    va = d3 * d6 - d5 * d4
    origin, s, t, feature = 0, 0.0, 0.0, INTERIOR     # q = vertex origin + s ab + t ac
    if d1 <= 0.0 and d2 <= 0.0:
        feature = VERTEX
    elif d3 >= 0.0 and d4 <= d3:
        origin, feature = 1, VERTEX + 1
    elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        s, feature = d1 / (d1 - d3), EDGE
    elif d6 >= 0.0 and d5 <= d6:
        origin, feature = 2, VERTEX + 2
    elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        t, feature = d2 / (d2 - d6), EDGE + 2
    elif va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        s, t, feature = 1.0 - w, w, EDGE + 1
    else:
        scale = 1.0 / (va + vb + vc)
        s, t = vb * scale, vc * scale
    d2sum = 0.0
    for a in range(3):
        if origin == 0:
            q[a] = params[base + a] + s * ab[a] + t * ac[a]
        else:
            q[a] = params[base + 3 * origin + a]
        d2sum += (y[a] - q[a]) ** 2
    return d2sum, feature


@jit
def _facet_nearest(params, r, y, dim, q):
    """(squared distance, feature) of facet ``r``'s point ``q`` nearest to ``y``."""
    base = MESH_HEADER + r * int(params[14])
    if dim == 2:
        return _segment_nearest(params, base, y, q)
    return _triangle_nearest(params, base, y, q)


@jit_inline
def _plane_distance(params, r, y, dim):
    """Signed distance of ``y`` from the plane of facet ``r`` (its normal's side positive)."""
    base = MESH_HEADER + r * int(params[14])
    normal = base + 3 * int(params[13])
    side = 0.0
    for a in range(dim):
        side += (y[a] - params[base + a]) * params[normal + a]
    return side


@jit
def _mesh_nearest(params, y, dim, q, facing=-1):
    """The facet nearest to ``y``, its nearest point ``q`` and feature: a
    walk down the facets' bounding-volume hierarchy (:func:`pimpm.surfaces.pack`),
    the nearer child first, skipping every box farther than the best facet
    so far. ``facing`` >= 0: only the facets whose normal points within 90
    degrees of that facet's (-1 and no point: there are none)."""
    length = int(params[14])
    tree = int(params[15])
    normal = 3 * int(params[13])
    facing_normal = MESH_HEADER + max(facing, 0) * length + normal
    best, best_d2, best_feature = -1, np.inf, INTERIOR
    trial = np.empty(3)
    stack = np.empty(128, dtype=np.int64)
    top = 0
    stack[0] = 0
    while top >= 0:
        node = tree + NODE * stack[top]
        top -= 1
        if _box_distance2(params, node, y, dim) >= best_d2:
            continue
        left = int(params[node + 6])
        if left < 0:                          # a leaf: its facets
            first = int(params[node + 8])
            for r in range(first, first + int(params[node + 9])):
                if facing >= 0:
                    alignment = 0.0
                    for a in range(dim):
                        alignment += params[MESH_HEADER + r * length + normal + a] * params[facing_normal + a]
                    if not alignment > 0.0:
                        continue
                d2, feature = _facet_nearest(params, r, y, dim, trial)
                if d2 < best_d2:
                    best, best_d2, best_feature = r, d2, feature
                    for a in range(dim):
                        q[a] = trial[a]
            continue
        right = int(params[node + 7])
        d_left = _box_distance2(params, tree + NODE * left, y, dim)
        d_right = _box_distance2(params, tree + NODE * right, y, dim)
        near, far, d_far = (left, right, d_right) if d_left <= d_right else (right, left, d_left)
        if d_far < best_d2:
            top += 1
            stack[top] = far
        top += 1
        stack[top] = near
    return best, best_d2, best_feature


@jit_inline
def _box_distance2(params, node, y, dim):
    """Squared distance of ``y`` from the box of the hierarchy's node at ``node``."""
    gap2 = 0.0
    for a in range(dim):
        below = params[node + a] - y[a]
        above = y[a] - params[node + 3 + a]
        if below > 0.0:
            gap2 += below * below
        elif above > 0.0:
            gap2 += above * above
    return gap2


@jit
def _mesh_distance(params, y, dim, n, H, face):
    """Signed distance of ``y`` from a surface mesh (facets oriented with
    outward normals): the nearest point's distance, signed by the pseudo-normal
    of its feature (the facet's normal inside a facet, the angle-weighted mean
    of the facets' normals at a vertex, the mean of the two at an edge:
    Baerentzen & Aanaes 2005, exact for closed manifold surfaces), with its
    gradient and Hessian: zero inside a facet, (P - n n^T (- t t^T along an
    edge t)) / phi about an edge or vertex (but over a facet's plane to within
    a millionth of ``params[11]``: the joint of coplanar facets is flat).
    ``face`` >= 0: the facet the
    point's particle meets the tool through (:func:`contact_faces`): where
    the point lies over (within ``params[11]`` of) the nearest of the facets
    that face the same way, the distance from that facet's plane (a corner
    that has crossed a thin platen's bottom surface deeper than half its
    thickness, or beside its side, still belongs to the bottom, as with a
    box's face)."""
    k, length = int(params[13]), int(params[14])
    q = np.empty(3)
    if face >= 0:                             # the nearest facet that faces the way ``face`` does
        r, d2, _ = _mesh_nearest(params, y, dim, q, int(face))
        phi = _plane_distance(params, r, y, dim)
        if d2 - phi * phi <= params[11] * params[11]:      # over it (widened by params[11])
            base = MESH_HEADER + r * length
            for a in range(dim):
                n[a] = params[base + 3 * k + a]
            return phi
    r, d2, feature = _mesh_nearest(params, y, dim, q)
    base = MESH_HEADER + r * length
    side = _plane_distance(params, r, y, dim)
    # inside the facet, or over its edge or vertex within a millionth of params[11]
    # (a point over the joint of two coplanar facets is over a flat surface: no curvature)
    if feature == INTERIOR or d2 - side * side <= (1e-6 * params[11]) ** 2:
        for a in range(dim):
            n[a] = params[base + 3 * k + a]
        return side
    if feature >= EDGE:
        pseudo = base + 6 * k + 3 + 3 * (feature - EDGE)
    else:
        pseudo = base + 3 * k + 3 + 3 * (feature - VERTEX)
    d = np.sqrt(d2)
    if d == 0.0:                              # on the surface at an edge or vertex
        for a in range(dim):
            n[a] = params[pseudo + a]
        return 0.0
    side = 0.0
    for a in range(dim):
        side += (y[a] - q[a]) * params[pseudo + a]
    phi = d if side >= 0.0 else -d
    for a in range(dim):
        n[a] = (y[a] - q[a]) / phi
    for a in range(dim):
        for b in range(dim):
            H[a, b] = ((1.0 if a == b else 0.0) - n[a] * n[b]) / phi
    if feature >= EDGE:                       # no curvature along the edge
        i = feature - EDGE
        j = (i + 1) % 3
        t = np.empty(3)
        norm2 = 0.0
        for a in range(3):
            t[a] = params[base + 3 * j + a] - params[base + 3 * i + a]
            norm2 += t[a] * t[a]
        for a in range(3):
            for b in range(3):
                H[a, b] -= t[a] * t[b] / (norm2 * phi)
    return phi


@jit
def tool_distance(kind, params, y, dim, n, H, face=-1):
    """Signed distance of ``y`` from the tool's surface (positive outside),
    its gradient ``n`` (the outward unit normal of the nearest surface
    point) and its Hessian ``H`` (zero on flat faces), for the tool at rest
    (``y``: the point minus the tool's displacement).

    ``face`` (boxes, cylinders and meshes; -1: none): the face the point meets the
    tool through (:func:`contact_faces`). Inside a box the nearest face is
    not always that one: a corner that has just crossed the bottom face
    beside the box's side face (a platen as wide as the body, its side on
    the symmetry plane) is nearer the side. Within the face's extent the
    distance is then the signed distance from the face's plane (the extent
    widened by ``params[11]``, a thousandth of a cell: a corner on the edge
    of a tool as wide as the body must not flicker in and out of contact
    with round-off)."""
    for a in range(dim):
        n[a] = 0.0
        for b in range(dim):
            H[a, b] = 0.0
    if kind == MESH:
        return _mesh_distance(params, y, dim, n, H, face)
    if face >= 0 and kind == BOX:             # face = 2 axis + (1 on the upper side)
        normal_axis = int(face) // 2
        within = True
        for a in range(dim):
            if a != normal_axis and (y[a] < params[a] - params[11] or y[a] > params[3 + a] + params[11]):
                within = False
        if within:
            if int(face) % 2 == 1:
                n[normal_axis] = 1.0
                return y[normal_axis] - params[3 + normal_axis]
            n[normal_axis] = -1.0
            return params[normal_axis] - y[normal_axis]
    if face >= 0 and kind == CYLINDER:        # face 0: the mantle; 1, 2: the lower, upper cap
        axis = int(params[7])
        if face == 0 and params[axis] - params[11] <= y[axis] <= params[3 + axis] + params[11]:
            r2 = 0.0
            for a in range(3):
                if a != axis:
                    r2 += (y[a] - params[8 + a]) ** 2
            r = np.sqrt(r2)
            if r > 0.0:
                mask = np.ones(3, dtype=np.bool_)
                mask[axis] = False
                for a in range(3):
                    n[a] = 0.0 if a == axis else (y[a] - params[8 + a]) / r
                _radial_hessian(H, n, r, mask, 3)
                return r - params[6]
        elif face > 0:
            r2 = 0.0
            for a in range(3):
                if a != axis:
                    r2 += (y[a] - params[8 + a]) ** 2
            if r2 <= (params[6] + params[11]) ** 2:
                if face == 2:
                    n[axis] = 1.0
                    return y[axis] - params[3 + axis]
                n[axis] = -1.0
                return params[axis] - y[axis]
    if kind == HALF_SPACE:                    # point params[0:3], unit normal params[3:6]
        phi = 0.0
        for a in range(dim):
            n[a] = params[3 + a]
            phi += (y[a] - params[a]) * params[3 + a]
        return phi
    if kind == BALL:                          # center params[0:3], radius params[6]
        d2 = 0.0
        for a in range(dim):
            d2 += (y[a] - params[a]) ** 2
        d = np.sqrt(d2)
        if d == 0.0:
            n[dim - 1] = 1.0
            return -params[6]
        mask = np.ones(3, dtype=np.bool_)
        for a in range(dim):
            n[a] = (y[a] - params[a]) / d
        _radial_hessian(H, n, d, mask, dim)
        return d - params[6]
    if kind == BOX:                           # lower params[0:3], upper params[3:6]
        q = np.empty(3)
        s = np.empty(3)
        inside = True
        for a in range(dim):
            c = 0.5 * (params[a] + params[3 + a])
            s[a] = 1.0 if y[a] >= c else -1.0
            q[a] = abs(y[a] - c) - 0.5 * (params[3 + a] - params[a])
            if q[a] > 0.0:
                inside = False
        if inside:                            # the nearest face
            best = 0
            for a in range(1, dim):
                if q[a] > q[best]:
                    best = a
            n[best] = s[best]
            return q[best]
        d2 = 0.0
        mask = np.zeros(3, dtype=np.bool_)
        for a in range(dim):
            if q[a] > 0.0:
                d2 += q[a] * q[a]
                mask[a] = True
        d = np.sqrt(d2)
        for a in range(dim):
            if mask[a]:
                n[a] = s[a] * q[a] / d
        _radial_hessian(H, n, d, mask, dim)
        return d
    # CYLINDER (3D): lower params[0:3], upper params[3:6], radius params[6],
    # axis params[7], center params[8:11]
    axis = int(params[7])
    radial = np.empty(3)
    r2 = 0.0
    for a in range(3):
        radial[a] = 0.0 if a == axis else y[a] - params[8 + a]
        r2 += radial[a] * radial[a]
    r = np.sqrt(r2)
    er = np.zeros(3)
    if r > 0.0:
        for a in range(3):
            er[a] = radial[a] / r
    else:
        er[(axis + 1) % 3] = 1.0
    dr = r - params[6]
    middle = 0.5 * (params[axis] + params[3 + axis])
    sa = 1.0 if y[axis] >= middle else -1.0
    da = abs(y[axis] - middle) - 0.5 * (params[3 + axis] - params[axis])
    mask = np.ones(3, dtype=np.bool_)
    mask[axis] = False
    if dr <= 0.0 and da <= 0.0:               # inside: the nearer of the mantle and the caps
        if dr >= da:
            for a in range(3):
                n[a] = er[a]
            if r > 0.0:
                _radial_hessian(H, er, r, mask, 3)
            return dr
        n[axis] = sa
        return da
    if da <= 0.0:                             # beside the mantle
        for a in range(3):
            n[a] = er[a]
        _radial_hessian(H, er, r, mask, 3)
        return dr
    if dr <= 0.0:                             # above or below a cap
        n[axis] = sa
        return da
    d = np.sqrt(dr * dr + da * da)            # beyond the rim: the distance from the rim circle
    for a in range(3):
        n[a] = (dr * er[a] + (sa * da if a == axis else 0.0)) / d
    # H = (grad g grad g^T - n n^T) / d + (dr / d) Hr, g = (dr, da)
    for a in range(3):
        for b in range(3):
            H[a, b] = (er[a] * er[b] + (1.0 if (a == axis and b == axis) else 0.0) - n[a] * n[b]) / d
    scale = dr / d
    for a in range(3):
        for b in range(3):
            H[a, b] += scale * ((1.0 if (a == b and mask[a]) else 0.0) - er[a] * er[b]) / r
    return d


@jit
def contact_faces(kind, params, x, offset_end, faces):
    """The face each particle meets a box, cylinder or mesh tool through: the one
    its centre ``x`` lies beyond, and only beyond (the tool displaced by
    ``offset_end``: where it is at the start of the step); -1 where the centre lies beyond an edge or inside
    (then the nearest point of the tool counts), and for other tools. A
    mesh's face: the facet nearest to the centre, if the centre lies outside
    the tool and over that facet (its projection on the facet's plane within
    ``params[11]`` of the facet: a point over the joint of coplanar facets
    has one)."""
    n_particles, dim = x.shape
    y_mesh = np.empty(3)
    q = np.empty(3)
    for p in range(n_particles):
        faces[p] = -1
        if kind == MESH:
            for a in range(dim):
                y_mesh[a] = x[p, a] - offset_end[a]
            r, d2, _ = _mesh_nearest(params, y_mesh, dim, q)
            side = _plane_distance(params, r, y_mesh, dim)
            # outside, and above the facet (its interior, or an edge with a coplanar neighbour)
            if side > 0.0 and d2 - side * side <= params[11] * params[11]:
                faces[p] = r
        elif kind == BOX:
            beyond = 0
            for a in range(dim):
                y = x[p, a] - offset_end[a]
                if y < params[a]:
                    beyond += 1
                    faces[p] = 2 * a
                elif y > params[3 + a]:
                    beyond += 1
                    faces[p] = 2 * a + 1
            if beyond != 1:
                faces[p] = -1
        elif kind == CYLINDER:
            axis = int(params[7])
            r2 = 0.0
            for a in range(3):
                if a != axis:
                    r2 += (x[p, a] - offset_end[a] - params[8 + a]) ** 2
            y = x[p, axis] - offset_end[axis]
            outside_radius = r2 > params[6] ** 2
            below, above = y < params[axis], y > params[3 + axis]
            if outside_radius and not (below or above):
                faces[p] = 0
            elif not outside_radius and below:
                faces[p] = 1
            elif not outside_radius and above:
                faces[p] = 2


@jit_inline
def _trial_slip(n, H, slip, history, dim, s, ds, v, Hv):
    """The trial elastic slip s = P v, v = history + slip (dv/dy = I; P = I -
    n n^T), and its derivative ds/dy = P - (n.v) H - n (H v)^T, into ``s``
    and ``ds`` (``v``, ``Hv``: scratch of 3). Returns |s|^2."""
    nv = 0.0
    for a in range(dim):
        v[a] = history[a] + slip[a]
        nv += n[a] * v[a]
    for a in range(dim):
        Hv[a] = 0.0
        for b in range(dim):
            Hv[a] += H[a, b] * v[b]
    norm2 = 0.0
    for a in range(dim):
        s[a] = v[a] - n[a] * nv
        norm2 += s[a] * s[a]
        for b in range(dim):
            ds[a, b] = (1.0 if a == b else 0.0) - n[a] * n[b] - nv * H[a, b] - n[a] * Hv[b]
    return norm2


@jit_inline
def _tied_point(n, H, phi, slip, history, area, kn, kt, dim, f, D, traction, elastic, work):
    """A tied point: the penalty p = -kn phi in both directions (it pulls as
    well as pushes) and a tangential spring t = -kt s on the elastic slip
    s = P (history + slip), never released. Returns (STICK, p, 0)."""
    p = -kn * phi
    s, ds = work[0, 1], work[3]
    _trial_slip(n, H, slip, history, dim, s, ds, work[1, 1], work[1, 2])
    for a in range(dim):
        t = -kt * s[a]
        elastic[a] = s[a]
        traction[a] = t
        f[a] = area * (p * n[a] + t)
        for b in range(dim):
            D[a, b] = area * (-kn * n[a] * n[b] + p * H[a, b] - kt * ds[a, b])
    return STICK, p, 0.0


#: the scratch :func:`contact_point_in` works in: (CONTACT_WORK, 3, 3)
CONTACT_WORK = 5


@jit
def contact_point(kind, params, y, slip, history, area, kn, stick, kt, mu, friction, dim, f, D, traction,
                  elastic, face=-1, hold=False, applied=-1.0, onset=0.0, tied=False):
    """:func:`contact_point_in` with its own scratch (for one point; a loop
    over points hands :func:`contact_point_in` one scratch for all)."""
    return contact_point_in(kind, params, y, slip, history, area, kn, stick, kt, mu, friction, dim, f, D,
                            traction, elastic, face, hold, applied, onset, tied, np.empty((CONTACT_WORK, 3, 3)))


@jit
def contact_point_in(kind, params, y, slip, history, area, kn, stick, kt, mu, friction, dim, f, D, traction,
                     elastic, face, hold, applied, onset, tied, work):
    """The contact law at one point: the force ``f`` on the body (dim), its
    derivative ``D`` = df/dy (dim x dim), the tangential traction on the
    body ``traction`` (dim) and the status (OPEN, STICK, SLIP), for the point
    at ``y`` (relative to the tool at rest) that has moved ``slip`` relative
    to the tool over the step; ``area``: its share of the surface.

    Normal: the penalty p = -kn phi. Tangential (``friction``): Coulomb's law
    regularized by an elastic slip s_e of at most ``stick`` (a length): the
    trial s = P (history + slip) (``history``: the last step's s_e; P = I -
    n n^T); while |s| <= stick the point sticks, t = -(mu p / stick) s, else
    it slips, t = -mu p s / |s|. The tangential stiffness scales with the
    pressure, so whether a point sticks is decided on a length (a thousandth
    of a cell), not on a traction divided by a penalty stiffness: at the
    small pressures of a block under its own weight the latter is 1e-11 m,
    below what Newton's iterates can resolve. At high pressures the
    stiffness is capped at ``kt`` (per area and length; 0: no cap), the
    classical penalty: a point sticks while kt |s| <= mu p, so its elastic
    slip limit grows to mu p / kt; a tangential stiffness far above the
    body's own makes Newton chase the stick-slip front point by point
    (docs/VALIDATION.md, the frictional billet). The elastic slip is carried
    (``elastic``, the next step's ``history``), so a sticking point does not
    creep. ``hold``: the point was in contact at the end of the last step;
    if it is open now but within ``stick`` of the tool, D gets the penalty's
    normal stiffness -kn a n n^T all the same, and if it stuck (``hold`` ==
    STICK, mu > 0) the capped tangential one -kt a (I - n n^T) (status
    HELD, no force): the first Newton iteration of a step, whose predictor
    may lift a resting corner off the tool by round-off, then neither throws
    the body away nor lets it slide freely where it stuck (without the
    tangential part every corner of the frictional billet slipped in the
    first iterate and Newton found the stick zone again a few corners an
    iteration: 9.9 iterations a step against 7.0; holding the corners that
    slipped too took 6.8 on the billet but inverted a particle of the
    linear-shape upsetting; docs/VALIDATION.md).
    ``applied`` >= 0: the pressure is this (the explicit step's, applied at
    its trial state: :meth:`pimpm.terms.contact.ContactTool.settle`), not
    the penalty's at ``y``; 0 is open.
    ``onset`` > 0: the penalty grows smoothly over the first ``onset`` of
    penetration, p = kn phi^2 / (2 onset), and is kn (-phi - onset / 2)
    beyond (continuous with its derivative: a point that flips between
    open and pressed from one Newton iterate to the next does not jump
    between no stiffness and the full penalty; the pairs' law:
    :func:`pimpm.kernels.multifield.pair_forces`).
    ``tied``: the point is welded to the tool once it has touched it
    (``hold``: it touched by the end of the last step): the penalty pulls as
    well as pushes and a tangential spring ``kt`` holds its elastic slip,
    with no limit (:func:`_tied_point`; ``contact: tied``). Over the step in
    which it first presses on the tool it is frictionless (status SLIP): tied
    at once, a corner of the upsetting's bulge that folds onto the platen
    flipped between open and tied from one Newton iterate to the next, and
    the 0.25 mm run failed near 59% with some tangential stiffnesses.
    ``work``: scratch, (CONTACT_WORK, 3, 3) (a few small arrays allocated
    at every point cost more than the law itself on the open points of a
    frictional platen).
    Returns (status, pressure, the slip beyond the elastic one: the
    frictional dissipation is area mu p times it)."""
    n, H = work[0, 0], work[2]
    phi = tool_distance(kind, params, y, dim, n, H, face)
    for a in range(dim):
        f[a] = 0.0
        traction[a] = 0.0
        elastic[a] = 0.0
        for b in range(dim):
            D[a, b] = 0.0
    if tied:
        if hold:                              # tied: bilateral and sticking, once touched
            return _tied_point(n, H, phi, slip, history, area, kn, kt, dim, f, D, traction, elastic, work)
        friction = False                      # not yet: it slides freely over its first step in contact
    if applied >= 0.0:                        # the explicit step's pressure, where the corner is now
        if not applied > 0.0:
            return OPEN, 0.0, 0.0
        phi = -applied / kn
    if not phi <= 0.0:                        # touching (phi = 0, as placed on a tool) is in contact
        if hold and phi < stick:
            held_kt = kt if friction and mu > 0.0 and hold == STICK else 0.0
            for a in range(dim):
                for b in range(dim):
                    D[a, b] = -area * kn * n[a] * n[b] - area * held_kt * ((1.0 if a == b else 0.0) - n[a] * n[b])
            return HELD, 0.0, 0.0
        return OPEN, 0.0, 0.0
    p = -kn * phi                             # the penalty pressure, dp/dy = -kp n
    kp = kn
    if onset > 0.0:
        if phi > -onset:
            p = kn * phi * phi / (2.0 * onset)
            kp = -kn * phi / onset
        else:
            p = -kn * (phi + 0.5 * onset)
    for a in range(dim):
        f[a] = area * p * n[a]
        for b in range(dim):
            D[a, b] = area * (-kp * n[a] * n[b] + p * H[a, b])
    if not friction:
        return SLIP, p, 0.0
    s, ds, t, dt = work[0, 1], work[3], work[0, 2], work[4]
    norm = np.sqrt(_trial_slip(n, H, slip, history, dim, s, ds, work[1, 1], work[1, 2]))
    plastic = 0.0
    # the tangential stiffness k = mu p / stick, at most kt (if kt > 0): beyond
    # the pressure kt stick / mu the elastic slip limit grows as mu p / kt
    capped = kt > 0.0 and mu * p > kt * stick
    limit = mu * p / kt if capped else stick
    if norm <= limit:                         # stick: t = -k s
        status = STICK
        k = kt if capped else mu * p / stick
        for a in range(dim):
            t[a] = -k * s[a]
            elastic[a] = s[a]
            for b in range(dim):
                dt[a, b] = -k * ds[a, b]
                if not capped:                # dk/dy = (mu / stick) dp/dy
                    dt[a, b] += s[a] * mu * kp * n[b] / stick
    else:                                     # slip: t = -mu p e, e = s / |s|
        status = SLIP
        plastic = norm - limit                # the slip beyond the elastic one
        e = work[1, 0]
        for a in range(dim):
            e[a] = s[a] / norm
            t[a] = -mu * p * e[a]
            elastic[a] = limit * e[a]
        for a in range(dim):
            for b in range(dim):
                proj = 0.0
                for c in range(dim):
                    proj += ((1.0 if a == c else 0.0) - e[a] * e[c]) * ds[c, b]
                dt[a, b] = mu * kp * e[a] * n[b] - mu * p / norm * proj
    for a in range(dim):
        f[a] += area * t[a]
        traction[a] = t[a]
        for b in range(dim):
            D[a, b] += area * dt[a, b]
    return status, p, plastic


@jit
def corner_weights(node_index, S, G, half, W, offsets):
    """Each domain corner's offset r_c = (+-l_1, +-l_2(, +-l_3)) from the
    particle (offsets: (n, corners, dim); ``half``: the GIMP domain's half
    sizes, convected by the diagonal of F) and weights w_cI = S_Ip + G_Ip .
    r_c (W: (n, corners, nn)). (Corners r_c = F r0 of the whole F were
    tried: they follow a corner exactly from step to step, but the top row
    of a square compressed by a plate then shears (F_yx up to 0.03) and the
    unloading fails; with friction regularized on a length, the axis-aligned
    domain's step-to-step offset F_xy l does not make a sticking corner
    creep: it is the same at the start of every step.)"""
    n, nn = S.shape
    dim = half.shape[1]
    corners = 1 << dim
    for p in range(n):
        for c in range(corners):
            for a in range(dim):
                offsets[p, c, a] = half[p, a] if (c >> a) & 1 else -half[p, a]
            for k in range(nn):
                w = S[p, k]
                for a in range(dim):
                    w += G[p, k, a] * offsets[p, c, a]
                W[p, c, k] = w


@jit
def corner_areas(kind, params, x, offsets, half, offset_end, axisymmetric, faces, area):
    """Each corner's share of its particle's surface facing the tool: the
    domain's area projected on the plane normal to the tool's normal at the
    corner's start, sum_i |n_i| A_i, over the 2^(dim-1) corners of a face;
    times 2 pi r in axisymmetry (in-plane lengths per unit thickness in
    plane strain and stress). Fixed over the step."""
    n_particles, corners, dim = offsets.shape
    n = np.empty(3)
    H = np.empty((3, 3))
    y = np.empty(3)
    face_area = np.empty(3)
    for p in range(n_particles):
        for a in range(dim):
            face_area[a] = 1.0
            for b in range(dim):
                if b != a:
                    face_area[a] *= 2.0 * half[p, b]
        for c in range(corners):
            for a in range(dim):
                y[a] = x[p, a] + offsets[p, c, a] - offset_end[a]
            tool_distance(kind, params, y, dim, n, H, faces[p])
            s = 0.0
            for a in range(dim):
                s += abs(n[a]) * face_area[a]
            s *= 2.0 / corners
            if axisymmetric:
                s *= 2.0 * np.pi * max(x[p, 0] + offsets[p, c, 0], 0.0)
            area[p, c] = s


@jit_inline
def _gather_corner(W, node_index, p, c, dim, values, out):
    """out = sum_I w_cI values_I over the nodes I of particle p (corner c)."""
    for a in range(dim):
        s = 0.0
        for k in range(W.shape[2]):
            s += W[p, c, k] * values[node_index[p, k], a]
        out[a] = s


@jit_inline
def _corner_at(W, node_index, u_local, x, offsets, offset_end, p, c, dim, y, moved):
    """Corner c of particle p at the iterate: its displacement over the step
    ``moved`` = sum_I w_cI u_I and its position relative to the tool at rest
    ``y`` = x_p + r_c + moved - the tool's displacement."""
    _gather_corner(W, node_index, p, c, dim, u_local, moved)
    for a in range(dim):
        y[a] = x[p, a] + offsets[p, c, a] + moved[a] - offset_end[a]


@jit_inline
def _scatter_corner(W, node_index, p, c, dim, vector, out):
    """out_I += w_cI vector for the nodes I of particle p (corner c)."""
    for k in range(W.shape[2]):
        w = W[p, c, k]
        if w == 0.0:
            continue
        i = node_index[p, k]
        for a in range(dim):
            out[i, a] += w * vector[a]


@jit
def contact_forces(kind, params, node_index, S, G, W, x, offsets, u_local, offset_end, increment, history,
                   area, faces, kn, stick, kt, mu, friction, held, force_local, D, status, pressure, traction,
                   elastic, dissipation, corner_force, applied, tied=False):
    """The contact term at the iterate ``u_local``: each corner's force on
    the body scattered to its particle's nodes (added to ``force_local``;
    ``S``, ``G``: the particles' shape functions and gradients, ``W``: the
    corners' weights :func:`corner_weights` made of them),
    and per corner its derivative ``D`` (n, corners, dim, dim), status,
    pressure, tangential traction on the body, elastic slip (the next
    step's ``history``), frictional dissipation over the step and force on
    the body (``corner_force``). ``held`` (n, corners): the corners to hold;
    ``applied`` (n, corners): each corner's pressure where >= 0 (the explicit
    step's, :func:`contact_point`), the penalty's where -1."""
    n_particles, corners, nn = W.shape
    dim = x.shape[1]
    y = np.empty(3)
    slip = np.empty(3)
    f = np.empty(3)
    t = np.empty(3)
    work = np.empty((CONTACT_WORK, 3, 3))
    u_p = np.empty(3)
    grad = np.empty((3, 3))
    for p in range(n_particles):
        # a corner moves by sum_I (S_Ip + G_Ip . r_c) u_I = u_p + grad_p r_c (corner_weights): the
        # particle's displacement and its gradient, gathered once for its corners
        for a in range(dim):
            u_p[a] = 0.0
            for b in range(dim):
                grad[a, b] = 0.0
        for k in range(nn):
            i = node_index[p, k]
            for a in range(dim):
                u = u_local[i, a]
                u_p[a] += S[p, k] * u
                for b in range(dim):
                    grad[a, b] += u * G[p, k, b]
        for c in range(corners):
            for a in range(dim):
                m = u_p[a]
                for b in range(dim):
                    m += grad[a, b] * offsets[p, c, b]
                y[a] = x[p, a] + offsets[p, c, a] + m - offset_end[a]
                slip[a] = m - increment[a]
            s, pr, plastic = contact_point_in(kind, params, y, slip, history[p, c], area[p, c], kn, stick, kt, mu,
                                              friction, dim, f, D[p, c], t, elastic[p, c], faces[p], held[p, c],
                                              applied[p, c], 0.0, tied, work)
            status[p, c] = s
            pressure[p, c] = pr
            for a in range(dim):
                corner_force[p, c, a] = f[a]
            for a in range(dim):
                traction[p, c, a] = t[a]
            dissipation[p, c] = area[p, c] * mu * pr * plastic     # Coulomb's dissipation over the step
            if s != OPEN and s != HELD:
                _scatter_corner(W, node_index, p, c, dim, f, force_local)


@jit
def contact_blocks(node_index, active, W, D, status, node_ijk, width, indptr, slot_position, values):
    """Add the contact tangent -sum_c w_cI D_c w_cJ (the residual's
    derivative: the force on the body enters it with a minus sign) of every
    particle with a corner in contact (or HELD) into the step pattern's ``values``."""
    n_particles, corners, nn = W.shape
    dim = D.shape[2]
    K = np.zeros((nn, nn, dim * dim))       # block (k, m), entry (a, b) at a dim + b
    used = np.zeros((nn, nn), dtype=np.bool_)
    nodes = np.empty(nn, dtype=np.int64)
    for p in range(n_particles):
        any_contact = False
        for c in range(corners):
            if status[p, c] != OPEN:
                any_contact = True
                for k in range(nn):
                    if not active[p, k]:
                        continue
                    for m in range(nn):
                        if not active[p, m]:
                            continue
                        used[k, m] = True
                        ww = W[p, c, k] * W[p, c, m]
                        for a in range(dim):
                            for b in range(dim):
                                K[k, m, a * dim + b] -= ww * D[p, c, a, b]
        if any_contact:
            for k in range(nn):
                nodes[k] = node_index[p, k]
            _add_group(False, nodes, K, used, node_ijk, width, indptr, slot_position, values, dim)


@jit
def contact_product(node_index, W, D, status, x_local, out_local):
    """out_I += -sum_c w_cI D_c sum_J w_cJ x_J (the contact tangent times x)."""
    n_particles, corners, nn = W.shape
    dim = D.shape[2]
    y = np.empty(3)
    z = np.empty(3)
    for p in range(n_particles):
        for c in range(corners):
            if status[p, c] == OPEN:
                continue
            _gather_corner(W, node_index, p, c, dim, x_local, y)
            for a in range(dim):                # z = -D_c y, once per corner
                s = 0.0
                for b in range(dim):
                    s += D[p, c, a, b] * y[b]
                z[a] = -s
            _scatter_corner(W, node_index, p, c, dim, z, out_local)


@jit
def contact_diagonal(node_index, W, D, status, out_local):
    """out_Ia += -sum_c w_cI^2 D_c[a, a] (the contact tangent's diagonal)."""
    n_particles, corners, nn = W.shape
    dim = D.shape[2]
    for p in range(n_particles):
        for c in range(corners):
            if status[p, c] == OPEN:
                continue
            for k in range(nn):
                w = W[p, c, k]
                i = node_index[p, k]
                for a in range(dim):
                    out_local[i, a] -= w * w * D[p, c, a, a]


@jit
def push_out(kind, params, node_index, W, x, offsets, u_local, offset_end, faces, target, depth, moved, weight):
    """The contact predictor's sums: for every corner deeper than ``depth``
    below its ``target`` distance (n, corners; <= 0) inside the tool at
    ``u_local``, the displacement that would bring it back to that distance
    ((target - phi) n), added to its particle's nodes with the weights |w_cI|
    (``moved`` += |w| d, ``weight`` += |w|; ghosted-local)."""
    n_particles, corners, nn = W.shape
    dim = x.shape[1]
    y = np.empty(3)
    travel = np.empty(3)
    n = np.empty(3)
    H = np.empty((3, 3))
    for p in range(n_particles):
        for c in range(corners):
            _corner_at(W, node_index, u_local, x, offsets, offset_end, p, c, dim, y, travel)
            phi = tool_distance(kind, params, y, dim, n, H, faces[p])
            if not phi < target[p, c] - depth:
                continue
            for k in range(nn):
                w = abs(W[p, c, k])
                if w == 0.0:
                    continue
                i = node_index[p, k]
                weight[i] += w
                for a in range(dim):
                    moved[i, a] += w * (target[p, c] - phi) * n[a]


@jit
def particle_distances(kind, params, node_index, S, x, u_local, offset, out):
    """Each particle centre's signed distance from the tool (displaced by
    ``offset``), the centre moved by its interpolated displacement
    ``u_local`` (zeros: where it is), into ``out``. For the contact term's
    candidates and its check of the others."""
    n_particles, nn = S.shape
    dim = x.shape[1]
    y = np.empty(3)
    n = np.empty(3)
    H = np.empty((3, 3))
    for p in range(n_particles):
        for a in range(dim):
            du = 0.0
            for k in range(nn):
                du += S[p, k] * u_local[node_index[p, k], a]
            y[a] = x[p, a] + du - offset[a]
        out[p] = tool_distance(kind, params, y, dim, n, H)


@jit
def point_distances(kind, params, points, out):
    """The signed distance of each point (n, dim) from the tool at rest."""
    dim = points.shape[1]
    y = np.zeros(3)
    n = np.empty(3)
    H = np.empty((3, 3))
    for p in range(points.shape[0]):
        for a in range(dim):
            y[a] = points[p, a]
        out[p] = tool_distance(kind, params, y, dim, n, H)
