"""Spatial geometry of boundary facets for the contact search and overlap (compiled), the
same calls in 2D and 3D.

A facet is a row of node numbers: a segment (p, q) in 2D, a triangle (p, q, r) in 3D,
oriented outward (docs/architecture.md). A node's dual boundary face on a facet (its share)
is the half-segment from the node to the midpoint in 2D and, in 3D, the quadrilateral
(node, midpoint of one edge, centroid, midpoint of the other edge): a third of the triangle.
Polygons in a facet's plane are handled in the plane's own 2D coordinates.
"""

import math

import numpy as np
from numba import njit

#: most vertices of a polygon clipped in a facet plane (a quadrilateral clipped by one)
MAX_POLYGON = 12


@njit(cache=True, inline="always", error_model="numpy")
def facet_area_vector(x, facet, out):
    """Outward area vector of ``facet`` at positions x into out: (dy, -dx) of a segment
    (its length times its normal), (q - p) x (r - p) / 2 of a triangle. Returns its norm."""
    p = facet[0]
    q = facet[1]
    if facet.shape[0] == 2:
        out[0] = x[q, 1] - x[p, 1]
        out[1] = -(x[q, 0] - x[p, 0])
        return math.sqrt(out[0] * out[0] + out[1] * out[1])
    r = facet[2]
    a0 = x[q, 0] - x[p, 0]
    a1 = x[q, 1] - x[p, 1]
    a2 = x[q, 2] - x[p, 2]
    b0 = x[r, 0] - x[p, 0]
    b1 = x[r, 1] - x[p, 1]
    b2 = x[r, 2] - x[p, 2]
    out[0] = 0.5 * (a1 * b2 - a2 * b1)
    out[1] = 0.5 * (a2 * b0 - a0 * b2)
    out[2] = 0.5 * (a0 * b1 - a1 * b0)
    return math.sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2])


@njit(cache=True, inline="always", error_model="numpy")
def closest_point(x, facet, point, w):
    """Barycentric weights w (one per facet node) of the point of ``facet`` closest to
    ``point``; returns the distance. 2D: the clamped projection on the segment; 3D: the
    closest point of the triangle (its inside, an edge or a vertex)."""
    d = x.shape[1]
    p = facet[0]
    q = facet[1]
    if d == 2:
        e0 = x[q, 0] - x[p, 0]
        e1 = x[q, 1] - x[p, 1]
        L2 = e0 * e0 + e1 * e1
        xi = min(max(((point[0] - x[p, 0]) * e0 + (point[1] - x[p, 1]) * e1) / L2, 0.0), 1.0)
        w[0] = 1.0 - xi
        w[1] = xi
        c0 = x[p, 0] + xi * e0 - point[0]
        c1 = x[p, 1] + xi * e1 - point[1]
        return math.sqrt(c0 * c0 + c1 * c1)
    r = facet[2]
    # Ericson, Real-Time Collision Detection, 5.1.5: regions of the triangle's plane
    ab0, ab1, ab2 = x[q, 0] - x[p, 0], x[q, 1] - x[p, 1], x[q, 2] - x[p, 2]
    ac0, ac1, ac2 = x[r, 0] - x[p, 0], x[r, 1] - x[p, 1], x[r, 2] - x[p, 2]
    ap0, ap1, ap2 = point[0] - x[p, 0], point[1] - x[p, 1], point[2] - x[p, 2]
    d1 = ab0 * ap0 + ab1 * ap1 + ab2 * ap2
    d2 = ac0 * ap0 + ac1 * ap1 + ac2 * ap2
    bp0, bp1, bp2 = point[0] - x[q, 0], point[1] - x[q, 1], point[2] - x[q, 2]
    d3 = ab0 * bp0 + ab1 * bp1 + ab2 * bp2
    d4 = ac0 * bp0 + ac1 * bp1 + ac2 * bp2
    cp0, cp1, cp2 = point[0] - x[r, 0], point[1] - x[r, 1], point[2] - x[r, 2]
    d5 = ab0 * cp0 + ab1 * cp1 + ab2 * cp2
    d6 = ac0 * cp0 + ac1 * cp1 + ac2 * cp2
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    if d1 <= 0.0 and d2 <= 0.0:
        u, v = 0.0, 0.0
    elif d3 >= 0.0 and d4 <= d3:
        u, v = 1.0, 0.0
    elif d6 >= 0.0 and d5 <= d6:
        u, v = 0.0, 1.0
    elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        u, v = d1 / (d1 - d3), 0.0
    elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        u, v = 0.0, d2 / (d2 - d6)
    elif va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        u, v = 1.0 - t, t
    else:
        denom = 1.0 / (va + vb + vc)
        u, v = vb * denom, vc * denom
    w[0] = 1.0 - u - v
    w[1] = u
    w[2] = v
    s = 0.0
    for k in range(3):
        c = w[0] * x[p, k] + w[1] * x[q, k] + w[2] * x[r, k] - point[k]
        s += c * c
    return math.sqrt(s)


@njit(cache=True, inline="always", error_model="numpy")
def _raw_face_vector(x, a, others, out):
    d = x.shape[1]
    if d == 2:
        o = others[0]
        h0 = 0.5 * (x[o, 0] - x[a, 0])
        h1 = 0.5 * (x[o, 1] - x[a, 1])
        out[0] = h1
        out[1] = -h0
        return
    b = others[0]
    c = others[1]
    # diagonals: centroid - x_a and midpoint(ac) - midpoint(ab) = (x_c - x_b) / 2
    g0 = (x[b, 0] + x[c, 0] - 2.0 * x[a, 0]) / 3.0
    g1 = (x[b, 1] + x[c, 1] - 2.0 * x[a, 1]) / 3.0
    g2 = (x[b, 2] + x[c, 2] - 2.0 * x[a, 2]) / 3.0
    m0 = 0.5 * (x[c, 0] - x[b, 0])
    m1 = 0.5 * (x[c, 1] - x[b, 1])
    m2 = 0.5 * (x[c, 2] - x[b, 2])
    out[0] = 0.5 * (g1 * m2 - g2 * m1)
    out[1] = 0.5 * (g2 * m0 - g0 * m2)
    out[2] = 0.5 * (g0 * m1 - g1 * m0)


@njit(cache=True, inline="always", error_model="numpy")
def dual_face_vector(x, X, a, others, reference, out):
    """Outward spatial area vector of node a's dual boundary face on its facet (a and the
    facet's other nodes ``others``) into out; returns its norm. 2D: the half-segment to the
    midpoint; 3D: the quadrilateral (x_a, midpoint to others[0], centroid, midpoint to
    others[1]). The order of ``others`` does not matter: the face is turned like its
    reference area vector ``reference`` is turned against the same face at the reference
    positions X (so that a rotation of the body cannot turn it inside out)."""
    d = x.shape[1]
    _raw_face_vector(X, a, others, out)
    dot = 0.0
    for k in range(d):
        dot += out[k] * reference[k]
    _raw_face_vector(x, a, others, out)
    s = 0.0
    for k in range(d):
        s += out[k] * out[k]
        if dot < 0.0:
            out[k] = -out[k]
    return math.sqrt(s)


@njit(cache=True, inline="always", error_model="numpy")
def dual_face_polygon(x, a, others, poly):
    """Vertices of node a's dual boundary face into the rows of poly; returns their count
    (2 in 2D: x_a and the midpoint; 4 in 3D: x_a, midpoint ab, centroid, midpoint ac)."""
    d = x.shape[1]
    if d == 2:
        o = others[0]
        for k in range(2):
            poly[0, k] = x[a, k]
            poly[1, k] = 0.5 * (x[a, k] + x[o, k])
        return 2
    b = others[0]
    c = others[1]
    for k in range(3):
        poly[0, k] = x[a, k]
        poly[1, k] = 0.5 * (x[a, k] + x[b, k])
        poly[2, k] = (x[a, k] + x[b, k] + x[c, k]) / 3.0
        poly[3, k] = 0.5 * (x[a, k] + x[c, k])
    return 4


@njit(cache=True, inline="always", error_model="numpy")
def plane_frame(x, facet, normal, e1, e2):
    """An orthonormal frame (e1, e2) of a triangle's plane, ``normal`` its unit normal."""
    p = facet[0]
    q = facet[1]
    s = 0.0
    for k in range(3):
        e1[k] = x[q, k] - x[p, k]
        s += e1[k] * e1[k]
    s = math.sqrt(s)
    for k in range(3):
        e1[k] /= s
    e2[0] = normal[1] * e1[2] - normal[2] * e1[1]
    e2[1] = normal[2] * e1[0] - normal[0] * e1[2]
    e2[2] = normal[0] * e1[1] - normal[1] * e1[0]


@njit(cache=True, inline="always", error_model="numpy")
def project_to_plane(poly, count, origin, e1, e2, out):
    """Coordinates (u, v) in the plane frame (origin, e1, e2) of the first ``count`` rows of
    poly (orthogonal projection) into out."""
    for j in range(count):
        u = 0.0
        v = 0.0
        for k in range(3):
            r = poly[j, k] - origin[k]
            u += r * e1[k]
            v += r * e2[k]
        out[j, 0] = u
        out[j, 1] = v


@njit(cache=True, inline="always", error_model="numpy")
def polygon_area(poly, count):
    """Signed area of a polygon in the plane (counter-clockwise positive)."""
    s = 0.0
    for j in range(count):
        k = j + 1 if j + 1 < count else 0
        s += poly[j, 0] * poly[k, 1] - poly[k, 0] * poly[j, 1]
    return 0.5 * s


@njit(cache=True, inline="always", error_model="numpy")
def clip_polygon(subject, count, clip, clip_count, work, out):
    """Sutherland-Hodgman: the part of the polygon ``subject`` (``count`` vertices in the
    plane) inside the convex counter-clockwise polygon ``clip``, into out; returns its
    vertex count. ``work`` and ``out`` hold MAX_POLYGON rows."""
    n = count
    for j in range(n):
        out[j, 0] = subject[j, 0]
        out[j, 1] = subject[j, 1]
    for e in range(clip_count):
        if n == 0:
            break
        f = e + 1 if e + 1 < clip_count else 0
        a0 = clip[e, 0]
        a1 = clip[e, 1]
        t0 = clip[f, 0] - a0
        t1 = clip[f, 1] - a1
        for j in range(n):
            work[j, 0] = out[j, 0]
            work[j, 1] = out[j, 1]
        m = 0
        for j in range(n):
            k = j + 1 if j + 1 < n else 0
            sj = t0 * (work[j, 1] - a1) - t1 * (work[j, 0] - a0)
            sk = t0 * (work[k, 1] - a1) - t1 * (work[k, 0] - a0)
            if sj >= 0.0:
                if m < MAX_POLYGON:
                    out[m, 0] = work[j, 0]
                    out[m, 1] = work[j, 1]
                m += 1
            if (sj >= 0.0) != (sk >= 0.0):
                s = sj / (sj - sk)
                if m < MAX_POLYGON:
                    out[m, 0] = work[j, 0] + s * (work[k, 0] - work[j, 0])
                    out[m, 1] = work[j, 1] + s * (work[k, 1] - work[j, 1])
                m += 1
        n = min(m, MAX_POLYGON)
    return n


@njit(cache=True, error_model="numpy")
def _test_clip(subject, clip):
    """Area of the intersection of two polygons (for the tests)."""
    work = np.empty((MAX_POLYGON, 2))
    out = np.empty((MAX_POLYGON, 2))
    n = clip_polygon(subject, subject.shape[0], clip, clip.shape[0], work, out)
    return polygon_area(out, n)
