"""Bodies that overlap at the start: found before a run, reported by check, refused by run."""

from __future__ import annotations

import numpy as np


def body_overlap(points_a, facets_a, points_b, cells_b, facets_b, tol) -> float:
    """How deep the boundary nodes of body a lie inside body b (0 if none is inside by more
    than ``tol``). 2D: cells_b are triangles."""
    from matplotlib.tri import Triangulation

    nodes = np.unique(facets_a)
    pts = points_a[nodes]
    tri = Triangulation(points_b[:, 0], points_b[:, 1], cells_b)
    inside = tri.get_trifinder()(pts[:, 0], pts[:, 1]) >= 0
    if not inside.any():
        return 0.0
    depth = _distance_to_facets(pts[inside][:2000], points_b, facets_b).max()
    return float(depth) if depth > tol else 0.0


def wall_overlap(points, point, normal) -> float:
    """How far the deepest node lies behind a wall through ``point`` with ``normal`` (out of
    the wall); 0 or negative when none does."""
    nw = np.asarray(normal, float)
    nw = nw / np.linalg.norm(nw)
    return float(-((points - np.asarray(point, float)) @ nw).min())


def _distance_to_facets(points, X, facets):
    p = X[facets[:, 0]]
    d = X[facets[:, 1]] - p
    out = np.empty(len(points))
    for i, q in enumerate(points):  # setup only, on the few nodes found inside
        t = np.clip(np.einsum("ij,ij->i", q - p, d) / np.einsum("ij,ij->i", d, d), 0, 1)
        out[i] = np.min(np.linalg.norm(p + t[:, None] * d - q, axis=1))
    return out


def find_overlaps(case) -> list[str]:
    """One message per contact whose bodies (or body and wall) overlap at the start.

    Works on the case's reference meshes, so every method (FV or FE) refuses the same cases.
    """
    from ..mesh.edges import boundary_facets

    bodies = {b.name: b for b in case.bodies}
    h = min(float(b.mesh.edge_lengths().min()) for b in case.bodies)
    tol = 1e-6 * h
    problems = []
    for k, spec in enumerate(case.contacts):
        if spec.wall is not None:
            body = bodies[spec.bodies[0]]
            depth = wall_overlap(body.mesh.points, spec.wall.point, spec.wall.normal)
            if depth > tol:
                problems.append(f"contact[{k}]: body {body.name!r} starts {depth:.4g} m behind "
                                "the wall")
            continue
        a, b = (bodies[name] for name in spec.bodies)
        for first, second in ((a, b), (b, a)):
            depth = body_overlap(first.mesh.points, boundary_facets(first.mesh.cells),
                                 second.mesh.points, second.mesh.cells,
                                 boundary_facets(second.mesh.cells), tol)
            if depth > 0:
                problems.append(f"contact[{k}]: bodies {first.name!r} and {second.name!r} "
                                f"overlap at the start (a node of {first.name!r} lies "
                                f"{depth:.4g} m inside {second.name!r})")
                break
    return problems
