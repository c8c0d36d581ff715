"""Edges and boundary facets of cell meshes, shared by the finite-volume scheme, the contact
geometry and the finite-element baselines.

2D cells are polygons (triangles, or the quadrilaterals of the FE baseline) listed
counter-clockwise; their boundary facets are edges oriented with the body on the left of
a -> b, so (dy, -dx) is the outward normal.
"""

from __future__ import annotations

import numpy as np


def directed_edges(cells: np.ndarray) -> np.ndarray:
    """The edges of every polygon in its own (counter-clockwise) orientation, (k m, 2):
    all first edges, then all second edges, and so on."""
    cells = np.asarray(cells, dtype=np.int64)
    return np.concatenate([cells[:, [i, (i + 1) % cells.shape[1]]]
                           for i in range(cells.shape[1])])


def edge_keys(edges: np.ndarray) -> np.ndarray:
    """One int64 per undirected edge (min * 2^32 + max): 1D unique/sort instead of row-wise
    ``np.unique(axis=0)``, which is several times slower and needs more memory."""
    lo = np.minimum(edges[:, 0], edges[:, 1]).astype(np.int64)
    hi = np.maximum(edges[:, 0], edges[:, 1]).astype(np.int64)
    return (lo << 32) | hi


def keys_to_edges(keys: np.ndarray) -> np.ndarray:
    return np.column_stack([keys >> 32, keys & 0xFFFFFFFF])


def unique_edges(cells: np.ndarray) -> np.ndarray:
    """Undirected edges (a < b) of a polygon mesh, sorted by a then b."""
    return keys_to_edges(np.unique(edge_keys(directed_edges(cells))))


def boundary_facets(cells: np.ndarray) -> np.ndarray:
    """Edges used by one cell only, oriented as in their (counter-clockwise) cell."""
    directed = directed_edges(cells)
    _, inverse, counts = np.unique(edge_keys(directed), return_inverse=True,
                                   return_counts=True)
    return directed[counts[inverse] == 1]


def facet_index(boundary: np.ndarray, facets: np.ndarray, what: str) -> np.ndarray:
    """Row of each of ``facets`` in ``boundary`` (both oriented facet lists); ``what`` names
    the facets in the error raised for one that is not on the boundary."""
    keys = edge_keys(boundary)
    order = np.argsort(keys)
    wanted = edge_keys(facets)
    pos = np.searchsorted(keys, wanted, sorter=order)
    pos = np.minimum(pos, len(keys) - 1)
    found = keys[order[pos]] == wanted
    if not found.all():
        bad = facets[np.flatnonzero(~found)[0]]
        raise ValueError(f"{what}: facet {bad.tolist()} is not on the boundary")
    return order[pos]
