"""Output files. Each is written to a temporary name in the same folder, then renamed, so a
run killed at any moment leaves every existing file complete and readable."""

from __future__ import annotations

import io
import json
import os
import tempfile
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from ..case import INTEGER_FIELDS


def _follow_umask(path):
    """Give a finished temporary file the mode a plain open() would have (0666 minus the
    umask): mkstemp creates files 0600, which colleagues on a shared machine cannot read."""
    mask = os.umask(0)
    os.umask(mask)
    os.chmod(path, 0o666 & ~mask)


def atomic_replace(path: Path, write):
    """Write ``path`` through ``write(file handle)`` into a temporary file, then rename."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        _follow_umask(tmp)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def atomic_write_text(path, text: str):
    atomic_replace(path, lambda fh: fh.write(text.encode("utf-8")))


def write_history_csv(path, history: dict[str, np.ndarray], n_rows: int):
    names = list(history)
    table = np.column_stack([history[k][:n_rows] for k in names]) if n_rows else \
        np.zeros((0, len(names)))
    buf = io.StringIO()
    buf.write(",".join(names) + "\n")
    np.savetxt(buf, table, delimiter=",", fmt="%.12e")
    atomic_write_text(path, buf.getvalue())


def json_safe(value):
    """``value`` with every NaN or infinity replaced by None (JSON has no such numbers: a
    reader would choke on ``NaN``) and numpy scalars turned into Python numbers."""
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def write_summary(path, summary: dict):
    """summary.json: strict JSON, non-finite numbers written as null."""
    text = json.dumps(json_safe(summary), indent=2, sort_keys=False, allow_nan=False)
    atomic_write_text(path, text + "\n")


def _three_components(value, dim):
    if value.ndim == 2 and value.shape[1] == dim and dim < 3:
        return np.column_stack([value, np.zeros((len(value), 3 - dim))])
    return value


def cell_type(dim: int, nodes_per_cell: int) -> str:
    """The VTK (meshio) cell type of cells of ``nodes_per_cell`` nodes in ``dim`` dimensions:
    triangle or quad in 2D, tetra in 3D."""
    kinds = {(2, 3): "triangle", (2, 4): "quad", (3, 4): "tetra"}
    if (dim, nodes_per_cell) not in kinds:
        raise ValueError(f"no VTK cell type for {nodes_per_cell}-node cells in {dim}D")
    return kinds[(dim, nodes_per_cell)]


def frame_arrays(point_data: dict, dim: int, fields=None) -> dict:
    """The point data of a frame as ParaView reads it: vectors (n, d) with 3 components,
    3 x 3 tensors as 6 (xx, yy, zz, xy, yz, xz), integer fields as int32; only ``fields``
    (None: all)."""

    out = {}
    for key, value in point_data.items():
        if fields is not None and key not in fields:
            continue
        value = np.asarray(value)
        if key in INTEGER_FIELDS:
            out[key] = value.astype(np.int32)
        elif value.ndim == 3:
            out[key] = vtk_tensor(value.astype(float))
        else:
            out[key] = _three_components(value.astype(float), dim)
    return out


def _write_vtu(target: Path, mesh):
    import meshio

    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    os.close(fd)
    try:
        meshio.write(tmp, mesh, file_format="vtu", binary=True, compression="zlib")
        _follow_umask(tmp)
        os.replace(tmp, target)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _write_pvd(path: Path, entries):
    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
             "  <Collection>"]
    for t, name in entries:
        lines.append(f'    <DataSet timestep="{t:.12e}" group="" part="0" '
                     f"file={quoteattr(name)}/>")
    lines += ["  </Collection>", "</VTKFile>", ""]
    atomic_write_text(path, "\n".join(lines))


def wall_patch(centre, normal, size):
    """Points and cells of a flat patch of the wall through ``centre`` with ``normal``, of
    side ``size``: a segment in 2D ("line"), a square in 3D ("quad")."""
    normal = np.asarray(normal, float)
    d = len(normal)
    # tangent basis: the null space of the normal
    tangents = np.linalg.svd(normal[None, :])[2][1:]
    corners = [[-0.5], [0.5]] if d == 2 else [[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5],
                                               [-0.5, 0.5]]
    points = np.asarray(centre, float) + size * np.asarray(corners) @ tangents
    return points, ("line" if d == 2 else "quad"), np.arange(len(points))[None, :]


class SnapshotWriter:
    """Writes ``<stem>_NNNN.vtu`` frames and keeps ``<stem>.pvd`` indexing them; with rigid
    walls also ``walls_NNNN.vtu`` and ``walls.pvd`` (a patch per wall, moved with it).

    Frames hold the **reference** points and the ``displacement`` field (ParaView's "Warp
    By Vector" on displacement, scale 1, gives the deformed bodies), zlib-compressed."""

    def __init__(self, folder, stem: str = "fields", fields=None, walls=()):
        self.folder = Path(folder)
        self.stem = stem
        self.fields = None if fields is None else tuple(fields)
        self.walls = list(walls or ())
        self.entries: list[tuple[float, str]] = []

    def write(self, time: float, points: np.ndarray, cells: np.ndarray,
              point_data: dict[str, np.ndarray]):
        """Add a frame: reference points (n, d), cells (triangles or quads in 2D, tetrahedra
        in 3D) and point fields (:func:`frame_arrays`)."""
        import meshio

        name = f"{self.stem}_{len(self.entries):04d}.vtu"
        points = np.asarray(points, dtype=float)
        dim = points.shape[1]
        cells = np.asarray(cells, dtype=np.int64)
        mesh = meshio.Mesh(_three_components(points, dim),
                           [(cell_type(dim, cells.shape[1]), cells)],
                           point_data=frame_arrays(point_data, dim, self.fields))
        self.folder.mkdir(parents=True, exist_ok=True)
        _write_vtu(self.folder / name, mesh)
        if self.walls:
            self._write_walls(time, dim, len(self.entries))
        self.entries.append((time, name))
        self.write_collection()

    def write_collection(self):
        """Write `<stem>.pvd` (and `walls.pvd`) listing the current entries."""
        _write_pvd(self.folder / f"{self.stem}.pvd", self.entries)
        if self.walls:
            _write_pvd(self.folder / "walls.pvd",
                       [(t, f"walls_{k:04d}.vtu") for k, (t, _) in enumerate(self.entries)])

    def _write_walls(self, time, dim, index):
        import meshio

        points, cells, velocity, wall = [], [], [], []
        for k, (centre, normal, v, size) in enumerate(self.walls):
            p, kind, c = wall_patch(np.asarray(centre) + time * np.asarray(v), normal, size)
            cells.append((kind, c + sum(len(q) for q in points)))
            points.append(p)
            velocity.append(np.repeat(np.asarray(v, float)[None, :], len(p), axis=0))
            wall.append(np.full(len(p), k, np.int32))
        normals = np.concatenate([np.repeat(np.asarray(n, float)[None, :], len(p), axis=0)
                                  for (_, n, _, _), p in zip(self.walls, points)])
        mesh = meshio.Mesh(_three_components(np.concatenate(points), dim), cells,
                           point_data={"velocity": _three_components(np.concatenate(velocity),
                                                                     dim),
                                       "normal": _three_components(normals, dim),
                                       "wall": np.concatenate(wall)})
        _write_vtu(self.folder / f"walls_{index:04d}.vtu", mesh)


def vtk_tensor(stress: np.ndarray) -> np.ndarray:
    """(n, 6) components xx, yy, zz, xy, yz, xz of symmetric (n, 3, 3) tensors: the order in
    which ParaView reads a 6-component array as a symmetric tensor."""
    s = np.asarray(stress)
    return np.column_stack([s[:, 0, 0], s[:, 1, 1], s[:, 2, 2], s[:, 0, 1], s[:, 1, 2],
                            s[:, 0, 2]])
