"""Mesh files: Abaqus ``.inp`` (impactfv.mesh.abaqus) and every format meshio reads; their
named sets and gmsh physical groups become boundary regions (impactfv.mesh.sets), their
quadrilaterals are cut into triangles for the FV scheme and kept for the Q4 baseline
(impactfv.mesh.quads). A file with tetrahedra is a 3D mesh; its gmsh physical surfaces
(tagged triangles) are its regions."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np

from ..errors import InputError
from .core import Mesh
from .edges import boundary_facets
from .quads import orient_counter_clockwise, split_quads
from .sets import RawMesh, regions_from_sets


def read_mesh(path: str | Path) -> Mesh:
    """Read a 2D mesh of linear triangles and/or quadrilaterals, or a 3D mesh of linear
    tetrahedra.

    Regions: gmsh physical groups of lines (2D) or triangles (3D), named after the group, or
    ``group<N>``, and the named node sets, element sets and surfaces of other formats
    (impactfv.mesh.sets). Quadratic or other cells are refused.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: mesh file not found")
    if path.suffix.lower() == ".inp":
        from .abaqus import read_inp
        raw = read_inp(path)
    else:
        m = _meshio_read(path)
        if any(block.type == "tetra" for block in m.cells):
            return _tetrahedral(path, m)
        raw = _read_meshio(path, m)
    return raw_to_mesh(raw, str(path))


def _meshio_read(path: Path):
    import meshio

    said = io.StringIO()
    try:
        # meshio prints warnings and blank lines of its own: keep them off our output
        with contextlib.redirect_stderr(said), contextlib.redirect_stdout(io.StringIO()):
            m = meshio.read(str(path))
    except (Exception, SystemExit) as exc:  # meshio raises many types, and some readers
        # print a message and call sys.exit on malformed files; all mean the same to a user
        text = str(exc) if not isinstance(exc, SystemExit) else said.getvalue()
        first = text.strip().splitlines()[0] if text.strip() else type(exc).__name__
        raise InputError(f"{path}: cannot read mesh ({first})") from None
    return m


def _read_meshio(path: Path, m) -> RawMesh:
    raw = RawMesh(np.asarray(m.points, dtype=float))
    physical = m.cell_data.get("gmsh:physical")
    names = {}
    for name, value in (m.field_data or {}).items() if physical is not None else ():
        value = np.asarray(value).ravel()
        if len(value) == 2 and int(value[1]) == 1:
            names[int(value[0])] = name
    keep = []
    for k, block in enumerate(m.cells):
        if block.type == "vertex":
            continue
        if block.type not in ("triangle", "quad", "line"):
            raise InputError(f"{path}: cells of type {block.type!r} are not supported "
                             "(expected linear triangles or quadrilaterals)")
        keep.append(k)
        raw.blocks.append((block.type, np.asarray(block.data, dtype=np.int64)))
        if block.type == "line" and physical is not None:
            tags = np.asarray(physical[k])
            for tag in np.unique(tags):
                if tag >= 0:
                    name = names.get(int(tag), f"group{int(tag)}")
                    raw.line_groups.setdefault(name, []).append(block.data[tags == tag])
    raw.line_groups = {k: np.concatenate(v) for k, v in raw.line_groups.items()}
    if physical is None:
        # named sets of other formats; a gmsh file's cell_sets repeat its physical groups
        offsets = np.concatenate([[0], np.cumsum([len(m.cells[k].data) for k in keep])])
        for name, per_block in (m.cell_sets or {}).items():
            if name.startswith("gmsh:"):
                continue
            numbers = [np.asarray(per_block[k], dtype=np.int64) + offsets[j]
                       for j, k in enumerate(keep) if k < len(per_block)]
            raw.element_sets[name] = np.concatenate(numbers) if numbers else \
                np.zeros(0, np.int64)
        for name, nodes in (m.point_sets or {}).items():
            raw.node_sets[name] = np.asarray(nodes, dtype=np.int64).ravel()
    return raw


def raw_to_mesh(raw: RawMesh, source: str) -> Mesh:
    """The Mesh of a file as read: planar points, triangles (quads cut in two), regions."""
    points = np.asarray(raw.points, dtype=float)
    if points.ndim != 2 or points.shape[1] < 2:
        raise InputError(f"{source}: expected 2D points")
    if points.shape[1] == 3:
        if np.ptp(points[:, 2]) > 1e-12 * max(np.ptp(points[:, :2]), 1e-300):
            raise InputError(f"{source}: points are not planar (z varies); 2D meshes only")
        points = points[:, :2]
    triangles = [b[1] for b in raw.blocks if b[0] == "triangle"]
    quads = [b[1] for b in raw.blocks if b[0] == "quad"]
    tri = np.concatenate(triangles).astype(np.int64) if triangles else np.zeros((0, 3), int)
    quad = np.concatenate(quads).astype(np.int64) if quads else np.zeros((0, 4), int)
    if len(tri) + len(quad) == 0:
        raise InputError(f"{source}: no triangles or quadrilaterals found")
    for cells in (tri, quad):
        if len(cells) and (cells.min() < 0 or cells.max() >= len(points)):
            raise InputError(f"{source}: cell node index out of range 0..{len(points) - 1}")
    if len(quad):
        quad = orient_counter_clockwise(points, quad)
        tri = np.concatenate([tri, split_quads(points, quad, tri)])
    regions, skipped = regions_from_sets(raw, boundary_facets(tri))
    for name, lines in raw.line_groups.items():
        regions[name] = np.asarray(lines, dtype=np.int64).reshape(-1, 2)
        skipped.pop(name, None)
    # drop points not used by cells (gmsh often keeps geometry points)
    used = np.zeros(len(points), bool)
    used[tri.ravel()] = True
    new_index = np.cumsum(used) - 1
    for name, facets in regions.items():
        if not used[facets.ravel()].all():
            raise InputError(f"{source}: region {name!r} has line nodes that belong to no "
                             "triangle or quadrilateral")
    regions = {k: new_index[v] for k, v in regions.items()}
    only_quads = len(quad) and not triangles
    return Mesh(points[used], new_index[tri], regions,
                quads=new_index[quad] if only_quads else None, skipped_sets=skipped)


def _tetrahedral(path, m) -> Mesh:
    """A 3D mesh: tetrahedra, and the tagged triangles as boundary regions."""
    points = np.asarray(m.points, dtype=float)
    if points.ndim != 2 or points.shape[1] != 3:
        raise InputError(f"{path}: tetrahedra need 3D points")
    names = {}
    for name, value in (m.field_data or {}).items():
        value = np.asarray(value).ravel()
        if len(value) == 2 and int(value[1]) == 2:
            names[int(value[0])] = name
    physical = m.cell_data.get("gmsh:physical")
    tets, faces, face_tags = [], [], []
    for k, block in enumerate(m.cells):
        if block.type == "tetra":
            tets.append(block.data)
        elif block.type == "triangle":
            faces.append(block.data)
            tags = physical[k] if physical is not None else np.full(len(block.data), -1)
            face_tags.append(np.asarray(tags))
        elif block.type in ("vertex", "line"):
            continue
        else:
            raise InputError(f"{path}: cells of type {block.type!r} are not supported "
                             "(expected linear tetrahedra)")
    tet = np.concatenate(tets).astype(np.int64)
    if tet.min() < 0 or tet.max() >= len(points):
        raise InputError(f"{path}: cell node index out of range 0..{len(points) - 1}")
    used = np.zeros(len(points), bool)
    used[tet.ravel()] = True
    new_index = np.cumsum(used) - 1
    regions = {}
    if faces:
        all_faces = np.concatenate(faces).astype(np.int64)
        all_tags = np.concatenate(face_tags)
        for tag in np.unique(all_tags):
            if tag < 0:
                continue
            group = all_faces[all_tags == tag]
            if not used[group.ravel()].all():
                raise InputError(f"{path}: physical group {names.get(int(tag), tag)!r} has "
                                 "triangle nodes that belong to no tetrahedron")
            regions[names.get(int(tag), f"group{int(tag)}")] = new_index[group]
    return Mesh(points[used], new_index[tet], regions)
