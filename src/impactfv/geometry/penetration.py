"""Bodies that overlap at the start: found before a run, reported by check, refused by run."""

from __future__ import annotations

import numpy as np
from numba import njit

from .facets import closest_point


def containing_cell(points, X, cells, eps=1e-12) -> np.ndarray:
    """Index of a simplex (triangle in 2D, tetrahedron in 3D) of the mesh (X, cells) that
    contains each of ``points`` (n, d), or -1. Barycentric coordinates >= -eps count as
    inside. Candidates come from a k-d tree of the cell centroids (scipy.spatial) within the
    largest centroid-to-vertex distance, so the cost is about linear."""
    from scipy.spatial import cKDTree

    points = np.atleast_2d(np.asarray(points, float))
    X = np.asarray(X, float)
    cells = np.asarray(cells, dtype=np.int64)
    out = np.full(len(points), -1, np.int64)
    if len(points) == 0 or len(cells) == 0:
        return out
    corners = X[cells]                                  # (m, d + 1, d)
    centroid = corners.mean(axis=1)
    with np.errstate(over="ignore", invalid="ignore"):  # absurd coordinates: search all
        reach = float(np.abs(corners - centroid[:, None, :]).sum(axis=2).max())
    try:
        lists = cKDTree(centroid).query_ball_point(points, reach * (1 + 1e-9) + 1e-300)
    except ValueError:     # coordinates near the double range overflow the tree's distances
        lists = None
    if lists is None:
        which = np.repeat(np.arange(len(points)), len(cells))
        cand = np.tile(np.arange(len(cells)), len(points))
    else:
        counts = np.array([len(c) for c in lists])
        if counts.sum() == 0:
            return out
        which = np.repeat(np.arange(len(points)), counts)
        cand = np.concatenate([np.asarray(c, np.int64) for c in lists if len(c)])
    # barycentric coordinates: T lam' = p - x0, T = [x1 - x0, ..., xd - x0]
    T = np.swapaxes(corners[cand, 1:] - corners[cand, :1], 1, 2)      # (k, d, d)
    rhs = points[which] - corners[cand, 0]
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        lam = np.linalg.solve(T, rhs[..., None])[..., 0]
        lam = np.column_stack([1.0 - lam.sum(axis=1), lam])
        hit = np.all(lam >= -eps, axis=1)
    out[which[hit][::-1]] = cand[hit][::-1]              # the first hit of each point
    return out


def body_overlap(points_a, facets_a, points_b, cells_b, facets_b, tol) -> float:
    """How deep the boundary nodes of body a lie inside body b (0 if none is inside by more
    than ``tol``); cells_b are triangles (2D) or tetrahedra (3D)."""
    nodes = np.unique(facets_a)
    pts = points_a[nodes]
    inside = containing_cell(pts, points_b, cells_b) >= 0
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
    """Distance of each point to the nearest facet (segment or triangle)."""
    return _nearest_facet_distance(np.ascontiguousarray(points, dtype=float),
                                   np.ascontiguousarray(X, dtype=float),
                                   np.ascontiguousarray(facets, dtype=np.int64))


@njit(cache=True)
def _nearest_facet_distance(points, X, facets):
    out = np.full(points.shape[0], np.inf)
    w = np.empty(facets.shape[1])
    for i in range(points.shape[0]):  # setup only, on the few nodes found inside
        for f in range(facets.shape[0]):
            out[i] = min(out[i], closest_point(X, facets[f], points[i], w))
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
        if spec.self_contact:
            continue        # a body's mesh cannot overlap itself (folds are refused)
        a, b = (bodies[name] for name in spec.bodies)
        for first, second in ((a, b), (b, a)):
            depth = body_overlap(first.mesh.points,
                                 boundary_facets(first.mesh.cells, first.mesh.dim),
                                 second.mesh.points, second.mesh.cells,
                                 boundary_facets(second.mesh.cells, second.mesh.dim), tol)
            if depth > 0:
                problems.append(f"contact[{k}]: bodies {first.name!r} and {second.name!r} "
                                f"overlap at the start (a node of {first.name!r} lies "
                                f"{depth:.4g} m inside {second.name!r})")
                break
    return problems
