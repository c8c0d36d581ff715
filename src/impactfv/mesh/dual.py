"""The median dual of a triangle mesh (numerics.md B.1, B.4, B.5).

For a triangle e with centroid X_e, the dual face of its edge ab is the segment from the edge
midpoint to X_e; its area vector C_ab^e is that segment rotated so that C_ab^e . (X_b - X_a)
> 0. C_ab sums the one or two triangles sharing ab. A boundary edge (a, b) of length L and
outward normal N gives each end node a half-edge area vector C_gamma = (L/2) N. The dual
area of a node is a third of the area of each triangle around it.

Closure: sum_b C_ab + sum_gamma C_gamma = 0 at every node. With the boundary value
u_gamma = (5 u_a + u_b)/6 on the half-edge of node a, the Green-Gauss gradient
grad u_a = (1/Omega_a)[ sum_b (u_a + u_b)/2 (x) C_ab + sum_gamma u_gamma (x) C_gamma ] is exact
for linear fields.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .trimesh import boundary_edges_of, directed_edges, edge_keys, keys_to_edges


@dataclass
class MedianDual:
    edges: np.ndarray            # (m,2) int, a < b, sorted by a then b
    area_vectors: np.ndarray     # (m,2) C_ab, oriented from a to b
    dual_areas: np.ndarray       # (n,) Omega_a
    boundary_edges: np.ndarray   # (k,2) int, body on the left of a->b
    boundary_normals: np.ndarray  # (k,2) C_gamma = (L/2) N, the same for both end nodes
    node_length: np.ndarray      # (n,) shortest incident edge length (time step scale)


def median_dual(points: np.ndarray, triangles: np.ndarray) -> MedianDual:
    n = len(points)
    centroid = points[triangles].mean(axis=1)
    directed = directed_edges(triangles)
    mid = 0.5 * (points[directed[:, 0]] + points[directed[:, 1]])
    d = np.tile(centroid, (3, 1)) - mid
    # triangles are counter-clockwise, so the centroid is left of a->b and (dy, -dx) points a->b
    c_directed = np.column_stack([d[:, 1], -d[:, 0]])
    sign = np.where(directed[:, 0] < directed[:, 1], 1.0, -1.0)
    keys, inverse = np.unique(edge_keys(directed), return_inverse=True)
    edges = keys_to_edges(keys)
    m = len(edges)
    area_vectors = np.column_stack([np.bincount(inverse, sign * c_directed[:, j], minlength=m)
                                    for j in range(2)])

    p = points[triangles]
    tri_area = 0.5 * ((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                      - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0]))
    dual_areas = np.bincount(triangles.ravel(), np.repeat(tri_area / 3.0, 3), minlength=n)

    bnd = boundary_edges_of(triangles)
    t = points[bnd[:, 1]] - points[bnd[:, 0]]
    boundary_normals = 0.5 * np.column_stack([t[:, 1], -t[:, 0]])

    length = np.linalg.norm(points[edges[:, 1]] - points[edges[:, 0]], axis=1)
    node_length = np.full(n, np.inf)
    np.minimum.at(node_length, edges[:, 0], length)
    np.minimum.at(node_length, edges[:, 1], length)
    return MedianDual(edges.astype(np.int64), area_vectors, dual_areas, bnd.astype(np.int64),
                      boundary_normals, node_length)


def green_gauss_gradient(dual: MedianDual, u: np.ndarray) -> np.ndarray:
    """Nodal gradient (n, k, 2) of nodal values u (n, k) (reference implementation in numpy)."""
    u = np.asarray(u, dtype=float)
    if u.ndim == 1:
        u = u[:, None]
    a, b = dual.edges[:, 0], dual.edges[:, 1]
    flux = 0.5 * (u[a] + u[b])[:, :, None] * dual.area_vectors[:, None, :]
    g = np.zeros(u.shape + (2,))
    np.add.at(g, a, flux)
    np.add.at(g, b, -flux)
    ba, bb = dual.boundary_edges[:, 0], dual.boundary_edges[:, 1]
    cg = dual.boundary_normals[:, None, :]
    np.add.at(g, ba, ((5 * u[ba] + u[bb]) / 6)[:, :, None] * cg)
    np.add.at(g, bb, ((5 * u[bb] + u[ba]) / 6)[:, :, None] * cg)
    return g / dual.dual_areas[:, None, None]
