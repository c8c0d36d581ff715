"""Checkpoints: one atomic ``.npz`` per checkpoint (no pickle), in ``<output>/checkpoints``."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np

from ..errors import InputError
from .writers import atomic_replace


def case_fingerprint(case) -> str:
    """A hash of the validated case, so a checkpoint is never continued with another case."""
    import hashlib
    text = json.dumps(case.spec.model_dump(mode="python"), sort_keys=True,
                      default=lambda o: getattr(o, "__qualname__", type(o).__name__))
    return hashlib.sha256(text.encode()).hexdigest()


def save_checkpoint(folder: Path, steps: int, arrays: dict[str, np.ndarray]) -> Path:
    """Write ``checkpoint_<steps>.npz`` atomically; returns its path."""
    path = Path(folder) / f"checkpoint_{steps:09d}.npz"

    def dump(fh):
        buf = io.BytesIO()
        np.savez(buf, **arrays)
        fh.write(buf.getvalue())
    atomic_replace(path, dump)
    return path


def load_newest_checkpoint(folder: Path) -> tuple[Path, dict[str, np.ndarray]]:
    """The arrays of the newest checkpoint in ``folder`` (InputError if none or unreadable)."""
    folder = Path(folder)
    files = sorted(folder.glob("checkpoint_*.npz")) if folder.is_dir() else []
    if not files:
        raise InputError(f"{folder}: no checkpoint to restart from")
    path = files[-1]
    try:
        with np.load(path, allow_pickle=False) as data:
            return path, {k: data[k] for k in data.files}
    except (OSError, ValueError, KeyError) as exc:
        raise InputError(f"{path}: unreadable checkpoint ({exc})") from None
