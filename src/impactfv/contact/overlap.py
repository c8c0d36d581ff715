"""Bodies that overlap at the start: found before a run, reported by check, refused by run."""

from __future__ import annotations

import numpy as np


def find_overlaps(case, model) -> list[str]:
    """One message per contact whose bodies (or body and wall) overlap at the start."""
    from matplotlib.tri import Triangulation

    problems = []
    for k, spec in enumerate(case.contacts):
        layouts = [model.bodies[model.body_index(name)] for name in spec.bodies]
        tol = 1e-6 * float(model.node_length.min())
        if spec.wall is not None:
            nw = np.array(spec.wall.normal, float)
            nw /= np.linalg.norm(nw)
            b = layouts[0]
            g = (model.X[b.start:b.stop] - np.array(spec.wall.point)) @ nw
            if g.min() < -tol:
                problems.append(f"contact[{k}]: body {b.name!r} starts {-g.min():.4g} m behind "
                                "the wall")
            continue
        for a, b in ((layouts[0], layouts[1]), (layouts[1], layouts[0])):
            pts = model.X[np.unique(a.boundary_edges)]
            tri = Triangulation(model.X[:, 0], model.X[:, 1], b.triangles)
            inside = tri.get_trifinder()(pts[:, 0], pts[:, 1]) >= 0
            if not inside.any():
                continue
            depth = _distance_to_segments(pts[inside][:2000], model.X, b.boundary_edges)
            if depth.max() > tol:
                problems.append(f"contact[{k}]: bodies {a.name!r} and {b.name!r} overlap at the "
                                f"start (a node of {a.name!r} lies {depth.max():.4g} m inside "
                                f"{b.name!r})")
                break
    return problems


def _distance_to_segments(points, X, segs):
    p = X[segs[:, 0]]
    d = X[segs[:, 1]] - p
    out = np.empty(len(points))
    for i, q in enumerate(points):  # setup only, on the few nodes found inside
        t = np.clip(np.einsum("ij,ij->i", q - p, d) / np.einsum("ij,ij->i", d, d), 0, 1)
        out[i] = np.min(np.linalg.norm(p + t[:, None] * d - q, axis=1))
    return out
