"""Named sets of a mesh file -> boundary regions.

A mesh file names parts of its mesh in several ways; each becomes a boundary region (a list
of boundary facets) of the same name:

* a **node set** (Abaqus ``*NSET``, meshio ``point_sets``): the boundary facets whose nodes
  all lie in the set;
* an **element set** (Abaqus ``*ELSET``, meshio ``cell_sets``): its line elements are
  facets themselves; of its triangles and quadrilaterals, the faces on the boundary;
* a node set and an element set of the same name (what Abaqus/CAE writes for a set): the
  facets both give (the boundary faces of the set's elements whose nodes are all in the set);
* a **surface** (Abaqus ``*SURFACE``): the element faces it lists (``S1``..), which must be
  boundary facets, and the boundary faces of the element sets it lists without a face id;
  a surface wins over sets of the same name;
* a gmsh physical group of lines: its lines (read by impactfv.mesh.reader).

A set that gives no boundary facet (a set of interior nodes, a single node, a reference
point) is not a region; it is listed with the reason in ``Mesh.skipped_sets``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .edges import edge_keys


@dataclass
class RawMesh:
    """A mesh file as read, before it becomes a :class:`impactfv.mesh.Mesh`.

    ``blocks`` are (meshio cell type, connectivity); element numbers count the elements of
    all blocks in order. Sets: ``node_sets`` (node indices), ``element_sets`` (element
    numbers), ``face_sets`` ((k, 2): element number, local face 0..; each must be a
    boundary facet), ``surface_elements`` (element numbers whose boundary facets a surface
    takes), ``line_groups`` (gmsh physical groups of lines: (k, 2) node pairs)."""

    points: np.ndarray
    blocks: list = field(default_factory=list)
    node_sets: dict = field(default_factory=dict)
    element_sets: dict = field(default_factory=dict)
    face_sets: dict = field(default_factory=dict)
    surface_elements: dict = field(default_factory=dict)
    line_groups: dict = field(default_factory=dict)


def element_faces(blocks, numbers, local=None) -> np.ndarray:
    """Node pairs (k, 2) of the faces of elements ``numbers`` (all their faces, or face
    ``local[i]`` of element ``numbers[i]``); line elements are their own face."""
    sizes = np.array([len(b[1]) for b in blocks], dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(sizes)])
    numbers = np.asarray(numbers, dtype=np.int64)
    out = []
    for k, (kind, conn) in enumerate(blocks):
        inside = (numbers >= starts[k]) & (numbers < starts[k + 1])
        if not inside.any():
            continue
        rows = numbers[inside] - starts[k]
        cells = conn[rows]
        m = cells.shape[1]
        if kind == "line":
            out.append(cells[:, :2])
        elif local is None:
            out += [cells[:, [i, (i + 1) % m]] for i in range(m)]
        else:
            f = np.asarray(local)[inside]
            out.append(np.column_stack([cells[np.arange(len(rows)), f],
                                        cells[np.arange(len(rows)), (f + 1) % m]]))
    return np.concatenate(out) if out else np.zeros((0, 2), np.int64)


def _unique_facets(pairs):
    if len(pairs) == 0:
        return np.zeros((0, 2), np.int64)
    _, first = np.unique(edge_keys(pairs), return_index=True)
    return pairs[np.sort(first)]


def regions_from_sets(raw: RawMesh, boundary: np.ndarray):
    """(regions, skipped): region name -> facets (k, 2) for every named set of ``raw`` that
    gives boundary facets, and name -> reason for those that give none. ``boundary`` holds
    the boundary facets of the mesh (node numbers of ``raw``)."""
    bkeys = np.sort(edge_keys(boundary))

    def on_boundary(pairs):
        if len(pairs) == 0:
            return pairs
        keys = edge_keys(pairs)
        pos = np.minimum(np.searchsorted(bkeys, keys), len(bkeys) - 1)
        return pairs[bkeys[pos] == keys]

    is_line = np.concatenate([np.full(len(b[1]), b[0] == "line") for b in raw.blocks]) \
        if raw.blocks else np.zeros(0, bool)

    def element_facets(numbers):
        numbers = np.asarray(numbers, dtype=np.int64)
        lines = is_line[numbers]
        return np.concatenate([element_faces(raw.blocks, numbers[lines]),
                               on_boundary(element_faces(raw.blocks, numbers[~lines]))])

    regions, skipped = {}, {}
    surfaces = set(raw.face_sets) | set(raw.surface_elements)
    for name in list(dict.fromkeys([*raw.node_sets, *raw.element_sets, *surfaces])):
        if name in surfaces:
            exact = raw.face_sets.get(name, np.zeros((0, 2), np.int64))
            facets = np.concatenate([
                element_faces(raw.blocks, exact[:, 0], exact[:, 1]) if len(exact)
                else np.zeros((0, 2), np.int64),
                element_facets(raw.surface_elements.get(name, np.zeros(0, np.int64)))])
            what = "surface"
        else:
            nodes = raw.node_sets.get(name)
            elements = raw.element_sets.get(name)
            if elements is not None:
                facets = element_facets(elements)
                what = "element set"
            else:
                facets = boundary
                what = "node set"
            if nodes is not None:
                inside = np.zeros(len(raw.points), bool)
                inside[nodes] = True
                facets = facets[inside[facets].all(axis=1)] if len(facets) else facets
                if elements is not None:
                    what = "node and element set"
        facets = _unique_facets(np.asarray(facets, dtype=np.int64).reshape(-1, 2))
        if len(facets):
            regions[name] = facets
        else:
            skipped[name] = f"{what} with no facet on the boundary of the mesh"
    return regions, skipped
