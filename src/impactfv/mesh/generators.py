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


def annulus_segments(radius, inner_radius, rings) -> int:
    """Cells around an annulus: an even number that makes them about square at mid-radius."""
    h = (radius - inner_radius) / rings
    return max(8, 2 * int(round(np.pi * (radius + inner_radius) / 2 / h)))


def annulus(centre, radius, inner_radius, rings: int) -> Mesh:
    """Triangulate the ring inner_radius <= r <= radius: ``rings`` cells through the wall and
    about square cells around it (annulus_segments, an even number), each cut along one of
    its diagonals in a checkerboard (no preferred direction). Boundary regions ``outer``
    and ``inner``."""
    if not (0 < inner_radius < radius) or not np.isfinite(radius):
        raise InputError(f"mesh.inner_radius: expected 0 < inner_radius < radius, got "
                         f"{inner_radius!r} and {radius!r}")
    if rings < 1:
        raise InputError(f"mesh.rings: expected a positive integer, got {rings!r}")
    m = annulus_segments(radius, inner_radius, rings)
    r = inner_radius + (radius - inner_radius) * np.arange(rings + 1) / rings
    theta = 2.0 * np.pi * np.arange(m) / m
    R, T = np.meshgrid(r, theta, indexing="ij")
    points = np.column_stack([(R * np.cos(T)).ravel(), (R * np.sin(T)).ravel()])
    points += np.asarray(centre, float)
    i, j = np.meshgrid(np.arange(rings), np.arange(m), indexing="ij")
    i, j = i.ravel(), j.ravel()
    n00 = i * m + j
    n01 = i * m + (j + 1) % m          # next around
    n10 = n00 + m                      # next outward
    n11 = n01 + m
    cut = (i + j) % 2 == 0
    first = np.where(cut[:, None], np.column_stack([n00, n10, n11]),
                     np.column_stack([n00, n10, n01]))
    second = np.where(cut[:, None], np.column_stack([n00, n11, n01]),
                      np.column_stack([n10, n11, n01]))
    tri = np.concatenate([first, second]).astype(np.int64)
    outer = rings * m + np.arange(m)
    inner = np.arange(m)
    regions = {"outer": np.column_stack([outer, np.roll(outer, -1)]),
               "inner": np.column_stack([np.roll(inner, -1), inner])}
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


def box(origin, size, divisions) -> Mesh:
    """Tetrahedra of the box [x0, x0+Lx] x [y0, y0+Ly] x [z0, z0+Lz] with nx x ny x nz cells.

    Each hexahedral cell is cut into the six tetrahedra around one of its main diagonals
    (Kuhn's subdivision, all six congruent, dihedral angles 45-90 degrees). The diagonal's
    direction is mirrored from cell to cell, counted from the nearest box corner along each
    axis, so that no direction is preferred, the face diagonals alternate in a checkerboard,
    the mesh is symmetric about the three centre planes (for even division counts), and,
    with at least two cells along each axis, every box corner lies on the main diagonal of
    its cell (six tetrahedra meet there, not one). Mirroring along an axis depends only on
    the index along that axis, so neighbouring cells cut their common face along the same
    diagonal.

    Boundary regions xmin, xmax, ymin, ymax, zmin, zmax hold the outward-oriented triangles
    of each side.
    """
    from itertools import permutations

    (x0, y0, z0), (lx, ly, lz), (nx, ny, nz) = origin, size, divisions
    axes = [o + length * np.arange(k + 1) / k for o, length, k in zip(origin, size, divisions)]
    X, Y, Z = np.meshgrid(*axes, indexing="ij")
    points = np.column_stack([X.ravel(order="F"), Y.ravel(order="F"), Z.ravel(order="F")])

    def node(i, j, k):
        return i + (nx + 1) * (j + (ny + 1) * k)

    i, j, k = (a.ravel(order="F") for a in np.meshgrid(np.arange(nx), np.arange(ny),
                                                        np.arange(nz), indexing="ij"))
    # mirror each axis in the cells whose distance from the nearer end is odd
    flips = []
    for index, count in ((i, nx), (j, ny), (k, nz)):
        from_end = np.where(index > (count - 1) / 2, count - 1 - index, index)
        mirrored_half = index > (count - 1) / 2
        flips.append((from_end % 2 == 1) ^ mirrored_half)
    tets = []
    for order in permutations(range(3)):
        corner = np.zeros((len(i), 3), np.int64)
        path = [corner.copy()]
        for axis in order:
            corner[:, axis] = 1
            path.append(corner.copy())
        tet = []
        for local in path:
            # local corner (0/1 per axis), mirrored where the cell is mirrored
            li = np.where(flips[0], 1 - local[:, 0], local[:, 0])
            lj = np.where(flips[1], 1 - local[:, 1], local[:, 1])
            lk = np.where(flips[2], 1 - local[:, 2], local[:, 2])
            tet.append(node(i + li, j + lj, k + lk))
        tets.append(np.column_stack(tet))
    tets = np.concatenate(tets).astype(np.int64)
    p = points[tets]
    volume = np.einsum("ij,ij->i", p[:, 1] - p[:, 0],
                       np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]))
    tets[volume < 0] = tets[volume < 0][:, [0, 2, 1, 3]]
    from .edges import boundary_facets
    facets = boundary_facets(tets, 3)
    centre = points[facets].mean(axis=1)
    regions = {}
    for axis, (lo, hi) in enumerate(((x0, x0 + lx), (y0, y0 + ly), (z0, z0 + lz))):
        tol = 1e-9 * size[axis]
        name = "xyz"[axis]
        regions[name + "min"] = facets[np.abs(centre[:, axis] - lo) < tol]
        regions[name + "max"] = facets[np.abs(centre[:, axis] - hi) < tol]
    return Mesh(points, tets, regions)
