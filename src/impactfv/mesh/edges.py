"""Edges and boundary facets of cell meshes, shared by the finite-volume scheme, the contact
geometry and the finite-element baselines.

2D cells are polygons (triangles, or the quadrilaterals of the FE baseline) listed
counter-clockwise; their boundary facets are edges oriented with the body on the left of
a -> b, so (dy, -dx) is the outward normal.

3D cells are positively oriented tetrahedra (a, b, c, d): det[b - a, c - a, d - a] > 0.
Their boundary facets are triangles (a, b, c) oriented outward: (b - a) x (c - a) points out
of the body.
"""

from __future__ import annotations

import numpy as np

#: the six edges of a tetrahedron, as pairs of its local nodes
TET_EDGES = ((0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3))
#: its four faces, each opposite the local node of the same index and oriented outward
TET_FACES = ((1, 2, 3), (0, 3, 2), (0, 1, 3), (0, 2, 1))


def _pairs(cells: np.ndarray, dim: int):
    if dim == 3:
        return TET_EDGES
    k = cells.shape[1]
    return tuple((i, (i + 1) % k) for i in range(k))


def directed_edges(cells: np.ndarray, dim: int = 2) -> np.ndarray:
    """The edges of every cell, (k m, 2): all first edges, then all second edges, and so on.
    2D: each polygon's edges in its own (counter-clockwise) orientation; 3D: the six edges of
    each tetrahedron (TET_EDGES)."""
    cells = np.asarray(cells, dtype=np.int64)
    return np.concatenate([cells[:, list(pair)] for pair in _pairs(cells, dim)])


def edge_keys(edges: np.ndarray) -> np.ndarray:
    """One int64 per undirected edge (min * 2^32 + max): 1D unique/sort instead of row-wise
    ``np.unique(axis=0)``, which is several times slower and needs more memory."""
    lo = np.minimum(edges[:, 0], edges[:, 1]).astype(np.int64)
    hi = np.maximum(edges[:, 0], edges[:, 1]).astype(np.int64)
    return (lo << 32) | hi


def keys_to_edges(keys: np.ndarray) -> np.ndarray:
    return np.column_stack([keys >> 32, keys & 0xFFFFFFFF])


def unique_edges(cells: np.ndarray, dim: int = 2) -> np.ndarray:
    """Undirected edges (a < b) of a cell mesh, sorted by a then b."""
    return keys_to_edges(np.unique(edge_keys(directed_edges(cells, dim))))


def cell_facets(cells: np.ndarray, dim: int = 2) -> np.ndarray:
    """Every facet of every cell, oriented outward from its cell: the directed edges of a
    polygon (2D) or the four faces of a tetrahedron (3D), all first facets first."""
    cells = np.asarray(cells, dtype=np.int64)
    if dim == 2:
        return directed_edges(cells, 2)
    return np.concatenate([cells[:, list(face)] for face in TET_FACES])


def facet_keys(facets: np.ndarray) -> np.ndarray:
    """One sortable key per unoriented facet: the int64 edge key in 2D; in 3D an int64 built
    from the sorted node triple (21 bits each) when the node numbers allow it, else a row of
    bytes (numpy void) that sorts and compares the same way."""
    facets = np.asarray(facets, dtype=np.int64)
    if facets.shape[1] == 2:
        return edge_keys(facets)
    s = np.sort(facets, axis=1)
    if len(s) == 0 or s.max() < (1 << 21):
        return (s[:, 0] << 42) | (s[:, 1] << 21) | s[:, 2]
    s = np.ascontiguousarray(s)
    return s.view(np.dtype((np.void, s.dtype.itemsize * 3))).ravel()


def boundary_facets(cells: np.ndarray, dim: int = 2) -> np.ndarray:
    """Facets used by one cell only, oriented outward (as in their cell)."""
    facets = cell_facets(cells, dim)
    _, inverse, counts = np.unique(facet_keys(facets), return_inverse=True,
                                   return_counts=True)
    return facets[counts[inverse] == 1]


def facet_index(boundary: np.ndarray, facets: np.ndarray, what: str) -> np.ndarray:
    """Row of each of ``facets`` in ``boundary`` (both facet lists, any orientation); ``what``
    names the facets in the error raised for one that is not on the boundary."""
    keys = facet_keys(boundary)
    order = np.argsort(keys)
    wanted = facet_keys(facets)
    pos = np.searchsorted(keys, wanted, sorter=order)
    pos = np.minimum(pos, len(keys) - 1)
    found = keys[order[pos]] == wanted
    if not found.all():
        bad = facets[np.flatnonzero(~found)[0]]
        raise ValueError(f"{what}: facet {bad.tolist()} is not on the boundary")
    return order[pos]
