"""The mesh of one body: reference points, cells and named boundary regions; checks and
renumbering for locality."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import reverse_cuthill_mckee

from ..errors import InputError
from .edges import boundary_facets, cell_facets, facet_keys, unique_edges
from .quads import orient_counter_clockwise

#: the dihedral angles of a regular tetrahedron, degrees
REGULAR_DIHEDRAL = float(np.degrees(np.arccos(1.0 / 3.0)))


@dataclass
class Mesh:
    """Reference points (n, d) and cells (m, d + 1): counter-clockwise triangles in 2D,
    positively oriented tetrahedra in 3D.

    ``regions`` maps a region name to its boundary facets (k, d), each oriented like the
    boundary of its cell (2D: the body lies on the left of a->b, outward normal (dy, -dx)/L;
    3D: (b - a) x (c - a) points out of the body).
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

    def cell_volumes(self) -> np.ndarray:
        """Signed measure of each cell: the area of a triangle (2D), the volume of a
        tetrahedron (3D); positive when the cell is oriented as the class requires."""
        if self.dim == 2:
            return self.triangle_areas()
        return signed_volumes(self.points, self.cells)

    def edge_lengths(self) -> np.ndarray:
        e = unique_edges(self.cells, self.dim)
        return np.linalg.norm(self.points[e[:, 1]] - self.points[e[:, 0]], axis=1)

    def quality(self) -> dict:
        """Statistics a user wants before running: sizes, aspect ratios, smallest angles."""
        if self.dim == 3:
            return self._tetrahedron_quality()
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

    def _tetrahedron_quality(self) -> dict:
        """Sizes, the radius ratio (3 r_in / R_circ, so that a regular tetrahedron has aspect
        ratio 1 and a sliver a large one) and the smallest dihedral angle."""
        p = self.points[self.cells]
        volume = np.abs(signed_volumes(self.points, self.cells))
        faces = [p[:, list(f)] for f in ((1, 2, 3), (0, 3, 2), (0, 1, 3), (0, 2, 1))]
        normals = [0.5 * np.cross(f[:, 1] - f[:, 0], f[:, 2] - f[:, 0]) for f in faces]
        face_area = np.stack([np.linalg.norm(nv, axis=1) for nv in normals], axis=1)
        r_in = 3.0 * volume / face_area.sum(axis=1)
        # circumradius: the centre c solves 2 (p_i - p_0) . c = |p_i|^2 - |p_0|^2
        A = 2.0 * (p[:, 1:] - p[:, :1])
        rhs = (p[:, 1:] ** 2).sum(axis=2) - (p[:, :1] ** 2).sum(axis=2)
        centre = np.linalg.solve(A, rhs[:, :, None])[:, :, 0]
        r_circ = np.linalg.norm(centre - p[:, 0], axis=1)
        aspect = r_circ / (3.0 * r_in)
        # dihedral angle at the edge shared by faces f and g: pi minus the angle between
        # their outward normals
        unit = [nv / np.linalg.norm(nv, axis=1)[:, None] for nv in normals]
        angles = [np.degrees(np.pi - np.arccos(np.clip((unit[f] * unit[g]).sum(axis=1), -1, 1)))
                  for f in range(4) for g in range(f + 1, 4)]
        edge_len = self.edge_lengths()
        return {
            "nodes": int(self.n_nodes), "tetrahedra": int(len(self.cells)),
            "volume": float(volume.sum()),
            "edge_length_min": float(edge_len.min()), "edge_length_max": float(edge_len.max()),
            "aspect_ratio_max": float(aspect.max()),
            "min_dihedral_deg": float(np.min(angles)),
        }


def signed_volumes(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """det[b - a, c - a, d - a] / 6 of each tetrahedron (a, b, c, d)."""
    p = points[tets]
    return np.einsum("ij,ij->i", p[:, 1] - p[:, 0],
                     np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0])) / 6.0


def validate_and_orient(mesh: Mesh, source: str) -> Mesh:
    """Check a mesh for the errors a user can make; orient its cells (triangles
    counter-clockwise, tetrahedra with positive volume).

    Raises InputError naming ``source`` for degenerate cells, out-of-range or duplicated
    nodes, facets shared by more than two cells, folds, and empty regions.
    """
    pts = np.asarray(mesh.points, dtype=float)
    cells = np.asarray(mesh.cells)
    if pts.ndim != 2 or pts.shape[1] not in (2, 3) or len(pts) < pts.shape[1] + 1:
        raise InputError(f"{source}: expected at least 3 points with 2 coordinates (or 4 "
                         "with 3)")
    d = pts.shape[1]
    kind, kinds = ("triangle", "triangles") if d == 2 else ("tetrahedron", "tetrahedra")
    if not np.all(np.isfinite(pts)):
        raise InputError(f"{source}: non-finite point coordinates")
    if cells.ndim != 2 or cells.shape[1] != d + 1 or len(cells) == 0:
        raise InputError(f"{source}: expected a non-empty list of {kind}s (m, {d + 1})")
    if cells.min() < 0 or cells.max() >= len(pts):
        raise InputError(f"{source}: {kind} node index out of range 0..{len(pts) - 1}")
    cells = cells.astype(np.int64)
    ordered = np.sort(cells, axis=1)
    if np.any(ordered[:, 1:] == ordered[:, :-1]):
        raise InputError(f"{source}: a {kind} repeats a node")
    quads = None if mesh.quads is None else np.asarray(mesh.quads, dtype=np.int64)
    if quads is not None and (quads.ndim != 2 or quads.shape[1] != 4 or quads.min() < 0
                              or quads.max() >= len(pts)):
        raise InputError(f"{source}: quadrilateral node index out of range 0..{len(pts) - 1}")
    if quads is not None:
        quads = orient_counter_clockwise(pts, quads)
    mesh = Mesh(pts, cells, {k: np.asarray(v, dtype=np.int64) for k, v in mesh.regions.items()},
                quads, dict(mesh.skipped_sets))
    measure = mesh.cell_volumes()
    scale = np.median(mesh.edge_lengths()) ** d
    bad = np.flatnonzero(np.abs(measure) <= 1e-10 * scale)
    if len(bad):
        what = "area" if d == 2 else "volume"
        raise InputError(f"{source}: {len(bad)} degenerate {kind}(s) of (near) zero {what}, "
                         f"first is {kind} {bad[0]} with nodes {cells[bad[0]].tolist()}")
    flip = measure < 0
    cells[flip] = cells[flip][:, [0, 2, 1] + list(range(3, d + 1))]
    used = np.zeros(len(pts), bool)
    used[cells.ravel()] = True
    if not used.all():
        raise InputError(f"{source}: {int((~used).sum())} node(s) belong to no {kind}, "
                         f"first is node {int(np.flatnonzero(~used)[0])}")
    facets = cell_facets(cells, d)
    keys = facet_keys(facets)
    _, counts = np.unique(keys, return_counts=True)
    what = "edge" if d == 2 else "face"
    if counts.max() > 2:
        raise InputError(f"{source}: {int((counts > 2).sum())} {what}(s) shared by more than "
                         f"two {kinds}"
                         " (the mesh is not a manifold)")
    # nodes closer than 1e-6 of the median edge are one point meant twice (a legitimate mesh
    # has no such pair; left apart, the body would run as pieces with a crack between them)
    from scipy.spatial import cKDTree
    pairs = cKDTree(pts).query_pairs(1e-6 * scale ** (1.0 / d), output_type="ndarray")
    if len(pairs):
        a, b = (int(i) for i in pairs[0])
        raise InputError(f"{source}: {len(pairs)} pair(s) of duplicated nodes (closer than "
                         f"1e-6 of the median edge), first nodes {a} and {b}; merge them so "
                         f"the {kinds} connect")
    # now all positively oriented: the two cells of an interior facet see it with opposite
    # orientations; the same orientation means both lie on one side (a fold, where cells
    # overlap and the body would get their mass twice)
    order = np.argsort(keys, kind="stable")
    pair = np.flatnonzero(keys[order][1:] == keys[order][:-1])
    parity = _orientation_parity(facets)
    folded = pair[parity[order][pair] == parity[order][pair + 1]]
    if len(folded):
        nodes = sorted(facets[order[folded[0]]].tolist())
        raise InputError(f"{source}: the mesh folds over itself: {len(folded)} interior "
                         f"{what}(s) have both {kinds}"
                         f" on the same side, first is {what} {tuple(nodes)} (inverted cells "
                         "overlapping their neighbours)")
    mesh.cells = cells
    # re-orient region facets like the boundary facets they are
    boundary = boundary_facets(cells, d)
    bkeys = facet_keys(boundary)
    border = np.argsort(bkeys)
    for name, region in mesh.regions.items():
        if len(region) == 0:
            raise InputError(f"{source}: boundary region {name!r} is empty")
        region = region.reshape(-1, d)
        rkeys = facet_keys(region)
        pos = np.minimum(np.searchsorted(bkeys, rkeys, sorter=border), len(bkeys) - 1)
        found = bkeys[border[pos]] == rkeys
        if not found.all():
            bad = region[np.flatnonzero(~found)[0]]
            raise InputError(f"{source}: region {name!r} has {what} {tuple(bad.tolist())} that "
                             f"is not on the boundary of the {kinds}")
        mesh.regions[name] = boundary[border[pos]].astype(np.int64).reshape(-1, d)
    return mesh


def _orientation_parity(facets: np.ndarray) -> np.ndarray:
    """Whether each oriented facet is an even permutation of its sorted nodes: the two
    cells of an interior facet give it opposite parities."""
    if facets.shape[1] == 2:
        return facets[:, 0] < facets[:, 1]
    a, b, c = facets[:, 0], facets[:, 1], facets[:, 2]
    inversions = (a > b).astype(int) + (a > c) + (b > c)
    return inversions % 2 == 0


def renumber_for_locality(mesh: Mesh) -> tuple[Mesh, np.ndarray]:
    """A node order whose edge loops touch few nodes at a time; cells sorted by their first
    node.

    2D: reverse Cuthill-McKee. 3D: slabs (``slab_order``): in a tetrahedral mesh the nodes
    an edge loop keeps in reach span a band of the order, and reverse Cuthill-McKee's band
    (its level sets from a corner run diagonally through a box) is 2.5 times that of slabs
    across the longest extent; with the band's data larger than a core's cache, the 3D flux
    loop is 15-20% slower in that order (docs/performance.md). In 2D a band of either order
    fits in cache.

    Returns the renumbered mesh and ``order`` with new_points = old_points[order].
    """
    n = mesh.n_nodes
    e = unique_edges(mesh.cells, mesh.dim)
    if mesh.dim == 3:
        order = slab_order(mesh.points, e)
    else:
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


def slab_order(points: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Nodes in slabs across the longest extent of the body, rows across the next, then
    along the shortest: the lexicographic order of a structured grid, for any mesh.

    Slabs and rows are one typical spacing thick (the median over the nodes of their
    shortest edge, h), counted from the smallest coordinate by rounding, so that the planes
    of a structured grid fall in the middle of theirs. An edge then joins nodes at most a
    few slabs apart, and the nodes a loop over the edges keeps in reach are about two slabs.
    Returns ``order`` with new_points = points[order].
    """
    n = len(points)
    length = np.linalg.norm(points[edges[:, 1]] - points[edges[:, 0]], axis=1)
    shortest = np.full(n, np.inf)
    np.minimum.at(shortest, edges[:, 0], length)
    np.minimum.at(shortest, edges[:, 1], length)
    h = float(np.median(shortest[np.isfinite(shortest)])) if np.isfinite(shortest).any() else 1.0
    low = points.min(axis=0)
    extent = points.max(axis=0) - low
    slow, middle, fast = np.argsort(-extent, kind="stable")
    slab = np.rint((points[:, slow] - low[slow]) / h).astype(np.int64)
    row = np.rint((points[:, middle] - low[middle]) / h).astype(np.int64)
    return np.lexsort((points[:, fast], row, slab)).astype(np.int64)
