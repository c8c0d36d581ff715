"""Checkpoints: one atomic ``.npz`` per checkpoint (no pickle), in ``<output>/checkpoints``,
and the description of the case a checkpoint may be continued with.

A checkpoint records the case as a flat table ``{key path: value}`` of the validated case
(plus a hash of every body's mesh as read: points, cells and regions) without the keys a
restart may change: ``run.end_time``, ``run.output_interval`` and ``run.max_steps`` (and the
``--checkpoint-every`` option, which is not in the case). A restart whose case differs in any
other key is refused, naming the keys that changed.
"""

from __future__ import annotations

import hashlib
import io
import json
import sys
from pathlib import Path

import numpy as np

from ..errors import InputError, printable
from .writers import atomic_replace

#: keys of the case a restart may change: they say how long to run and what to write
RESTART_MAY_CHANGE = ("run.end_time", "run.output_interval", "run.max_steps",
                      "output.keep_checkpoints")
BAD_SUFFIX = ".unreadable"


class BadCheckpoint(Exception):
    """A checkpoint file that cannot be continued from (truncated, corrupted, crafted)."""


def _flatten(value, path, out):
    if isinstance(value, dict):
        for k in sorted(value):
            _flatten(value[k], f"{path}.{k}" if path else str(k), out)
    elif isinstance(value, (list, tuple)) and path.rsplit(".", 1)[-1] in ("material", "body",
                                                                         "contact",
                                                                         "boundary"):
        for i, item in enumerate(value):
            _flatten(item, f"{path}[{i}]", out)
    elif callable(value):
        out[path] = "callable " + getattr(value, "__qualname__", type(value).__name__)
    else:
        out[path] = repr(value)


def mesh_digest(mesh) -> str:
    """A hash of a mesh as read and checked: its points, cells and regions."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(mesh.points, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(mesh.cells, dtype=np.int64).tobytes())
    for name in sorted(mesh.regions):
        h.update(name.encode() + b"\0")
        h.update(np.ascontiguousarray(mesh.regions[name], dtype=np.int64).tobytes())
    return h.hexdigest()


def case_description(case) -> dict[str, str]:
    """``{key path: value}`` of everything a checkpoint depends on (see the module text)."""
    out: dict[str, str] = {}
    _flatten(case.spec.model_dump(mode="python"), "", out)
    for key in RESTART_MAY_CHANGE:
        out.pop(key, None)
    for i, body in enumerate(case.bodies):
        out[f"body[{i}].mesh (the mesh data as read)"] = mesh_digest(body.mesh)
    return out


def fingerprint_of(description: dict) -> str:
    """A hash of a case's :func:`case_description`, which a checkpoint carries, so that it is
    never continued with another case (a changed mesh file included)."""
    return hashlib.sha256(json.dumps(description, sort_keys=True).encode()).hexdigest()


def changed_keys(old: dict, new: dict) -> list[str]:
    """The key paths whose values differ between two case descriptions."""
    return sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))


def save_checkpoint(folder: Path, steps: int, arrays: dict[str, np.ndarray],
                    keep: int | None = None) -> Path:
    """Write ``checkpoint_<steps>.npz`` atomically; returns its path. ``keep``: then delete
    all but the newest ``keep`` checkpoints of the folder (None: keep all)."""
    path = Path(folder) / f"checkpoint_{steps:09d}.npz"

    def dump(fh):
        buf = io.BytesIO()
        np.savez(buf, **arrays)
        fh.write(buf.getvalue())
    atomic_replace(path, dump)
    if keep is not None:
        for old in sorted(Path(folder).glob("checkpoint_*.npz"))[:-keep]:
            old.unlink(missing_ok=True)
    return path


def _read(path: Path) -> dict[str, np.ndarray]:
    try:
        with np.load(path, allow_pickle=False) as data:   # zipfile checks each CRC
            return {k: data[k] for k in data.files}
    except Exception as exc:   # zipfile, zlib, numpy format errors: all mean "corrupted"
        text = str(exc).strip().splitlines()
        raise BadCheckpoint(f"{type(exc).__name__}: {text[0]}" if text
                            else type(exc).__name__) from None


def load_good_checkpoint(folder: Path, accept) -> tuple[Path, dict[str, np.ndarray]]:
    """The arrays of the newest checkpoint in ``folder`` that can be read and that
    ``accept(path, arrays)`` takes (it raises BadCheckpoint for one that cannot be continued
    from, or InputError to refuse the restart). Checkpoints skipped on the way are renamed
    ``*.npz.unreadable`` and reported in one warning line on stderr; InputError when none is
    good."""
    folder = Path(folder)
    files = sorted(folder.glob("checkpoint_*.npz")) if folder.is_dir() else []
    if not files:
        raise InputError(f"{folder}: no checkpoint to restart from")
    skipped = []
    for path in reversed(files):
        try:
            data = _read(path)
            accept(path, data)
        except BadCheckpoint as exc:
            skipped.append((path, str(exc)))
            continue
        if skipped:
            newest, why = skipped[0]
            more = f" and {len(skipped) - 1} older one(s)" if len(skipped) > 1 else ""
            for bad, _ in skipped:
                try:
                    bad.replace(bad.with_name(bad.name + BAD_SUFFIX))
                except OSError:
                    pass
            print(printable(f"impactfv: warning: {newest}{more}: unreadable checkpoint "
                            f"({why}), kept as *{BAD_SUFFIX}; continuing from {path.name}"),
                  file=sys.stderr)
        return path, data
    newest, why = skipped[0]
    raise InputError(f"{newest}: unreadable checkpoint ({why}), and no older checkpoint in "
                     f"{folder} can be read either")


def load_newest_checkpoint(folder: Path) -> tuple[Path, dict[str, np.ndarray]]:
    """The arrays of the newest readable checkpoint in ``folder`` (InputError if none)."""
    return load_good_checkpoint(folder, lambda path, data: None)
