"""SIGINT/SIGTERM during a run: remembered, so the loop can stop cleanly between two steps."""

from __future__ import annotations

import signal
import threading


class SignalFlag:
    def __init__(self, active: bool):
        self.signum = None
        self.previous = {}
        if active and threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self.previous[sig] = signal.signal(sig, self._handle)

    def _handle(self, signum, frame):
        self.signum = signum

    def restore(self):
        for sig, handler in self.previous.items():
            signal.signal(sig, handler)
        self.previous = {}
