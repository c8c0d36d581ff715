"""Overlap step (compiled): which part of each contact node's dual boundary faces lies
against which node of the partner.

Every dual boundary face of a node in contact (2D: the half-edge from the node to its edge
midpoint; 3D: the quadrilateral, a third of a boundary triangle) is projected on the
partner's facets that face it and split where it overlaps the partner nodes' dual faces (2D:
half-segments, by interval overlap; 3D: quadrilaterals, by polygon clipping in the facet's
plane). Each overlap becomes a "piece": (node, its face, partner node, the partner's facet,
spatial size, common normal). Because each node receives the traction over its own dual
boundary, a uniform contact pressure is transmitted exactly when the meshes do not match.
"""

import math

import numpy as np
from numba import njit

from ..compiled import local_vector
from ..geometry.bins import bin_of
from ..geometry.facets import (MAX_POLYGON, clip_polygon, closest_point, dual_face_polygon,
                               dual_face_vector, facet_area_vector, plane_frame, polygon_area,
                               project_to_plane)
from .search import across_own_wall, neighbouring


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
def closing_fractions(x, v, slave, partner, partner_w, gap, normal, facets, memory, dt, phi):
    """Fraction of this step each slave node spends in contact (step_fraction_in_contact),
    from its gap and the rate at which the closest point of its partner facet (barycentric
    weights partner_w) approaches it."""
    d = x.shape[1]
    for i in range(slave.shape[0]):
        a = slave[i]
        s = partner[a]
        if s < 0:
            phi[a] = 1.0 if memory[a] else 0.0
            continue
        gdot = 0.0
        for k in range(d):
            vp = 0.0
            for m in range(d):
                vp += partner_w[a, m] * v[facets[s, m], k]
            gdot += (vp - v[a, k]) * normal[a, k]
        phi[a] = step_fraction_in_contact(gap[a], gdot, dt, memory[a] > 0)


def boundary_straightness(X, bface_node, bface_others):
    """How straight the reference boundary is at each node: -cos of the angle between its
    two boundary half-edges (1 where the boundary goes straight on, 0 at a right corner),
    clipped at 0 for sharper corners; 1 at nodes without exactly two boundary half-edges
    (interior nodes, 3D). Set once, from the reference geometry: a corner of the body stays
    its corner."""
    n, d = X.shape
    straightness = np.ones(n)
    if d != 2 or len(bface_node) == 0:
        return straightness
    count = np.bincount(bface_node, minlength=n)
    order = np.argsort(bface_node, kind="stable")
    nodes = bface_node[order]
    pairs = order[np.isin(nodes, np.flatnonzero(count == 2))].reshape(-1, 2)
    a = bface_node[pairs[:, 0]]
    d1 = X[bface_others[pairs[:, 0], 0]] - X[a]
    d2 = X[bface_others[pairs[:, 1], 0]] - X[a]
    cosine = np.einsum("ij,ij->i", d1, d2) / (np.linalg.norm(d1, axis=1)
                                                * np.linalg.norm(d2, axis=1))
    straightness[a] = np.maximum(0.0, -cosine)
    return straightness


@njit(cache=True, error_model="numpy")
def contact_pieces(x, X, slave, partner, partner_dist, normal, phi, face_start, face_list,
                   bface_others, bface_C, straightness, facets, origin, h, shape, start, items,
                   piece_node, piece_face, piece_partner, piece_segment, piece_length,
                   piece_face_length, piece_normal, skip_start, skip_nodes, pad,
                   deepest):
    """Pieces of the slave nodes in contact this step (phi > 0) against the master facets
    near them, in node order: piece_length is the size of the overlap (a length in 2D, an
    area in 3D), piece_face_length the size of the slave's face.

    A master facet takes part when it and the face point towards each other and it lies no
    farther from the node than the closest one plus the size of the face: a face cannot
    touch a surface farther away than its own size. The common normal of a piece is the
    mean of the face's outward normal and the facet's inward one (seed section 3: "a unique
    common normal"), in 2D each weighted by how straight its own body's boundary is at the
    node the piece belongs to (``straightness``, 1 on a straight boundary, 0 at a right or
    sharper corner): a corner has no normal of its own, so where a corner meets a face the
    face's normal is the contact normal (docs/contact.md, "Pieces"). Both passes
    of a contact then see the same normal, also at the ends of a face where the two
    surfaces are not parallel.
    In a self-contact (``deepest`` > 0) a facet that is the node's own body's other side
    across a wall (search.across_own_wall, with the search radius ``pad``) takes no part,
    as it is no partner in the search: a node remembered in contact with its gap opened
    reaches that far, and its pieces pressed the wall together.
    Returns the number of pieces; when it exceeds the capacity of the piece arrays only the
    count is meaningful and the caller grows them and calls again.
    """
    if x.shape[1] == 2:
        return _pieces_2d(x, X, slave, partner, partner_dist, normal, phi, face_start,
                          face_list, bface_others, bface_C, straightness, facets, origin, h,
                          shape, start, items, piece_node, piece_face, piece_partner,
                          piece_segment, piece_length, piece_face_length, piece_normal,
                          skip_start, skip_nodes, pad, deepest)
    return _pieces_3d(x, X, slave, partner, partner_dist, normal, phi, face_start, face_list,
                      bface_others, bface_C, facets, origin, h, shape, start, items,
                      piece_node, piece_face, piece_partner, piece_segment, piece_length,
                      piece_face_length, piece_normal, skip_start, skip_nodes, pad, deepest)


@njit(cache=True, inline="always", error_model="numpy")
def _pieces_3d(x, X, slave, partner, partner_dist, normal, phi, face_start, face_list,
               bface_others, bface_C, facets, origin, h, shape, start, items, piece_node,
               piece_face, piece_partner, piece_segment, piece_length, piece_face_length,
               piece_normal, skip_start, skip_nodes, pad, deepest):
    """contact_pieces in 3D: each face quadrilateral, projected on the plane of a facing
    master triangle, clipped by the quadrilaterals of the triangle's three nodes."""
    capacity = piece_node.shape[0]
    count = 0
    f = local_vector(3)
    S = local_vector(3)
    sn = local_vector(3)
    e1 = local_vector(3)
    e2 = local_vector(3)
    face_poly = np.empty((4, 3))
    node_poly = np.empty((4, 3))
    flat_face = np.empty((4, 2))
    flat_node = np.empty((4, 2))
    work = np.empty((MAX_POLYGON, 2))
    clipped = np.empty((MAX_POLYGON, 2))
    others = np.empty(2, np.int64)
    w = local_vector(3)
    for i in range(slave.shape[0]):
        a = slave[i]
        if phi[a] == 0.0 or partner[a] < 0:
            continue
        cell = bin_of(x[a], origin, h, shape)
        for k in range(face_start[a], face_start[a + 1]):
            face = face_list[k]
            face_area = dual_face_vector(x, X, a, bface_others[face], bface_C[face], f)
            for j in range(3):
                f[j] /= face_area
            dual_face_polygon(x, a, bface_others[face], face_poly)
            size = 0.0
            for j in range(1, 4):
                r = 0.0
                for c in range(3):
                    r += (face_poly[j, c] - x[a, c]) ** 2
                size = max(size, math.sqrt(r))
            reach = partner_dist[a] + size
            for it in range(start[cell], start[cell + 1]):
                sm = items[it]
                if neighbouring(facets, sm, a, skip_start, skip_nodes):
                    continue
                area = facet_area_vector(x, facets[sm], S)
                facing_contact = 0.0
                facing_face = 0.0
                for c in range(3):
                    sn[c] = -S[c] / area  # inward normal of the master facet
                    facing_contact += sn[c] * normal[a, c]
                    facing_face += sn[c] * f[c]
                if facing_contact <= 0.0 or facing_face <= 0.0:
                    continue
                if across_own_wall(a, x, X, facets[sm], pad, deepest, w):
                    continue
                mp = facets[sm, 0]
                # a facet farther from the node than the reach cannot overlap its face
                if closest_point(x, facets[sm], x[a], w) > reach:
                    continue
                # the plane frame of the master facet, counter-clockwise about its outward
                # normal, in which its nodes' quadrilaterals are counter-clockwise too
                for c in range(3):
                    S[c] = -sn[c]
                plane_frame(x, facets[sm], S, e1, e2)
                project_to_plane(face_poly, 4, x[mp], e1, e2, flat_face)
                for side in range(3):
                    b = facets[sm, side]
                    others[0] = facets[sm, (side + 1) % 3]
                    others[1] = facets[sm, (side + 2) % 3]
                    dual_face_polygon(x, b, others, node_poly)
                    project_to_plane(node_poly, 4, x[mp], e1, e2, flat_node)
                    n_clip = clip_polygon(flat_face, 4, flat_node, 4, work, clipped)
                    ov = abs(polygon_area(clipped, n_clip))
                    if ov <= 0.0:
                        continue
                    if count < capacity:
                        piece_node[count] = a
                        piece_face[count] = face
                        piece_partner[count] = b
                        piece_segment[count] = sm
                        piece_length[count] = ov
                        piece_face_length[count] = face_area
                        cl = 0.0
                        for c in range(3):
                            cl += (f[c] + sn[c]) ** 2
                        cl = math.sqrt(cl)
                        for c in range(3):
                            piece_normal[count, c] = (f[c] + sn[c]) / cl
                    count += 1
    return count


@njit(cache=True, inline="always", error_model="numpy")
def _pieces_2d(x, X, slave, partner, partner_dist, normal, phi, face_start, face_list,
                   bface_others, bface_C, straightness, segs, origin, h, shape, start, items,
                   piece_node, piece_face, piece_partner, piece_segment, piece_length,
                   piece_face_length, piece_normal, skip_start, skip_nodes, pad, deepest):
    """contact_pieces in 2D: half-edges against half-segments, by interval overlap."""
    capacity = piece_node.shape[0]
    count = 0
    scratch = local_vector(2)
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
                if neighbouring(segs, sm, a, skip_start, skip_nodes):
                    continue
                mp = segs[sm, 0]
                mq = segs[sm, 1]
                e1 = x[mq, 0] - x[mp, 0]
                e2 = x[mq, 1] - x[mp, 1]
                Ls = math.sqrt(e1 * e1 + e2 * e2)
                s1 = -e2 / Ls  # inward normal of the master segment
                s2 = e1 / Ls
                if s1 * n1 + s2 * n2 <= 0.0 or s1 * f1 + s2 * f2 <= 0.0:
                    continue
                if across_own_wall(a, x, X, segs[sm], pad, deepest, scratch):
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
                        wf = straightness[a]
                        ws = straightness[b]
                        if wf + ws == 0.0:
                            # two corners: neither has a normal of its own
                            wf = 1.0
                            ws = 1.0
                        c1 = wf * f1 + ws * s1
                        c2 = wf * f2 + ws * s2
                        cl = math.sqrt(c1 * c1 + c2 * c2)
                        piece_normal[count, 0] = c1 / cl
                        piece_normal[count, 1] = c2 / cl
                    count += 1
    return count


@njit(cache=True, error_model="numpy")
def wall_faces(a, n, x, X, face_start, face_list, bface_others, bface_C, faces, count):
    """Dual boundary faces of node a that face the wall (the normal n points into it):
    appended to ``faces``; returns (new count, the total size of their projections on the
    wall plane). A face meeting the wall at an angle carries the wall traction on its
    projection. Facing, as in search.closest_facet, means not only by round-off: the side
    of a block that meets the wall at a right angle stays a free side (a projection of
    round-off size, of either sign, would otherwise take its free flux off for the step)."""
    d = x.shape[1]
    f = local_vector(d)
    total = 0.0
    for k in range(face_start[a], face_start[a + 1]):
        face = face_list[k]
        size = dual_face_vector(x, X, a, bface_others[face], bface_C[face], f)
        projected = 0.0
        for j in range(d):
            projected += f[j] * n[j]
        if projected > 1e-12 * size:
            total += projected
            faces[count] = face
            count += 1
    return count, total
