"""One run owns its output folder: a lock file while it writes, and no files of an earlier
run left looking like its own."""

from __future__ import annotations

import os
from pathlib import Path

from .. import interrupts
from ..errors import InputError

LOCK_NAME = ".impactfv.lock"
# what a run writes; a fresh run removes these (and only these) from an earlier run
OUTPUT_PATTERNS = ("fields_*.vtu", "fields.pvd", "walls_*.vtu", "walls.pvd", "history.csv",
                   "summary.json", "checkpoints/checkpoint_*.npz",
                   "checkpoints/checkpoint_*.npz.unreadable", "plots/*.png")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:          # exists, owned by someone else
        return True
    return True


class OutputFolder:
    """``with OutputFolder(path, fresh):`` holds ``path/.impactfv.lock`` (the pid of this
    process) while the run writes. A second run into the same folder is refused with an
    InputError; a lock left by a process that no longer exists is taken over. ``fresh``
    (not a restart): the outputs of an earlier run are removed first, so that its frames and
    checkpoints cannot be mistaken for this run's. Left-over temporary files of a killed run
    are removed in any case."""

    def __init__(self, path, fresh: bool):
        self.path = Path(path)
        self.fresh = fresh
        self.lock = self.path / LOCK_NAME
        self.held = False

    def __enter__(self):
        self.path.mkdir(parents=True, exist_ok=True)
        for attempt in range(2):
            try:
                fd = os.open(self.lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                try:
                    pid = int(self.lock.read_text().strip() or 0)
                except (OSError, ValueError):
                    pid = 0
                if pid > 0 and pid != os.getpid() and _alive(pid):
                    raise InputError(f"{self.path}: another impactfv run (process {pid}) is "
                                     "writing to this folder; wait for it or choose another "
                                     "with -o") from None
                self.lock.unlink(missing_ok=True)     # stale: its process is gone
                continue
            interrupts.remove_on_exit(self.lock)   # a signal before the loop ends at once
            with os.fdopen(fd, "w") as fh:
                fh.write(f"{os.getpid()}\n")
            self.held = True
            break
        else:
            raise InputError(f"{self.path}: cannot take the folder's lock {LOCK_NAME}")
        for tmp in list(self.path.glob(".*.tmp")) + list(self.path.glob("checkpoints/.*.tmp")):
            tmp.unlink(missing_ok=True)
        if self.fresh:
            for pattern in OUTPUT_PATTERNS:
                for old in self.path.glob(pattern):
                    old.unlink(missing_ok=True)
        return self

    def __exit__(self, *exc):
        if self.held:
            self.lock.unlink(missing_ok=True)
            interrupts.keep_on_exit(self.lock)
            self.held = False
        return False
