"""One run owns its output folder: a lock file while it writes, and no files of an earlier
run left looking like its own."""

from __future__ import annotations

import os
from pathlib import Path

from .. import interrupts
from ..errors import InputError

LOCK_NAME = ".impactfv.lock"
#: the mark of a folder an impactfv run made: only such a folder (or an empty one) is
#: written into without --overwrite
MARKER_NAME = ".impactfv-output"
# the folders a run writes into, inside its output folder
SUBFOLDERS = ("checkpoints", "plots")
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
    are removed in any case.

    What a run may touch: a fresh run writes only into a folder that is empty or that an
    impactfv run made (its marker file), and not into one holding checkpoints that
    ``--restart`` could continue, unless ``overwrite``; no run writes or deletes through a
    symbolic link in the folder (a linked ``plots/``, ``checkpoints/`` or output file). Every
    refusal comes before anything on disk changes."""

    def __init__(self, path, fresh: bool, overwrite: bool = False):
        self.path = Path(path)
        self.fresh = fresh
        self.overwrite = overwrite
        self.lock = self.path / LOCK_NAME
        self.held = False

    def _refuse_what_is_not_ours(self):
        """An InputError naming what this run would delete or write through that is not its
        own; nothing has changed on disk yet."""
        path = self.path
        if not path.is_dir():
            return
        for name in SUBFOLDERS:
            linked = path / name
            if linked.is_symlink():
                raise InputError(f"{linked}: is a symbolic link; a run writes only into "
                                 "folders it made (remove the link, or choose another output "
                                 "folder with -o)")
            if linked.exists() and not linked.is_dir():
                raise InputError(f"{linked}: is a file where the run keeps a folder (remove "
                                 "it, or choose another output folder with -o)")
        for pattern in OUTPUT_PATTERNS:
            for found in path.glob(pattern):
                if found.is_symlink():
                    raise InputError(f"{found}: is a symbolic link; a run never writes or "
                                     "deletes through a link (remove it, or choose another "
                                     "output folder with -o)")
                if found.is_dir():
                    raise InputError(f"{found}: is a folder where the run writes a file "
                                     "(remove it, or choose another output folder with -o)")
        if not self.fresh or self.overwrite:
            return
        if not (path / MARKER_NAME).exists():
            others = [p.name for p in path.iterdir() if p.name != LOCK_NAME]
            if others:
                raise InputError(f"{path}: the output folder is not empty and was not made "
                                 f"by impactfv (it holds {others[0]!r}); choose an empty or "
                                 "new folder with -o, or pass --overwrite to write into it")
        elif any((path / "checkpoints").glob("checkpoint_*.npz")):
            raise InputError(f"{path}: holds checkpoints of an earlier run; continue it with "
                             f"--restart {path}, or pass --overwrite to start afresh (which "
                             "deletes them)")

    def _refuse_if_busy(self):
        """An InputError when a live process other than this one holds the lock."""
        try:
            pid = int(self.lock.read_text().strip() or 0)
        except (OSError, ValueError):
            return
        if pid > 0 and pid != os.getpid() and _alive(pid):
            raise InputError(f"{self.path}: another impactfv run (process {pid}) is writing "
                             "to this folder; wait for it or choose another with -o") from None

    def __enter__(self):
        # a busy folder first (the other run's files are its own), then what is not ours
        self._refuse_if_busy()
        self._refuse_what_is_not_ours()
        self.path.mkdir(parents=True, exist_ok=True)
        for attempt in range(2):
            try:
                fd = os.open(self.lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                self._refuse_if_busy()
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
        (self.path / MARKER_NAME).touch()
        return self

    def __exit__(self, *exc):
        if self.held:
            self.lock.unlink(missing_ok=True)
            interrupts.keep_on_exit(self.lock)
            self.held = False
        return False
