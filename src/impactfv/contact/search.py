"""Contact search (compiled): surface normals, and for each node of one body the closest
facing facet of its partner, with the gap and the contact normal.

Facets are segments in 2D and triangles in 3D (geometry.facets); the same loops serve both.
"""

import math
from collections import namedtuple

import numpy as np
from numba import njit

from ..compiled import local_vector
from ..geometry.bins import bin_of
from ..geometry.facets import closest_point, facet_area_vector

#: the bins of the master facets of a pass (geometry.bins.build_bins: Bins(*build_bins(...)))
Bins = namedtuple("Bins", "origin h shape start items")
#: per node, the nodes a self-contact node cannot touch: nodes[start[a]:start[a + 1]] (CSR
#: over all nodes; empty between two bodies)
Skip = namedtuple("Skip", "start nodes")
#: the search results per node, for the slave nodes of the current pass: its partner facet
#: (-1 if none), the barycentric weights of the closest point on it, the distance to it, the
#: gap, and the contact normal from the node into the partner
Partners = namedtuple("Partners", "facet weights distance gap normal")


@njit(cache=True, error_model="numpy")
def surface_normals(x, nodes, facets, nrm):
    """Outward spatial unit normal of the surface nodes: the normalised sum of the area
    vectors of the node's shares of its facets (each of a facet's d nodes owns S / d)."""
    d = x.shape[1]
    S = local_vector(d)
    for i in range(nodes.shape[0]):
        a = nodes[i]
        for k in range(d):
            nrm[a, k] = 0.0
    share = 1.0 / d
    for j in range(facets.shape[0]):
        facet_area_vector(x, facets[j], S)
        for m in range(d):
            a = facets[j, m]
            for k in range(d):
                nrm[a, k] += share * S[k]
    for i in range(nodes.shape[0]):
        a = nodes[i]
        s = 0.0
        for k in range(d):
            s += nrm[a, k] * nrm[a, k]
        s = math.sqrt(s)
        if s > 0.0:
            for k in range(d):
                nrm[a, k] /= s


@njit(cache=True, inline="always", error_model="numpy")
def neighbouring(facets, s, a, skip):
    """Whether facet s has a node among node a's own neighbours on its surface (``skip``,
    self-contact only: a body does not touch itself there)."""
    for k in range(skip.start[a], skip.start[a + 1]):
        for j in range(facets.shape[1]):
            if facets[s, j] == skip.nodes[k]:
                return True
    return False


@njit(cache=True, inline="always", error_model="numpy")
def _offset_from_plane(a, x, facet, scratch):
    """(how far node a lies in front of the facet's plane times its area, that area times the
    facet's size: its area in 2D, the square root of its area in 3D); negative offsets are
    behind the plane. ``scratch``: a d-vector."""
    d = x.shape[1]
    p = facet[0]
    area = facet_area_vector(x, facet, scratch)
    offset = 0.0
    for m in range(d):
        offset += (x[a, m] - x[p, m]) * scratch[m]
    return offset, area * (math.sqrt(area) if d == 3 else area)


@njit(cache=True, inline="always", error_model="numpy")
def across_own_wall(a, x, X, facet, pad, deepest, scratch):
    """Whether, in a self-contact (``deepest`` > 0), the facet is the node's own body's other
    side across a wall rather than a partner (closest_facet; the contact pieces apply the
    same rule): the node lay behind the facet's plane and within ``pad`` of it in the
    reference configuration X, or it now lies behind the plane deeper than ``deepest`` times
    the facet's length (3D: the square root of its area). ``scratch``: a d-vector."""
    if deepest <= 0.0:
        return False
    offset, scale = _offset_from_plane(a, x, facet, scratch)
    if offset < -deepest * scale:
        return True
    offset, scale = _offset_from_plane(a, X, facet, scratch)
    return offset < -1e-12 * scale and closest_point(X, facet, X[a], scratch) <= pad


@njit(cache=True, error_model="numpy")
def closest_facet(a, x, X, nrm, facets, bins, pad, w, skip, deepest):
    """Closest partner facet facing node a within ``pad`` (among those of its bin in
    ``bins``, and not its own neighbours ``skip``): (facet, distance) with the barycentric
    weights of the closest point in w, or (-1, inf). Facing: the facet's outward normal
    and the node's point towards each other (a negative dot product, not only by
    round-off: the faces of two blocks that meet at right angles are not facing).

    ``deepest`` > 0 (self-contact): the body's own other side across a thin wall (the outer
    face of a ring behind its inner face) faces the node as a partner would; taken for one,
    the contact would press the wall together. So a facet is not a partner
    - if the node lay behind its plane and within ``pad`` of it in the reference
      configuration X (they are the two sides of a wall thinner than the search radius; two
      parts of a body that come together lie in front of each other there, or far apart),
    - or if the node now lies behind its plane deeper than ``deepest`` times the facet's
      length (3D: the square root of its area): a wall thinned below the search radius."""
    d = x.shape[1]
    best = -1
    best_d = np.inf
    c = bin_of(x[a], bins.origin, bins.h, bins.shape)
    if c < 0:
        return best, best_d
    S = local_vector(d)
    trial = local_vector(d)
    for k in range(bins.start[c], bins.start[c + 1]):
        s = bins.items[k]
        if neighbouring(facets, s, a, skip):
            continue
        area = facet_area_vector(x, facets[s], S)
        facing = 0.0
        for m in range(d):
            facing += S[m] * nrm[a, m]
        if facing >= -1e-12 * area:
            continue
        if across_own_wall(a, x, X, facets[s], pad, deepest, trial):
            continue
        dist = closest_point(x, facets[s], x[a], trial)
        if dist < best_d and dist <= pad:
            best = s
            best_d = dist
            for m in range(d):
                w[m] = trial[m]
    return best, best_d


#: what the gap of a node beside its partner facet is (find_partners)
BESIDE_OFFSET, BESIDE_IS_OPEN, BESIDE_MEASURED = 0, 1, 2


@njit(cache=True, error_model="numpy")
def find_partners(x, X, slave, nrm, facets, bins, pad, found, skip, beside, deepest):
    """For every slave node, into ``found`` (Partners): its partner facet (-1 if none within
    reach), the barycentric weights of the closest point on it, the distance, the gap and the
    contact normal n from the node into the partner (minus the facet's outward unit normal).
    Returns the smallest gap.

    The gap is g = (x_closest - x_a) . n where the closest point is the node's projection on
    the facet's plane. Where the closest point lies on the facet's end, edge or corner
    instead (the node is beside the facet), ``beside`` says what the gap is:
    - BESIDE_IS_OPEN (3D, and self-contact in 2D): the distance. The node is outside the
      facet's body even when it lies behind the facet's plane, as a node on the side of one
      bar next to the bulging edge of the other does, or a node on the top of a slit next
      to its side.
    - BESIDE_OFFSET (between two bodies in 2D, in the Runge-Kutta stages): the normal
      offset. There a node beside the partner's corner still carries the part of its face
      that overlaps the partner (a small block's corner pressing into a face sank twice as
      deep with the distance, docs/contact.md).
    - BESIDE_MEASURED (between two bodies in 2D, the gap reported after each step): the
      distance where the node lies on the outer side of the facet's end node (its outward
      normal ``nrm``): beside a convex corner of the partner it is outside the partner,
      however far behind the facet's line it lies; beside a reentrant corner the normal
      offset."""
    d = x.shape[1]
    gmin = np.inf
    S = local_vector(d)
    w = local_vector(d)
    for i in range(slave.shape[0]):
        a = slave[i]
        s, dist = closest_facet(a, x, X, nrm, facets, bins, pad, w, skip, deepest)
        found.facet[a] = s
        if s < 0:
            continue
        L = facet_area_vector(x, facets[s], S)
        p = facets[s, 0]
        g = 0.0
        for k in range(d):
            # the projection x_p + sum_m w_m (x_m - x_p) of the node on the facet
            proj = x[p, k]
            for m in range(1, d):
                proj += w[m] * (x[facets[s, m], k] - x[p, k])
            found.normal[a, k] = -S[k] / L
            g += (proj - x[a, k]) * found.normal[a, k]
        if beside != BESIDE_OFFSET and dist > abs(g) * (1.0 + 1e-9) + 1e-12 * (
                math.sqrt(L) if d == 3 else L):
            if beside == BESIDE_IS_OPEN:
                g = dist
            else:
                # 2D: the closest point is the facet's end node with the larger weight
                e = facets[s, 0] if w[0] >= w[1] else facets[s, 1]
                side = 0.0
                for k in range(d):
                    side += (x[a, k] - x[e, k]) * nrm[e, k]
                if side > 0.0:
                    g = dist
        for m in range(d):
            found.weights[a, m] = w[m]
        found.distance[a] = dist
        found.gap[a] = g
        if g < gmin:
            gmin = g
    return gmin


@njit(cache=True, error_model="numpy")
def wall_gaps(x, slave, point_on_wall, wall_normal, gap, normal):
    """Gap of every slave node to a rigid plane (normal out of the wall) and the contact
    normal n = -wall_normal; returns the smallest gap."""
    d = x.shape[1]
    gmin = np.inf
    for i in range(slave.shape[0]):
        a = slave[i]
        g = 0.0
        for k in range(d):
            g += (x[a, k] - point_on_wall[k]) * wall_normal[k]
            normal[a, k] = -wall_normal[k]
        gap[a] = g
        if g < gmin:
            gmin = g
    return gmin


@njit(cache=True, error_model="numpy")
def near_each_other(x, slave, facets, pad, slave_near, facets_near):
    """The slave nodes within ``pad`` of the bounding box of the master facets, and the
    master facets whose bounding box comes within ``pad`` of the slave nodes' box (written
    into slave_near and facets_near; returns both counts). Only these can touch within the
    search radius, so the bins and the search cover the part of the two surfaces where they
    meet, not the whole of them."""
    d = x.shape[1]
    slo = np.full(d, np.inf)
    shi = np.full(d, -np.inf)
    for i in range(slave.shape[0]):
        a = slave[i]
        for k in range(d):
            slo[k] = min(slo[k], x[a, k])
            shi[k] = max(shi[k], x[a, k])
    mlo = np.full(d, np.inf)
    mhi = np.full(d, -np.inf)
    n_facets = 0
    for f in range(facets.shape[0]):
        inside = True
        for k in range(d):
            flo = np.inf
            fhi = -np.inf
            for j in range(facets.shape[1]):
                c = x[facets[f, j], k]
                flo = min(flo, c)
                fhi = max(fhi, c)
            mlo[k] = min(mlo[k], flo)
            mhi[k] = max(mhi[k], fhi)
            if fhi < slo[k] - pad or flo > shi[k] + pad:
                inside = False
        if inside:
            facets_near[n_facets] = f
            n_facets += 1
    n_slave = 0
    for i in range(slave.shape[0]):
        a = slave[i]
        inside = True
        for k in range(d):
            if x[a, k] < mlo[k] - pad or x[a, k] > mhi[k] + pad:
                inside = False
        if inside:
            slave_near[n_slave] = a
            n_slave += 1
    return n_slave, n_facets


@njit(cache=True, error_model="numpy")
def forget_partners(slave, partner):
    """No partner for any of the slave nodes (before a search of those near the partner)."""
    for i in range(slave.shape[0]):
        partner[slave[i]] = -1
