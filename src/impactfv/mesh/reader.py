"""Mesh files through meshio; gmsh physical groups on lines (2D) or triangles (3D) name the
boundary regions."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np

from ..errors import InputError
from .core import Mesh


def read_mesh(path: str | Path) -> Mesh:
    """Read a 2D triangle mesh or a 3D tetrahedral mesh (gmsh .msh, or any format meshio
    knows); a file with tetrahedra is 3D.

    Facet cells (lines in 2D, triangles in 3D) tagged with a physical group become boundary
    regions named after the group (or ``group<N>`` when the group has no name). Quadratic or
    other cells are refused.
    """
    import meshio

    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: mesh file not found")
    said = io.StringIO()
    try:
        with contextlib.redirect_stderr(said):
            m = meshio.read(str(path))
    except (Exception, SystemExit) as exc:  # meshio raises many types, and some readers
        # print a message and call sys.exit on malformed files; all mean the same to a user
        text = str(exc) if not isinstance(exc, SystemExit) else said.getvalue()
        first = text.strip().splitlines()[0] if text.strip() else type(exc).__name__
        raise InputError(f"{path}: cannot read mesh ({first})") from None
    points = np.asarray(m.points, dtype=float)
    if points.ndim != 2 or points.shape[1] < 2:
        raise InputError(f"{path}: expected 2D points")
    if any(block.type == "tetra" for block in m.cells):
        return _tetrahedral(path, m, points)
    if points.shape[1] == 3:
        if np.ptp(points[:, 2]) > 1e-12 * max(np.ptp(points[:, :2]), 1e-300):
            raise InputError(f"{path}: points are not planar (z varies); 2D meshes only")
        points = points[:, :2]
    triangles, lines, line_tags = [], [], []
    names = {}
    for name, (tag, dim) in (m.field_data or {}).items():
        if int(dim) == 1:
            names[int(tag)] = name
    physical = m.cell_data.get("gmsh:physical")
    for k, block in enumerate(m.cells):
        if block.type == "triangle":
            triangles.append(block.data)
        elif block.type == "line":
            lines.append(block.data)
            tags = physical[k] if physical is not None else np.full(len(block.data), -1)
            line_tags.append(np.asarray(tags))
        elif block.type in ("vertex",):
            continue
        else:
            raise InputError(f"{path}: cells of type {block.type!r} are not supported "
                             "(expected linear triangles)")
    if not triangles:
        raise InputError(f"{path}: no triangles found")
    tri = np.concatenate(triangles).astype(np.int64)
    # drop points not used by triangles (gmsh often keeps geometry points)
    used = np.zeros(len(points), bool)
    used[tri.ravel()] = True
    new_index = np.cumsum(used) - 1
    regions = {}
    if lines:
        all_lines = np.concatenate(lines)
        all_tags = np.concatenate(line_tags)
        for tag in np.unique(all_tags):
            if tag < 0:
                continue
            edges = all_lines[all_tags == tag]
            if not used[edges.ravel()].all():
                raise InputError(f"{path}: physical group {names.get(int(tag), tag)!r} has "
                                 "line nodes that belong to no triangle")
            regions[names.get(int(tag), f"group{int(tag)}")] = new_index[edges]
    return Mesh(points[used], new_index[tri], regions)


def _tetrahedral(path, m, points) -> Mesh:
    """A 3D mesh: tetrahedra, and the tagged triangles as boundary regions."""
    if points.shape[1] != 3:
        raise InputError(f"{path}: tetrahedra need 3D points")
    names = {int(tag): name for name, (tag, dim) in (m.field_data or {}).items()
             if int(dim) == 2}
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
    used = np.zeros(len(points), bool)
    used[tet.ravel()] = True
    new_index = np.cumsum(used) - 1
    regions = {}
    if faces:
        all_faces = np.concatenate(faces)
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
