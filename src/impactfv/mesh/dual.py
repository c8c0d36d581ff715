"""The median dual of a triangle or tetrahedral mesh (docs/theory.md, "Space").

For a triangle e with centroid X_e, the dual face of its edge ab is the segment from the edge
midpoint to X_e; its area vector C_ab^e is that segment rotated so that C_ab^e . (X_b - X_a)
> 0. C_ab sums the one or two triangles sharing ab. A boundary facet (an edge in 2D) with
outward area vector S gives each of its d nodes the share C_gamma = S / d (2D: (L/2) N). The
dual area of a node is a third of the area of each triangle around it.

Closure: sum_b C_ab + sum_gamma C_gamma = 0 at every node. With the boundary value
u_gamma = (5 u_a + u_b)/6 on the half-edge of node a (3D: (6 u_a + u_b + u_c)/8 on a third
of a triangle), the Green-Gauss gradient
grad u_a = (1/Omega_a)[ sum_b (u_a + u_b)/2 (x) C_ab + sum_gamma u_gamma (x) C_gamma ] is exact
for linear fields.

Tetrahedra (3D): the dual face of edge ab inside tetrahedron e is the quadrilateral (edge
midpoint, centroid of face abc, centroid X_e, centroid of face abd), c and d the other two
nodes; its area vector is half the cross product of its diagonals, oriented from a to b
(C_ab^e . (X_b - X_a) = V_e / 2 exactly). A boundary triangle gives each of its three nodes
S / 3, and each node owns a quarter of the volume of each tetrahedron around it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .edges import TET_EDGES, boundary_facets, directed_edges, edge_keys, keys_to_edges

#: boundary closure (weight of the node itself, denominator), the others weigh 1
CLOSURE = {2: (5.0, 6.0), 3: (6.0, 8.0)}


@dataclass
class MedianDual:
    edges: np.ndarray            # (m, 2) int, a < b, sorted by a then b
    area_vectors: np.ndarray     # (m, d) C_ab, oriented from a to b
    volumes: np.ndarray          # (n,) Omega_a (areas in 2D)
    facets: np.ndarray           # (k, d) boundary facets, oriented outward
    facet_vectors: np.ndarray    # (k, d) outward area vector S of each facet (2D: L N)
    node_length: np.ndarray      # (n,) time step length scale (time_step_length)

    @property
    def dim(self) -> int:
        return self.area_vectors.shape[1]


def median_dual(points: np.ndarray, cells: np.ndarray) -> MedianDual:
    """The median dual of a triangle mesh (points (n, 2)) or a tetrahedral mesh (n, 3)."""
    points = np.asarray(points, dtype=float)
    cells = np.asarray(cells, dtype=np.int64)
    if points.shape[1] == 3:
        directed, c_directed, volumes = _tetrahedra(points, cells)
    else:
        directed, c_directed, volumes = _triangles(points, cells)
    d = points.shape[1]
    sign = np.where(directed[:, 0] < directed[:, 1], 1.0, -1.0)
    keys, inverse = np.unique(edge_keys(directed), return_inverse=True)
    edges = keys_to_edges(keys)
    m = len(edges)
    area_vectors = np.column_stack([np.bincount(inverse, sign * c_directed[:, j], minlength=m)
                                    for j in range(d)])
    facets = boundary_facets(cells, d)
    facet_vectors = facet_area_vectors(points, facets)
    node_length = time_step_length(points, edges, volumes, facets, facet_vectors, area_vectors)
    return MedianDual(edges.astype(np.int64), area_vectors, volumes, facets.astype(np.int64),
                      facet_vectors, node_length)


def facet_area_vectors(points: np.ndarray, facets: np.ndarray) -> np.ndarray:
    """Outward area vector S of each boundary facet: (dy, -dx) of an edge (its length times
    its normal), or (b - a) x (c - a) / 2 of a triangle."""
    if facets.shape[1] == 2:
        t = points[facets[:, 1]] - points[facets[:, 0]]
        return np.column_stack([t[:, 1], -t[:, 0]])
    p = points[facets]
    return 0.5 * np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])


def _triangles(points, triangles):
    """Directed edges, their dual-face area vectors (from the edge's first to its second
    node) within each triangle, and the dual areas."""
    n = len(points)
    centroid = points[triangles].mean(axis=1)
    directed = directed_edges(triangles)
    mid = 0.5 * (points[directed[:, 0]] + points[directed[:, 1]])
    d = np.tile(centroid, (3, 1)) - mid
    # triangles are counter-clockwise, so the centroid is left of a->b and (dy, -dx) points a->b
    c_directed = np.column_stack([d[:, 1], -d[:, 0]])
    p = points[triangles]
    tri_area = 0.5 * ((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                      - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0]))
    volumes = np.bincount(triangles.ravel(), np.repeat(tri_area / 3.0, 3), minlength=n)
    return directed, c_directed, volumes


def _tetrahedra(points, tets):
    """The same for tetrahedra: the dual face of edge (a, b) in tetrahedron e is the
    quadrilateral (midpoint of ab, centroid of abc, centroid of e, centroid of abd)."""
    n = len(points)
    p = points[tets]
    centroid = p.mean(axis=1)
    directed = directed_edges(tets, 3)
    vectors = []
    for a, b in TET_EDGES:
        c, d = (k for k in range(4) if k not in (a, b))
        mid = 0.5 * (p[:, a] + p[:, b])
        face_c = (p[:, a] + p[:, b] + p[:, c]) / 3.0
        face_d = (p[:, a] + p[:, b] + p[:, d]) / 3.0
        area = 0.5 * np.cross(centroid - mid, face_d - face_c)
        # orient from a to b (the dot product is +-V/2, never zero for a proper tetrahedron)
        flip = np.einsum("ij,ij->i", area, p[:, b] - p[:, a]) < 0.0
        area[flip] *= -1.0
        vectors.append(area)
    volume = np.einsum("ij,ij->i", p[:, 1] - p[:, 0],
                       np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0])) / 6.0
    volumes = np.bincount(tets.ravel(), np.repeat(volume / 4.0, 4), minlength=n)
    return directed, np.concatenate(vectors), volumes


def time_step_length(points, edges, volumes, facets, facet_vectors, area_vectors=None):
    """Length h_a of the time step dt = cfl min_a h_a lambda_min / c_p (docs/theory.md, "Time
    step").

    The shortest edge at node a, and at a boundary node at most 4 Omega_a / A_a, with A_a
    the area of its dual boundary faces. The second bound is the stability of the boundary
    flux: it relaxes a boundary node's traction at the rate c_p A_a / Omega_a (p-wave
    impedance), a real eigenvalue for which the two-stage Runge-Kutta scheme needs
    dt c_p A_a / Omega_a <= 2. The default cfl 0.4 is 0.8 of the interior limit (about 0.5);
    4 Omega_a / A_a applies the same fraction to this one. It binds only where a boundary
    node has a small control volume, such as a corner node with a single triangle
    (4 Omega / A = 2h/3 on a right-angled corner of legs h).

    3D: an interior node's h_a is at most 4 Omega_a / A_int,a, A_int,a the area of its dual
    faces: the first-order upwind flux relaxes it at the rate c_p A_int / (2 Omega), the
    interior counterpart of the boundary bound. On triangles it is never below the shortest
    edge of the regular patterns (the 2D rule is kept as it was); on tetrahedra the shortest
    edge overestimates it (4 Omega / A_int = 0.72-0.88 h inside a box of Kuhn cells of edge h,
    0.62 h on a gmsh mesh), and a free block at nu = 0.495 blew up at cfl 0.35 with the
    shortest edge alone. With this bound the exact stability limit of the linearised scheme
    is cfl 0.43-0.46 (order 1) and 0.50-0.55 (order 2) on those meshes, against 0.42 and
    0.50 for the 2D rule on triangles (tests/test_time_step.py).
    """
    n = len(points)
    length = np.linalg.norm(points[edges[:, 1]] - points[edges[:, 0]], axis=1)
    node_length = np.full(n, np.inf)
    np.minimum.at(node_length, edges[:, 0], length)
    np.minimum.at(node_length, edges[:, 1], length)
    boundary_area = np.zeros(n)
    if len(facets):
        # each of a facet's d nodes owns 1/d of it (median dual)
        share = np.linalg.norm(facet_vectors, axis=1) / facets.shape[1]
        for k in range(facets.shape[1]):
            np.add.at(boundary_area, facets[:, k], share)
    on_boundary = boundary_area > 0.0
    node_length[on_boundary] = np.minimum(node_length[on_boundary],
                                          4.0 * volumes[on_boundary]
                                          / boundary_area[on_boundary])
    if points.shape[1] == 3 and area_vectors is not None:
        face = np.linalg.norm(area_vectors, axis=1)
        interior_area = (np.bincount(edges[:, 0], face, minlength=n)
                         + np.bincount(edges[:, 1], face, minlength=n))
        inside = ~on_boundary
        node_length[inside] = np.minimum(node_length[inside],
                                         4.0 * volumes[inside] / interior_area[inside])
    return node_length


def green_gauss_gradient(dual: MedianDual, u: np.ndarray) -> np.ndarray:
    """Nodal gradient (n, k, d) of nodal values u (n, k) (reference implementation in numpy)."""
    u = np.asarray(u, dtype=float)
    if u.ndim == 1:
        u = u[:, None]
    d = dual.dim
    own, denominator = CLOSURE[d]
    a, b = dual.edges[:, 0], dual.edges[:, 1]
    flux = 0.5 * (u[a] + u[b])[:, :, None] * dual.area_vectors[:, None, :]
    g = np.zeros(u.shape + (d,))
    np.add.at(g, a, flux)
    np.add.at(g, b, -flux)
    share = (dual.facet_vectors / d)[:, None, :]
    for k in range(d):
        node = dual.facets[:, k]
        others = sum(u[dual.facets[:, j]] for j in range(d) if j != k)
        np.add.at(g, node, ((own * u[node] + others) / denominator)[:, :, None] * share)
    return g / dual.volumes[:, None, None]
