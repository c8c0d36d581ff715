"""Quadrilateral meshes for the FV scheme: each quad cut into two triangles, with no
preferred direction.

The cut follows a 2-colouring of the nodes along the quad edges (a breadth-first search from
a corner of each connected piece): a quad's opposite corners have the same colour, and it is
cut along the diagonal that joins its two nodes of colour 0. On a structured grid this is
the checkerboard of alternating diagonals (the ``alternate`` pattern of the rectangle
generator, without its mirroring): every node of colour 0 is the end of all the diagonals
around it, every node of colour 1 of none, so neither diagonal direction is preferred. A quad
with a corner node (a node of no other cell) is cut through that node, so that no corner is
left with a single triangle (a third of the dual volume and a three-node gradient); a
non-convex quad is cut through its reflex corner. Where the colouring is not proper (an odd
cycle of quads around a hole) the shorter diagonal is taken.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components, dijkstra


def signed_areas(points, cells) -> np.ndarray:
    """Signed (shoelace) areas of polygons, positive when counter-clockwise."""
    p = np.asarray(points)[np.asarray(cells)]
    x, y = p[..., 0], p[..., 1]
    return 0.5 * np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1)


def orient_counter_clockwise(points, quads) -> np.ndarray:
    """The quads with clockwise ones reversed (a, b, c, d) -> (a, d, c, b)."""
    q = np.array(quads, dtype=np.int64)
    flip = signed_areas(points, q) < 0
    q[flip] = q[flip][:, ::-1]
    return q


def _colours(quads, n_points, corner):
    """0/1 per node: the parity of the breadth-first distance, along quad edges, from one
    start node per connected piece (a corner node where the piece has one)."""
    e = np.concatenate([quads[:, [i, (i + 1) % 4]] for i in range(4)])
    graph = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])),
                          shape=(n_points, n_points)).tocsr()
    graph = graph + graph.T
    n_pieces, piece = connected_components(graph, directed=False)
    in_quads = np.zeros(n_points, bool)
    in_quads[quads.ravel()] = True
    starts = []
    for k in np.unique(piece[in_quads]):
        members = np.flatnonzero((piece == k) & in_quads)
        corners = members[corner[members]]
        starts.append(int(corners[0] if len(corners) else members[0]))
    dist = dijkstra(graph, directed=False, indices=starts, unweighted=True, min_only=True)
    dist = np.where(np.isfinite(dist), dist, 0).astype(np.int64)
    return dist % 2


def split_quads(points, quads, other_cells=None) -> np.ndarray:
    """Two counter-clockwise triangles per counter-clockwise quad (see the module docstring),
    (2 m, 3): the two triangles of quad k are rows 2k and 2k + 1. ``other_cells`` (triangles
    of a mixed mesh) count when deciding which nodes are corners."""
    points = np.asarray(points, dtype=float)
    q = np.asarray(quads, dtype=np.int64).reshape(-1, 4)
    n = len(points)
    count = np.bincount(q.ravel(), minlength=n)
    if other_cells is not None and len(other_cells):
        count = count + np.bincount(np.asarray(other_cells).ravel(), minlength=n)
    corner = count == 1
    colour = _colours(q, n, corner)
    c = colour[q]
    proper = (c[:, 0] == c[:, 2]) & (c[:, 1] == c[:, 3]) & (c[:, 0] != c[:, 1])
    d_ac = np.linalg.norm(points[q[:, 2]] - points[q[:, 0]], axis=1)
    d_bd = np.linalg.norm(points[q[:, 3]] - points[q[:, 1]], axis=1)
    along_ac = np.where(proper, c[:, 0] == 0, d_ac <= d_bd)
    at_corner_ac = corner[q[:, 0]] | corner[q[:, 2]]
    at_corner_bd = corner[q[:, 1]] | corner[q[:, 3]]
    along_ac = np.where(at_corner_ac, True, np.where(at_corner_bd, False, along_ac))
    ac = (q[:, [0, 1, 2]], q[:, [0, 2, 3]])
    bd = (q[:, [0, 1, 3]], q[:, [1, 2, 3]])
    ok_ac = (signed_areas(points, ac[0]) > 0) & (signed_areas(points, ac[1]) > 0)
    ok_bd = (signed_areas(points, bd[0]) > 0) & (signed_areas(points, bd[1]) > 0)
    along_ac = np.where(along_ac & ~ok_ac & ok_bd, False, along_ac)
    along_ac = np.where(~along_ac & ~ok_bd & ok_ac, True, along_ac)
    tri = np.empty((2 * len(q), 3), dtype=np.int64)
    tri[0::2] = np.where(along_ac[:, None], ac[0], bd[0])
    tri[1::2] = np.where(along_ac[:, None], ac[1], bd[1])
    return tri
