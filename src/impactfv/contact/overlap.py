"""Overlap step (compiled): which part of each contact node's dual boundary faces lies
against which node of the partner.

Every dual boundary face of a candidate node (2D: the half-edge from the node to its edge
midpoint) is projected on the nearby partner segments and split where it overlaps the
partner nodes' half-edges. Each overlap becomes a "piece": (node, its face, partner node,
length, common normal). Because each node receives the traction over its own dual boundary,
a uniform contact pressure is transmitted exactly when the meshes do not match. 3D replaces
the segment overlap by polygon clipping here.
"""

import math

from numba import njit

from ..geometry.bins import bin_of


@njit(cache=True, inline="always")
def is_candidate(g, gdot, dt, was_active, h):
    """Contact candidate: the gap g would close within dt at the rate gdot, or the node was in
    contact at the previous step (or stage) and its gap is below 5% of its edge length h."""
    return g + dt * min(gdot, 0.0) <= 0.0 or (was_active > 0 and g <= 0.05 * h)


@njit(cache=True)
def contact_pieces(x, v, slave, partner, partner_xi, partner_dist, gap, normal, was_active,
                   node_length, dt, face_start, face_list, bface_others, segs, origin, h,
                   shape, start, items, piece_node, piece_face, piece_partner, piece_length,
                   piece_face_length, piece_normal):
    """Pieces of the candidate slave nodes against the master segments, in node order.

    Returns the number of pieces; when it exceeds the capacity of the piece arrays only the
    count is meaningful and the caller grows them and calls again.
    """
    capacity = piece_node.shape[0]
    count = 0
    for i in range(slave.shape[0]):
        a = slave[i]
        s = partner[a]
        if s < 0:
            continue
        p = segs[s, 0]
        q = segs[s, 1]
        xi = partner_xi[a]
        n1 = normal[a, 0]
        n2 = normal[a, 1]
        vB1 = (1.0 - xi) * v[p, 0] + xi * v[q, 0]
        vB2 = (1.0 - xi) * v[p, 1] + xi * v[q, 1]
        gdot = (vB1 - v[a, 0]) * n1 + (vB2 - v[a, 1]) * n2
        if not is_candidate(gap[a], gdot, dt, was_active[a], node_length[a]):
            continue
        L = math.sqrt((x[q, 0] - x[p, 0]) ** 2 + (x[q, 1] - x[p, 1]) ** 2)
        reach = partner_dist[a] + 0.25 * L
        cell = bin_of(x[a], origin, h, shape)
        for k in range(face_start[a], face_start[a + 1]):
            face = face_list[k]
            o = bface_others[face, 0]
            m1 = 0.5 * (x[a, 0] + x[o, 0])
            m2 = 0.5 * (x[a, 1] + x[o, 1])
            lh = math.sqrt((m1 - x[a, 0]) ** 2 + (m2 - x[a, 1]) ** 2)
            for it in range(start[cell], start[cell + 1]):
                sm = items[it]
                mp = segs[sm, 0]
                mq = segs[sm, 1]
                e1 = x[mq, 0] - x[mp, 0]
                e2 = x[mq, 1] - x[mp, 1]
                Ls = math.sqrt(e1 * e1 + e2 * e2)
                c1 = -e2 / Ls  # common normal for this master segment
                c2 = e1 / Ls
                # the face must face the segment: its direction is across c
                u0 = ((x[a, 0] - x[mp, 0]) * e1 + (x[a, 1] - x[mp, 1]) * e2) / (Ls * Ls)
                u1 = ((m1 - x[mp, 0]) * e1 + (m2 - x[mp, 1]) * e2) / (Ls * Ls)
                off = abs((x[a, 0] - x[mp, 0]) * c1 + (x[a, 1] - x[mp, 1]) * c2)
                if off > reach or c1 * n1 + c2 * n2 < 0.5:
                    continue
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
                        piece_length[count] = ov * Ls
                        piece_face_length[count] = lh
                        piece_normal[count, 0] = c1
                        piece_normal[count, 1] = c2
                    count += 1
    return count


@njit(cache=True)
def facing_faces(a, n, F, face_start, face_list, bface_C, faces, count):
    """Dual boundary faces of node a whose outward spatial normal is within 60 degrees of n
    (Nanson: da n = cof(F) dA N), appended to ``faces``; returns (new count, their total
    spatial length)."""
    total = 0.0
    for k in range(face_start[a], face_start[a + 1]):
        face = face_list[k]
        c1 = F[a, 1, 1] * bface_C[face, 0] - F[a, 1, 0] * bface_C[face, 1]
        c2 = -F[a, 0, 1] * bface_C[face, 0] + F[a, 0, 0] * bface_C[face, 1]
        length = math.sqrt(c1 * c1 + c2 * c2)
        if c1 * n[0] + c2 * n[1] > 0.5 * length:
            total += length
            faces[count] = face
            count += 1
    return count, total
