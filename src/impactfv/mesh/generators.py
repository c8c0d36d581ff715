"""Built-in structured meshes of rectangles: triangles for the FV scheme, quadrilaterals for
the mean-dilatation FE baseline (same grid, same nodes)."""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .core import Mesh

#: "right": every cell cut along the diagonal (0,0)-(1,1); "left": along (1,0)-(0,1);
#: "alternate": the two alternate in a checkerboard (no preferred direction), mirrored about
#: the centre lines so that the mesh is symmetric and every corner is split (see rectangle);
#: "crossed": four triangles per cell around a centre node.
DIAGONAL_PATTERNS = ("right", "left", "alternate", "crossed")


def rectangle(origin, size, divisions, pattern: str = "alternate") -> Mesh:
    """Triangulate [x0, x0+Lx] x [y0, y0+Ly] with nx x ny cells.

    Boundary regions are named xmin, xmax, ymin, ymax.
    """
    (x0, y0), (lx, ly), (nx, ny) = origin, size, divisions
    if pattern not in DIAGONAL_PATTERNS:
        raise InputError(f"mesh.pattern: expected one of {', '.join(DIAGONAL_PATTERNS)}, "
                         f"got {pattern!r}")
    xs = x0 + lx * np.arange(nx + 1) / nx
    ys = y0 + ly * np.arange(ny + 1) / ny
    X, Y = np.meshgrid(xs, ys, indexing="xy")
    points = np.column_stack([X.ravel(), Y.ravel()])
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="xy")
    i, j = i.ravel(), j.ravel()
    n00 = j * (nx + 1) + i
    n10, n01, n11 = n00 + 1, n00 + nx + 1, n00 + nx + 2
    if pattern == "crossed":
        centres = np.column_stack([x0 + lx * (i + 0.5) / nx, y0 + ly * (j + 0.5) / ny])
        c = len(points) + np.arange(len(i))
        points = np.vstack([points, centres])
        tri = np.concatenate([np.column_stack(t) for t in
                              ((n00, n10, c), (n10, n11, c), (n11, n01, c), (n01, n00, c))])
    else:
        if pattern == "right":
            cut_right = np.ones(len(i), bool)
        elif pattern == "left":
            cut_right = np.zeros(len(i), bool)
        else:
            # checkerboard counted from the nearest corner and mirrored into each quadrant:
            # the mesh is symmetric about both centre lines, and each corner cell is cut
            # through the corner, so no corner node has a single triangle (a third of the
            # volume and a three-node gradient, where boundary and contact fluxes meet)
            mirror_x = i > (nx - 1) / 2
            mirror_y = j > (ny - 1) / 2
            from_corner = np.where(mirror_x, nx - 1 - i, i) + np.where(mirror_y, ny - 1 - j, j)
            cut_right = (from_corner % 2 == 0) ^ mirror_x ^ mirror_y
        t_right = np.concatenate([np.column_stack((n00, n10, n11)), np.column_stack((n00, n11, n01))])
        t_left = np.concatenate([np.column_stack((n00, n10, n01)), np.column_stack((n10, n11, n01))])
        both = np.concatenate([cut_right, cut_right])
        tri = np.where(both[:, None], t_right, t_left)
    bottom = np.arange(nx)
    top = ny * (nx + 1) + np.arange(nx)
    left = np.arange(ny) * (nx + 1)
    right = np.arange(ny) * (nx + 1) + nx
    regions = {
        "ymin": np.column_stack([bottom, bottom + 1]),
        "xmax": np.column_stack([right, right + nx + 1]),
        "ymax": np.column_stack([top + 1, top]),
        "xmin": np.column_stack([left + nx + 1, left]),
    }
    return Mesh(points, tri.astype(np.int64), regions)


def disc(centre, radius, rings: int) -> Mesh:
    """Triangulate the disc of given centre and radius: the centre node and ``rings``
    concentric rings of 6k equally spaced nodes (k = 1..rings, every other ring turned by
    half a spacing), joined by their Delaunay triangulation: nearly equilateral triangles of
    side about radius / rings. The boundary region ``outer`` is the outer ring,
    counter-clockwise."""
    from scipy.spatial import Delaunay

    if radius <= 0 or not np.isfinite(radius):
        raise InputError(f"mesh.radius: expected a positive length, got {radius!r}")
    if rings < 1:
        raise InputError(f"mesh.rings: expected a positive integer, got {rings!r}")
    points = [np.zeros((1, 2))]
    for k in range(1, rings + 1):
        theta = 2.0 * np.pi * (np.arange(6 * k) + 0.5 * (k % 2)) / (6 * k)
        points.append(radius * k / rings * np.column_stack([np.cos(theta), np.sin(theta)]))
    points = np.vstack(points) + np.asarray(centre, float)
    tri = Delaunay(points).simplices.astype(np.int64)
    a, b, c = (points[tri[:, k]] for k in range(3))
    area = 0.5 * ((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
    tri[area < 0] = tri[area < 0][:, [0, 2, 1]]
    outer = len(points) - 6 * rings + np.arange(6 * rings)
    regions = {"outer": np.column_stack([outer, np.roll(outer, -1)])}
    return Mesh(points, tri, regions)


def rectangle_quads(origin, size, divisions):
    """Bilinear quads of the grid of :func:`rectangle` (the same nodes in the same order),
    counter-clockwise, with the same boundary regions."""
    (x0, y0), (lx, ly), (nx, ny) = origin, size, divisions
    base = rectangle(origin, size, divisions, "right")
    nid = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1)
    quads = np.column_stack([nid[:-1, :-1].ravel(), nid[:-1, 1:].ravel(),
                             nid[1:, 1:].ravel(), nid[1:, :-1].ravel()]).astype(np.int64)
    return Mesh(base.points, quads, base.regions)


def quads_to_triangles(quads, pattern="alternate"):
    """Split each quad (a,b,c,d) into two counter-clockwise triangles (for plotting).

    ``pattern="diagonal"`` always cuts along a-c; ``"alternate"`` alternates a-c / b-d from one
    quad to the next.
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
