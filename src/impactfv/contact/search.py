"""Contact search (compiled): surface normals, and for each node of one body the closest
facing segment of its partner, with the gap and the contact normal.

2D: the facets of a surface are segments. A 3D search adds point-to-triangle projection
here; the driver and the Riemann step do not change.
"""

import math

import numpy as np
from numba import njit

from ..geometry.bins import bin_of


@njit(cache=True, error_model="numpy")
def surface_normals(x, nodes, segs, nrm):
    """Outward spatial unit normal of the surface nodes (mean of the adjacent segments')."""
    d = x.shape[1]
    for i in range(nodes.shape[0]):
        a = nodes[i]
        for k in range(d):
            nrm[a, k] = 0.0
    for j in range(segs.shape[0]):
        p = segs[j, 0]
        q = segs[j, 1]
        d1 = x[q, 0] - x[p, 0]
        d2 = x[q, 1] - x[p, 1]
        for a in (p, q):
            nrm[a, 0] += 0.5 * d2
            nrm[a, 1] -= 0.5 * d1
    for i in range(nodes.shape[0]):
        a = nodes[i]
        s = math.sqrt(nrm[a, 0] ** 2 + nrm[a, 1] ** 2)
        if s > 0.0:
            nrm[a, 0] /= s
            nrm[a, 1] /= s


@njit(cache=True, error_model="numpy")
def closest_segment(a, x, nrm, segs, origin, h, shape, start, items, pad):
    """Closest master segment facing node a within ``pad``: (segment, xi, distance), or
    (-1, 0, inf). Facing: the segment's outward normal and the node's point towards each
    other (their dot product is negative). xi in [0, 1] is the closest point's position."""
    best = -1
    best_xi = 0.0
    best_d = np.inf
    c = bin_of(x[a], origin, h, shape)
    if c < 0:
        return best, best_xi, best_d
    px = x[a, 0]
    py = x[a, 1]
    for k in range(start[c], start[c + 1]):
        s = items[k]
        p = segs[s, 0]
        q = segs[s, 1]
        d1 = x[q, 0] - x[p, 0]
        d2 = x[q, 1] - x[p, 1]
        L2 = d1 * d1 + d2 * d2
        if d2 * nrm[a, 0] - d1 * nrm[a, 1] >= 0.0:
            continue
        xi = min(max(((px - x[p, 0]) * d1 + (py - x[p, 1]) * d2) / L2, 0.0), 1.0)
        cx = x[p, 0] + xi * d1 - px
        cy = x[p, 1] + xi * d2 - py
        dist = math.sqrt(cx * cx + cy * cy)
        if dist < best_d and dist <= pad:
            best = s
            best_xi = xi
            best_d = dist
    return best, best_xi, best_d


@njit(cache=True, error_model="numpy")
def find_partners(x, slave, nrm, segs, origin, h, shape, start, items, pad, partner,
                  partner_xi, partner_dist, gap, normal):
    """For every slave node: its partner segment (-1 if none within reach), the projection
    xi on it, the distance, the gap g = (x_projection - x_a) . n and the contact normal n
    from the node into the partner (minus the segment's outward normal). Returns the
    smallest gap."""
    gmin = np.inf
    for i in range(slave.shape[0]):
        a = slave[i]
        s, xi, dist = closest_segment(a, x, nrm, segs, origin, h, shape, start, items, pad)
        partner[a] = s
        if s < 0:
            continue
        p = segs[s, 0]
        q = segs[s, 1]
        d1 = x[q, 0] - x[p, 0]
        d2 = x[q, 1] - x[p, 1]
        L = math.sqrt(d1 * d1 + d2 * d2)
        n1 = -d2 / L
        n2 = d1 / L
        g = (x[p, 0] + xi * d1 - x[a, 0]) * n1 + (x[p, 1] + xi * d2 - x[a, 1]) * n2
        partner_xi[a] = xi
        partner_dist[a] = dist
        gap[a] = g
        normal[a, 0] = n1
        normal[a, 1] = n2
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
