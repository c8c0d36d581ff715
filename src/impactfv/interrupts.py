"""SIGINT and SIGTERM from the first instant of the command line (standard library only, so
that it can be installed before numpy, numba or the case schema are imported).

Until a run's time loop has taken its first step in this process there is nothing worth a
checkpoint, so :func:`install` makes a signal end the process at once: one line on stderr,
exit code 128 + signum (130 for SIGINT, 143 for SIGTERM), no traceback. Python runs a
signal handler only between two bytecodes of the main thread, and numba's compiler spends
seconds at a time inside LLVM (C code); so the C-level handler also writes the signal number
to a pipe (``signal.set_wakeup_fd``), and a watcher thread, which gets the interpreter while
the main thread is inside C code, ends the process from there.

Once the time loop has taken a step, :func:`defer` hands the signals to the loop, which
finishes the step, writes a checkpoint and valid outputs, then stops
(impactfv.pipeline.signals); :func:`undefer` returns to ending at once.
"""

from __future__ import annotations

import os
import signal
import threading

SIGNALS = (signal.SIGINT, signal.SIGTERM)

_installed = False
_deferred = None          # callable(signum) of the time loop, or None: end at once
_exiting = threading.Lock()
_on_exit: dict[str, None] = {}   # files to remove when ending at once (output folder locks)


def installed() -> bool:
    return _installed


def exit_now(signum: int):
    """Write the one line and end the process with 128 + signum, now."""
    if not _exiting.acquire(blocking=False):
        threading.Event().wait()          # the other thread is ending the process
    for path in list(_on_exit):
        try:
            os.unlink(path)
        except OSError:
            pass
    try:
        name = signal.Signals(signum).name
    except ValueError:
        name = f"signal {signum}"
    try:
        os.write(2, f"impactfv: interrupted by {name} (no time step to checkpoint)\n".encode())
    except OSError:
        pass
    os._exit(128 + signum)


def _handler(signum, frame):
    deferred = _deferred
    if deferred is not None:
        deferred(signum)
    else:
        exit_now(signum)


def _watch(fd: int):
    while True:
        try:
            data = os.read(fd, 64)
        except InterruptedError:
            continue
        except OSError:
            return
        if not data:
            return
        for signum in data:
            if signum in SIGNALS and _deferred is None:
                exit_now(signum)


def install() -> bool:
    """Make SIGINT and SIGTERM end the process at once (see the module text). Only from the
    main thread; returns whether the handlers are installed."""
    global _installed
    if _installed:
        return True
    if threading.current_thread() is not threading.main_thread():
        return False
    read_fd, write_fd = os.pipe()
    os.set_blocking(write_fd, False)
    for sig in SIGNALS:
        signal.signal(sig, _handler)
    signal.set_wakeup_fd(write_fd, warn_on_full_buffer=False)
    threading.Thread(target=_watch, args=(read_fd,), name="impactfv-signals",
                     daemon=True).start()
    _installed = True
    return True


def defer(callback):
    """From now on a signal calls ``callback(signum)`` (in the main thread) instead."""
    global _deferred
    _deferred = callback


def undefer():
    global _deferred
    _deferred = None


def remove_on_exit(path: str):
    """Remove ``path`` if a signal ends the process at once (a lock file)."""
    _on_exit[str(path)] = None


def keep_on_exit(path: str):
    _on_exit.pop(str(path), None)
