"""The mesh of one body: reference points, cells and named boundary regions; checks and
renumbering for locality."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import reverse_cuthill_mckee

from ..errors import InputError
from .edges import boundary_facets, directed_edges, edge_keys, unique_edges
from .quads import orient_counter_clockwise


@dataclass
class Mesh:
    """Reference points (n, d) and cells (m, d + 1): counter-clockwise triangles in 2D.

    ``regions`` maps a region name to its boundary facets (k, d), each oriented like the
    boundary of its cell (2D: the body lies on the left of a->b, outward normal (dy, -dx)/L).
    ``quads`` (m/2, 4): for a mesh read from quadrilaterals, the counter-clockwise quads
    that ``cells`` cut in two (impactfv.mesh.quads; the Q4 baseline runs on them), else
    None. ``skipped_sets``: named sets of the mesh file that are not regions, with the
    reason (impactfv.mesh.sets).
    """

    points: np.ndarray
    cells: np.ndarray
    regions: dict[str, np.ndarray] = field(default_factory=dict)
    quads: np.ndarray | None = None
    skipped_sets: dict[str, str] = field(default_factory=dict)

    @property
    def n_nodes(self) -> int:
        return len(self.points)

    @property
    def dim(self) -> int:
        return self.points.shape[1]

    def triangle_areas(self) -> np.ndarray:
        p = self.points[self.cells]
        d1 = p[:, 1] - p[:, 0]
        d2 = p[:, 2] - p[:, 0]
        return 0.5 * (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])

    def edge_lengths(self) -> np.ndarray:
        e = unique_edges(self.cells)
        return np.linalg.norm(self.points[e[:, 1]] - self.points[e[:, 0]], axis=1)

    def quality(self) -> dict:
        """Statistics a user wants before running: sizes, aspect ratios, smallest angles."""
        p = self.points[self.cells]
        lengths = np.stack([np.linalg.norm(p[:, (i + 1) % 3] - p[:, i], axis=1)
                            for i in range(3)], axis=1)
        area = np.abs(self.triangle_areas())
        # aspect ratio: longest edge over the height on it, scaled so an equilateral is 1
        longest = lengths.max(axis=1)
        aspect = longest ** 2 / (2.0 * area) * (np.sqrt(3.0) / 2.0)
        cosines = []
        for i in range(3):
            a, b, c = lengths[:, i], lengths[:, (i + 1) % 3], lengths[:, (i + 2) % 3]
            cosines.append((b ** 2 + c ** 2 - a ** 2) / (2 * b * c))
        min_angle = np.degrees(np.arccos(np.clip(np.max(cosines, axis=0), -1, 1)))
        edge_len = self.edge_lengths()
        return {
            "nodes": int(self.n_nodes), "triangles": int(len(self.cells)),
            "area": float(area.sum()),
            "edge_length_min": float(edge_len.min()), "edge_length_max": float(edge_len.max()),
            "aspect_ratio_max": float(aspect.max()),
            "min_angle_deg": float(min_angle.min()),
        }


def validate_and_orient(mesh: Mesh, source: str) -> Mesh:
    """Check a mesh for the errors a user can make; orient triangles counter-clockwise.

    Raises InputError naming ``source`` for degenerate triangles, out-of-range or duplicated
    nodes, edges shared by more than two triangles, and empty regions.
    """
    pts = np.asarray(mesh.points, dtype=float)
    tri = np.asarray(mesh.cells)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 3:
        raise InputError(f"{source}: expected at least 3 points with 2 coordinates")
    if not np.all(np.isfinite(pts)):
        raise InputError(f"{source}: non-finite point coordinates")
    if tri.ndim != 2 or tri.shape[1] != 3 or len(tri) == 0:
        raise InputError(f"{source}: expected a non-empty list of triangles (m, 3)")
    if tri.min() < 0 or tri.max() >= len(pts):
        raise InputError(f"{source}: triangle node index out of range 0..{len(pts) - 1}")
    tri = tri.astype(np.int64)
    if np.any(np.sort(tri, axis=1)[:, 1:] == np.sort(tri, axis=1)[:, :-1]):
        raise InputError(f"{source}: a triangle repeats a node")
    quads = None if mesh.quads is None else np.asarray(mesh.quads, dtype=np.int64)
    if quads is not None and (quads.ndim != 2 or quads.shape[1] != 4 or quads.min() < 0
                              or quads.max() >= len(pts)):
        raise InputError(f"{source}: quadrilateral node index out of range 0..{len(pts) - 1}")
    if quads is not None:
        quads = orient_counter_clockwise(pts, quads)
    mesh = Mesh(pts, tri, {k: np.asarray(v, dtype=np.int64) for k, v in mesh.regions.items()},
                quads, dict(mesh.skipped_sets))
    area = mesh.triangle_areas()
    scale = np.median(mesh.edge_lengths()) ** 2
    bad = np.flatnonzero(np.abs(area) <= 1e-10 * scale)
    if len(bad):
        raise InputError(f"{source}: {len(bad)} degenerate triangle(s) of (near) zero area, "
                         f"first is triangle {bad[0]} with nodes {tri[bad[0]].tolist()}")
    flip = area < 0
    tri[flip] = tri[flip][:, [0, 2, 1]]
    used = np.zeros(len(pts), bool)
    used[tri.ravel()] = True
    if not used.all():
        raise InputError(f"{source}: {int((~used).sum())} node(s) belong to no triangle, "
                         f"first is node {int(np.flatnonzero(~used)[0])}")
    directed = directed_edges(tri)
    keys = edge_keys(directed)
    _, counts = np.unique(keys, return_counts=True)
    if counts.max() > 2:
        raise InputError(f"{source}: {int((counts > 2).sum())} edge(s) shared by more than two "
                         "triangles (the mesh is not a manifold)")
    rounded = np.round(pts / np.sqrt(scale), 9)
    order = np.lexsort((rounded[:, 1], rounded[:, 0]))
    same = np.all(rounded[order[1:]] == rounded[order[:-1]], axis=1)
    if same.any():
        raise InputError(f"{source}: {int(same.sum())} duplicated node(s) at the same "
                         "position (merge them so the triangles connect)")
    # now all counter-clockwise: the two triangles of an interior edge run along it in
    # opposite directions; the same direction means both lie on one side (a fold, where
    # triangles overlap and the body would get their mass twice)
    order = np.argsort(keys, kind="stable")
    pair = np.flatnonzero(keys[order][1:] == keys[order][:-1])
    forward = directed[:, 0] < directed[:, 1]
    folded = pair[forward[order][pair] == forward[order][pair + 1]]
    if len(folded):
        a, b = sorted(directed[order[folded[0]]].tolist())
        raise InputError(f"{source}: the mesh folds over itself: {len(folded)} interior edge(s) "
                         f"have both triangles on the same side, first is edge ({a}, {b}) "
                         "(inverted triangles overlapping their neighbours)")
    mesh.cells = tri
    # re-orient region edges like the boundary edges they are
    boundary = boundary_facets(tri)
    lookup = {(int(a), int(b)): True for a, b in boundary}
    for name, edges in mesh.regions.items():
        if len(edges) == 0:
            raise InputError(f"{source}: boundary region {name!r} is empty")
        fixed = []
        for a, b in edges:
            if (int(a), int(b)) in lookup:
                fixed.append((a, b))
            elif (int(b), int(a)) in lookup:
                fixed.append((b, a))
            else:
                raise InputError(f"{source}: region {name!r} has edge ({a}, {b}) that is not on "
                                 "the boundary of the triangles")
        mesh.regions[name] = np.array(fixed, dtype=np.int64).reshape(-1, 2)
    return mesh


def renumber_for_locality(mesh: Mesh) -> tuple[Mesh, np.ndarray]:
    """Reverse Cuthill-McKee node order, cells sorted by their first node.

    Returns the renumbered mesh and ``order`` with new_points = old_points[order].
    """
    n = mesh.n_nodes
    e = unique_edges(mesh.cells)
    graph = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
    graph = graph + graph.T
    order = np.asarray(reverse_cuthill_mckee(graph, symmetric_mode=True), dtype=np.int64)
    new_index = np.empty(n, np.int64)
    new_index[order] = np.arange(n)
    cells = new_index[mesh.cells]
    cells = cells[np.argsort(cells.min(axis=1), kind="stable")]
    regions = {k: new_index[v] for k, v in mesh.regions.items()}
    quads = None if mesh.quads is None else new_index[mesh.quads]
    return Mesh(mesh.points[order], cells, regions, quads, dict(mesh.skipped_sets)), order
