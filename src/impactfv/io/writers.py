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


class SnapshotWriter:
    """Writes ``<stem>_NNNN.vtu`` snapshots and keeps ``<stem>.pvd`` indexing them."""

    def __init__(self, folder, stem: str = "fields"):
        self.folder = Path(folder)
        self.stem = stem
        self.entries: list[tuple[float, str]] = []

    def write(self, time: float, points: np.ndarray, cells: np.ndarray,
              point_data: dict[str, np.ndarray]):
        """Add a frame: points (n, d), cells (triangles or quads in 2D, tetrahedra in 3D) and
        point fields (vectors (n, d) are written with 3 components, as ParaView wants)."""
        import meshio

        name = f"{self.stem}_{len(self.entries):04d}.vtu"
        dim = points.shape[1]
        data = {key: _three_components(np.asarray(value, dtype=float), dim)
                for key, value in point_data.items()}
        cells = np.asarray(cells, dtype=np.int64)
        kind = {(2, 3): "triangle", (2, 4): "quad", (3, 4): "tetra"}[(dim, cells.shape[1])]
        mesh = meshio.Mesh(_three_components(points, dim), [(kind, cells)], point_data=data)

        target = self.folder / name
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{name}.", suffix=".tmp", dir=target.parent)
        os.close(fd)
        try:
            meshio.write(tmp, mesh, file_format="vtu", binary=True, compression=None)
            _follow_umask(tmp)
            os.replace(tmp, target)
        except BaseException:
            if os.path.exists(tmp):
                os.unlink(tmp)
            raise
        self.entries.append((time, name))
        self.write_collection()

    def write_collection(self):
        """Write `<stem>.pvd` listing the current entries."""
        lines = ['<?xml version="1.0"?>',
                 '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
                 "  <Collection>"]
        for t, name in self.entries:
            lines.append(f'    <DataSet timestep="{t:.12e}" group="" part="0" '
                         f"file={quoteattr(name)}/>")
        lines += ["  </Collection>", "</VTKFile>", ""]
        atomic_write_text(self.folder / f"{self.stem}.pvd", "\n".join(lines))
