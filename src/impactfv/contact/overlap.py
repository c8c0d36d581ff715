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
from collections import namedtuple

import numpy as np
from numba import njit

from ..compiled import local_vector
from ..geometry.bins import bin_of
from ..geometry.facets import (MAX_POLYGON, clip_polygon, closest_point, dual_face_polygon,
                               dual_face_vector, facet_area_vector, plane_frame, polygon_area,
                               project_to_plane)
from .search import across_own_wall, neighbouring

#: the discretisation's arrays the contact reads: the reference positions; per dual boundary
#: face its reference area vector and the other nodes of its facet; per node its material,
#: and the material table
Discretisation = namedtuple("Discretisation",
                            "X bface_C bface_others node_material material_table")
#: the contact faces (the dual boundary faces on the contact surfaces) of each node,
#: list[start[a]:start[a + 1]] (CSR over all nodes); per boundary face the part of the face
#: and of the step in contact, and its contact velocity times that part
ContactFaces = namedtuple("ContactFaces", "start list weight velocity")
#: the pieces (their capacity the length of the arrays): per piece its slave node, that
#: node's face, the partner node, the partner's facet, the size of the overlap and of the
#: slave's face, and the common normal
Pieces = namedtuple("Pieces", "node face partner segment length face_length normal")


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
def closing_fractions(x, v, slave, found, facets, memory, dt, phi):
    """Fraction of this step each slave node spends in contact (step_fraction_in_contact),
    from its gap and the rate at which the closest point of its partner facet (``found``,
    search.Partners: the facet and the barycentric weights of the point) approaches it."""
    d = x.shape[1]
    for i in range(slave.shape[0]):
        a = slave[i]
        s = found.facet[a]
        if s < 0:
            phi[a] = 1.0 if memory[a] else 0.0
            continue
        gdot = 0.0
        for k in range(d):
            vp = 0.0
            for m in range(d):
                vp += found.weights[a, m] * v[facets[s, m], k]
            gdot += (vp - v[a, k]) * found.normal[a, k]
        phi[a] = step_fraction_in_contact(found.gap[a], gdot, dt, memory[a] > 0)


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
def contact_pieces(x, disc, slave, found, phi, faces, straightness, facets, bins, pieces,
                   skip, pad, deepest):
    """Pieces of the slave nodes in contact this step (phi > 0) against the master facets
    near them, in node order: pieces.length is the size of the overlap (a length in 2D, an
    area in 3D), pieces.face_length the size of the slave's face.

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
    The slave nodes' partners are ``found`` (search.Partners), their contact faces
    ``faces`` (ContactFaces) among the boundary faces of ``disc`` (Discretisation), the
    master facets ``facets`` with their ``bins``; a self-contact node skips its own
    neighbours ``skip`` (search.Skip).
    Writes the pieces into ``pieces`` (Pieces) and returns their number; when it exceeds
    the capacity of the piece arrays only the count is meaningful and the caller grows them
    and calls again.
    """
    if x.shape[1] == 2:
        return _pieces_2d(x, disc, slave, found, phi, faces, straightness, facets, bins,
                          pieces, skip, pad, deepest)
    return _pieces_3d(x, disc, slave, found, phi, faces, facets, bins, pieces, skip, pad,
                      deepest)


@njit(cache=True, inline="always", error_model="numpy")
def _record_piece(pieces, p, a, face, b, facet, length, face_length):
    """Piece p (below the capacity of ``pieces``): node a's face against partner node b of
    the master facet, the overlap's size and the face's; its normal is left to the caller."""
    pieces.node[p] = a
    pieces.face[p] = face
    pieces.partner[p] = b
    pieces.segment[p] = facet
    pieces.length[p] = length
    pieces.face_length[p] = face_length


@njit(cache=True, inline="always", error_model="numpy")
def _face_quadrilateral(x, disc, a, face, f, face_poly):
    """Node a's dual boundary face ``face`` in 3D: its quadrilateral into face_poly and its
    unit outward normal into f; returns (its area, its size: the distance from the node to
    its farthest corner)."""
    face_area = dual_face_vector(x, disc.X, a, disc.bface_others[face], disc.bface_C[face], f)
    for j in range(3):
        f[j] /= face_area
    dual_face_polygon(x, a, disc.bface_others[face], face_poly)
    size = 0.0
    for j in range(1, 4):
        r = 0.0
        for c in range(3):
            r += (face_poly[j, c] - x[a, c]) ** 2
        size = max(size, math.sqrt(r))
    return face_area, size


@njit(cache=True, inline="always", error_model="numpy")
def _facet_meets_face(x, X, a, facet, normal, f, reach, pad, deepest, S, sn, w):
    """Whether the master triangle ``facet`` takes part for node a's face (unit outward
    normal f): it faces both the contact normal and the face, is not the node's own body
    across a wall, and lies within ``reach`` of the node. Its inward unit normal is left in
    sn (S and w: scratch 3-vectors)."""
    area = facet_area_vector(x, facet, S)
    facing_contact = 0.0
    facing_face = 0.0
    for c in range(3):
        sn[c] = -S[c] / area  # inward normal of the master facet
        facing_contact += sn[c] * normal[a, c]
        facing_face += sn[c] * f[c]
    if facing_contact <= 0.0 or facing_face <= 0.0:
        return False
    if across_own_wall(a, x, X, facet, pad, deepest, w):
        return False
    # a facet farther from the node than the reach cannot overlap its face
    if closest_point(x, facet, x[a], w) > reach:
        return False
    return True


@njit(cache=True, inline="always", error_model="numpy")
def _overlap_with_node(x, facet, side, e1, e2, flat_face, others, node_poly, flat_node,
                       work, clipped):
    """Area of the overlap of a face's quadrilateral projected on the plane of the master
    triangle (flat_face, in the plane frame e1, e2 at the triangle's first node) with the
    quadrilateral of the triangle's node ``side``; the other arguments are scratch."""
    b = facet[side]
    others[0] = facet[(side + 1) % 3]
    others[1] = facet[(side + 2) % 3]
    dual_face_polygon(x, b, others, node_poly)
    project_to_plane(node_poly, 4, x[facet[0]], e1, e2, flat_node)
    n_clip = clip_polygon(flat_face, 4, flat_node, 4, work, clipped)
    return abs(polygon_area(clipped, n_clip))


@njit(cache=True, inline="always", error_model="numpy")
def _pieces_3d(x, disc, slave, found, phi, faces, facets, bins, pieces, skip, pad, deepest):
    """contact_pieces in 3D: each face quadrilateral, projected on the plane of a facing
    master triangle, clipped by the quadrilaterals of the triangle's three nodes."""
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
        if phi[a] == 0.0 or found.facet[a] < 0:
            continue
        cell = bin_of(x[a], bins.origin, bins.h, bins.shape)
        for k in range(faces.start[a], faces.start[a + 1]):
            face = faces.list[k]
            face_area, size = _face_quadrilateral(x, disc, a, face, f, face_poly)
            reach = found.distance[a] + size
            for it in range(bins.start[cell], bins.start[cell + 1]):
                sm = bins.items[it]
                if neighbouring(facets, sm, a, skip):
                    continue
                if not _facet_meets_face(x, disc.X, a, facets[sm], found.normal, f, reach,
                                         pad, deepest, S, sn, w):
                    continue
                # the plane frame of the master facet, counter-clockwise about its outward
                # normal, in which its nodes' quadrilaterals are counter-clockwise too
                for c in range(3):
                    S[c] = -sn[c]
                plane_frame(x, facets[sm], S, e1, e2)
                project_to_plane(face_poly, 4, x[facets[sm, 0]], e1, e2, flat_face)
                for side in range(3):
                    ov = _overlap_with_node(x, facets[sm], side, e1, e2, flat_face, others,
                                            node_poly, flat_node, work, clipped)
                    if ov <= 0.0:
                        continue
                    if count < pieces.node.shape[0]:
                        _record_piece(pieces, count, a, face, facets[sm, side], sm, ov,
                                      face_area)
                        cl = 0.0
                        for c in range(3):
                            cl += (f[c] + sn[c]) ** 2
                        cl = math.sqrt(cl)
                        for c in range(3):
                            pieces.normal[count, c] = (f[c] + sn[c]) / cl
                    count += 1
    return count


@njit(cache=True, inline="always", error_model="numpy")
def _half_edge(x, X, bface_C, a, o, face):
    """Node a's dual boundary face ``face`` in 2D, the half-edge from a towards o: (its
    midpoint end m1, m2, its length, its unit outward normal f1, f2)."""
    m1 = 0.5 * (x[a, 0] + x[o, 0])
    m2 = 0.5 * (x[a, 1] + x[o, 1])
    lh = math.sqrt((m1 - x[a, 0]) ** 2 + (m2 - x[a, 1]) ** 2)
    # outward spatial normal of the face (the half-edge turned like the reference one)
    sign = 1.0
    if bface_C[face, 0] * (X[o, 1] - X[a, 1]) - bface_C[face, 1] * (X[o, 0] - X[a, 0]) < 0.0:
        sign = -1.0
    return m1, m2, lh, sign * (m2 - x[a, 1]) / lh, -sign * (m1 - x[a, 0]) / lh


@njit(cache=True, inline="always", error_model="numpy")
def _common_normal_2d(wf, ws, f1, f2, s1, s2):
    """The common normal of a 2D piece: the face's outward normal f and the segment's
    inward one s, weighted by the straightness of their bodies at the piece's nodes."""
    if wf + ws == 0.0:
        # two corners: neither has a normal of its own
        wf = 1.0
        ws = 1.0
    c1 = wf * f1 + ws * s1
    c2 = wf * f2 + ws * s2
    cl = math.sqrt(c1 * c1 + c2 * c2)
    return c1 / cl, c2 / cl


@njit(cache=True, inline="always", error_model="numpy")
def _pieces_2d(x, disc, slave, found, phi, faces, straightness, segs, bins, pieces, skip, pad,
               deepest):
    """contact_pieces in 2D: half-edges against half-segments, by interval overlap."""
    count = 0
    scratch = local_vector(2)
    for i in range(slave.shape[0]):
        a = slave[i]
        if phi[a] == 0.0 or found.facet[a] < 0:
            continue
        n1 = found.normal[a, 0]
        n2 = found.normal[a, 1]
        cell = bin_of(x[a], bins.origin, bins.h, bins.shape)
        for k in range(faces.start[a], faces.start[a + 1]):
            face = faces.list[k]
            m1, m2, lh, f1, f2 = _half_edge(x, disc.X, disc.bface_C, a,
                                            disc.bface_others[face, 0], face)
            reach = found.distance[a] + lh
            for it in range(bins.start[cell], bins.start[cell + 1]):
                sm = bins.items[it]
                if neighbouring(segs, sm, a, skip):
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
                if across_own_wall(a, x, disc.X, segs[sm], pad, deepest, scratch):
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
                    if count < pieces.node.shape[0]:
                        _record_piece(pieces, count, a, face, b, sm, ov * Ls, lh)
                        c1, c2 = _common_normal_2d(straightness[a], straightness[b], f1, f2,
                                                   s1, s2)
                        pieces.normal[count, 0] = c1
                        pieces.normal[count, 1] = c2
                    count += 1
    return count


@njit(cache=True, error_model="numpy")
def wall_faces(a, n, x, disc, faces, found, count):
    """Dual boundary faces of node a (its contact faces ``faces``) that face the wall (the
    normal n points into it): appended to ``found``; returns (new count, the total size of
    their projections on the wall plane). A face meeting the wall at an angle carries the
    wall traction on its projection. Facing, as in search.closest_facet, means not only by
    round-off: the side of a block that meets the wall at a right angle stays a free side
    (a projection of round-off size, of either sign, would otherwise take its free flux off
    for the step)."""
    d = x.shape[1]
    f = local_vector(d)
    total = 0.0
    for k in range(faces.start[a], faces.start[a + 1]):
        face = faces.list[k]
        size = dual_face_vector(x, disc.X, a, disc.bface_others[face], disc.bface_C[face], f)
        projected = 0.0
        for j in range(d):
            projected += f[j] * n[j]
        if projected > 1e-12 * size:
            total += projected
            found[count] = face
            count += 1
    return count, total
