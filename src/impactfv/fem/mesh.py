"""Small structured-mesh helpers for the FE baselines."""

from __future__ import annotations

import numpy as np


def rectangle_quads(origin, size, divisions):
    """Structured bilinear-quad mesh of the rectangle ``origin + [0, size[0]] x [0, size[1]]``.

    Returns ``(points (n,2), quads (m,4) counter-clockwise, boundary_edges (k,2))``; the
    boundary edges run counter-clockwise around the rectangle, so the body lies on the LEFT of
    each edge a->b and the outward normal is (dy, -dx)/L.  Node ``(i, j)`` (i along x) has
    index ``j * (nx + 1) + i``.
    """
    x0, y0 = float(origin[0]), float(origin[1])
    lx, ly = float(size[0]), float(size[1])
    nx, ny = int(divisions[0]), int(divisions[1])
    if nx < 1 or ny < 1:
        raise ValueError("divisions must be >= 1")
    xs = x0 + lx * np.arange(nx + 1) / nx
    ys = y0 + ly * np.arange(ny + 1) / ny
    X, Y = np.meshgrid(xs, ys)  # (ny+1, nx+1)
    points = np.column_stack([X.ravel(), Y.ravel()])
    nid = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1)
    quads = np.column_stack([nid[:-1, :-1].ravel(), nid[:-1, 1:].ravel(),
                             nid[1:, 1:].ravel(), nid[1:, :-1].ravel()]).astype(np.int64)
    loop = np.concatenate([nid[0, :], nid[1:, -1], nid[-1, -2::-1], nid[-2::-1, 0]])
    edges = np.column_stack([loop[:-1], loop[1:]]).astype(np.int64)
    return points, quads, edges


def quads_to_triangles(quads, pattern="alternate"):
    """Split each quad (a,b,c,d) into two counter-clockwise triangles.

    ``pattern="diagonal"`` always cuts along a-c; ``"alternate"`` alternates a-c / b-d from one
    quad to the next (for a structured mesh with an odd number of columns this gives a
    chequerboard of diagonals).
    """
    q = np.asarray(quads, dtype=np.int64)
    t1 = q[:, [0, 1, 2]]
    t2 = q[:, [0, 2, 3]]
    if pattern == "alternate":
        flip = (np.arange(len(q)) % 2) == 1
        t1 = np.where(flip[:, None], q[:, [0, 1, 3]], t1)
        t2 = np.where(flip[:, None], q[:, [1, 2, 3]], t2)
    elif pattern != "diagonal":
        raise ValueError(f"unknown pattern {pattern!r}")
    tris = np.empty((2 * len(q), 3), dtype=np.int64)
    tris[0::2] = t1
    tris[1::2] = t2
    return tris


def boundary_edges(cells):
    """Oriented boundary edges (body on the left) of a mesh of CCW triangles or quads."""
    c = np.asarray(cells, dtype=np.int64)
    e = np.column_stack([c.ravel(), np.roll(c, -1, axis=1).ravel()])
    key = np.sort(e, axis=1)
    _, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inv = inv.ravel()
    return e[cnt[inv] == 1]


def mesh_edges(cells):
    """Unique undirected edges (sorted pairs) of a triangle or quad mesh."""
    c = np.asarray(cells, dtype=np.int64)
    e = np.column_stack([c.ravel(), np.roll(c, -1, axis=1).ravel()])
    return np.unique(np.sort(e, axis=1), axis=0)
