"""SIGINT/SIGTERM during a run: remembered, so the loop can stop cleanly between two steps.

Under the command line (impactfv.interrupts installed) a signal before the loop has taken
its first step ends the process at once (nothing to checkpoint yet, and numba compiles the
kernels in that first step); :meth:`SignalFlag.armed` hands the signals to the loop after
it. From Python (``run(..., handle_signals=True)``) the flag catches them from the start.
"""

from __future__ import annotations

import signal
import threading

from .. import interrupts


class SignalFlag:
    def __init__(self, active: bool):
        self.signum = None
        self.previous = {}
        self.deferred = False
        self.handed_over = False
        if not active or threading.current_thread() is not threading.main_thread():
            return
        if interrupts.installed():
            self.deferred = True        # armed() hands the signals over after a step
        else:
            for sig in (signal.SIGINT, signal.SIGTERM):
                self.previous[sig] = signal.signal(sig, self._handle)

    def _handle(self, signum, frame=None):
        self.signum = signum

    def armed(self):
        """The loop has taken a step: from now on a signal stops it after the current step."""
        if self.deferred:
            interrupts.defer(self._handle)
            self.deferred = False
            self.handed_over = True

    def restore(self):
        if self.handed_over:
            interrupts.undefer()
            self.handed_over = False
        for sig, handler in self.previous.items():
            signal.signal(sig, handler)
        self.previous = {}
