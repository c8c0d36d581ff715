"""Overlap step (compiled): which part of each contact node's dual boundary faces lies
against which node of the partner.

Every dual boundary face of a node in contact (2D: the half-edge from the node to its edge
midpoint) is projected on the partner's segments that face it and split where it overlaps the
partner nodes' half-segments. Each overlap becomes a "piece": (node, its face, partner node,
the partner's segment, spatial length, common normal). Because each node receives the traction
over its own dual boundary, a uniform contact pressure is transmitted exactly when the meshes
do not match. 3D replaces the segment overlap by polygon clipping here.
"""

import math

from numba import njit

from ..geometry.bins import bin_of


@njit(cache=True, inline="always", error_model="numpy")
def step_fraction_in_contact(g, gdot, dt, remembered):
    """Fraction of the step the node is in contact: 1 if it was in contact at the end of the
    previous step (it stays until the contact would be tensile) or its gap is closed; for a
    gap g > 0 closing at the rate gdot < 0, the part of the step after the surfaces touch,
    1 - g / (-gdot dt); otherwise 0 (it stays open this step)."""
    if remembered or g <= 0.0:
        return 1.0
    if gdot < 0.0 and g + gdot * dt < 0.0:
        return 1.0 + g / (gdot * dt)
    return 0.0


@njit(cache=True, error_model="numpy")
def closing_fractions(x, v, slave, partner, partner_xi, gap, normal, segs, memory, dt, phi):
    """Fraction of this step each slave node spends in contact (step_fraction_in_contact),
    from its gap and the rate at which its partner segment approaches it."""
    d = x.shape[1]
    for i in range(slave.shape[0]):
        a = slave[i]
        s = partner[a]
        if s < 0:
            phi[a] = 1.0 if memory[a] else 0.0
            continue
        p = segs[s, 0]
        q = segs[s, 1]
        xi = partner_xi[a]
        gdot = 0.0
        for k in range(d):
            gdot += ((1.0 - xi) * v[p, k] + xi * v[q, k] - v[a, k]) * normal[a, k]
        phi[a] = step_fraction_in_contact(gap[a], gdot, dt, memory[a] > 0)


@njit(cache=True, error_model="numpy")
def contact_pieces(x, X, slave, partner, partner_dist, normal, phi, face_start, face_list,
                   bface_others, bface_C, segs, origin, h, shape, start, items, piece_node,
                   piece_face, piece_partner, piece_segment, piece_length, piece_face_length,
                   piece_normal):
    """Pieces of the slave nodes in contact this step (phi > 0) against the master segments
    near them, in node order.

    A master segment takes part when it and the face point towards each other and it lies no
    farther from the node than the closest one plus the length of the face: a face cannot
    touch a surface farther away than its own length. The common normal of a piece is the
    mean of the face's outward normal and the segment's inward one (seed section 3: "a unique
    common normal"); both passes of a contact then see the same normal, also at the ends of
    a face where the two surfaces are not parallel.
    Returns the number of pieces; when it exceeds the capacity of the piece arrays only the
    count is meaningful and the caller grows them and calls again.
    """
    capacity = piece_node.shape[0]
    count = 0
    for i in range(slave.shape[0]):
        a = slave[i]
        if phi[a] == 0.0 or partner[a] < 0:
            continue
        n1 = normal[a, 0]
        n2 = normal[a, 1]
        cell = bin_of(x[a], origin, h, shape)
        for k in range(face_start[a], face_start[a + 1]):
            face = face_list[k]
            o = bface_others[face, 0]
            m1 = 0.5 * (x[a, 0] + x[o, 0])
            m2 = 0.5 * (x[a, 1] + x[o, 1])
            lh = math.sqrt((m1 - x[a, 0]) ** 2 + (m2 - x[a, 1]) ** 2)
            reach = partner_dist[a] + lh
            # outward spatial normal of the face (the half-edge turned like the reference one)
            sign = 1.0
            if bface_C[face, 0] * (X[o, 1] - X[a, 1]) - bface_C[face, 1] * (X[o, 0] - X[a, 0]) < 0.0:
                sign = -1.0
            f1 = sign * (m2 - x[a, 1]) / lh
            f2 = -sign * (m1 - x[a, 0]) / lh
            for it in range(start[cell], start[cell + 1]):
                sm = items[it]
                mp = segs[sm, 0]
                mq = segs[sm, 1]
                e1 = x[mq, 0] - x[mp, 0]
                e2 = x[mq, 1] - x[mp, 1]
                Ls = math.sqrt(e1 * e1 + e2 * e2)
                s1 = -e2 / Ls  # inward normal of the master segment
                s2 = e1 / Ls
                if s1 * n1 + s2 * n2 <= 0.0 or s1 * f1 + s2 * f2 <= 0.0:
                    continue
                off = abs((x[a, 0] - x[mp, 0]) * s1 + (x[a, 1] - x[mp, 1]) * s2)
                if off > reach:
                    continue
                u0 = ((x[a, 0] - x[mp, 0]) * e1 + (x[a, 1] - x[mp, 1]) * e2) / (Ls * Ls)
                u1 = ((m1 - x[mp, 0]) * e1 + (m2 - x[mp, 1]) * e2) / (Ls * Ls)
                lo = min(u0, u1)
                hi = max(u0, u1)
                for side in range(2):
                    b = mp if side == 0 else mq
                    ov = min(hi, 0.5 + 0.5 * side) - max(lo, 0.5 * side)
                    if ov <= 0.0:
                        continue
                    if count < capacity:
                        piece_node[count] = a
                        piece_face[count] = face
                        piece_partner[count] = b
                        piece_segment[count] = sm
                        piece_length[count] = ov * Ls
                        piece_face_length[count] = lh
                        c1 = f1 + s1
                        c2 = f2 + s2
                        cl = math.sqrt(c1 * c1 + c2 * c2)
                        piece_normal[count, 0] = c1 / cl
                        piece_normal[count, 1] = c2 / cl
                    count += 1
    return count


@njit(cache=True, error_model="numpy")
def wall_faces(a, n, x, X, face_start, face_list, bface_others, bface_C, faces, count):
    """Dual boundary faces of node a that face the wall (the normal n points into it):
    appended to ``faces``; returns (new count, the total length of their projections on the
    wall plane). A face meeting the wall at an angle carries the wall traction on its
    projection."""
    total = 0.0
    for k in range(face_start[a], face_start[a + 1]):
        face = face_list[k]
        o = bface_others[face, 0]
        # the spatial half-edge, turned outward like the reference one
        h1 = 0.5 * (x[o, 0] - x[a, 0])
        h2 = 0.5 * (x[o, 1] - x[a, 1])
        sign = 1.0
        if bface_C[face, 0] * (X[o, 1] - X[a, 1]) - bface_C[face, 1] * (X[o, 0] - X[a, 0]) < 0.0:
            sign = -1.0
        projected = sign * (h2 * n[0] - h1 * n[1])
        if projected > 0.0:
            total += projected
            faces[count] = face
            count += 1
    return count, total
