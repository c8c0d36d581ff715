"""The progress bar of long runs (on standard error, when it is a terminal)."""

from __future__ import annotations

import sys
import time


def _clock(seconds: float) -> str:
    if seconds != seconds or seconds == float("inf"):
        return "?"
    seconds = int(seconds)
    h, rest = divmod(seconds, 3600)
    return (f"{h}:" if h else "") + f"{rest // 60:02d}:{rest % 60:02d}"


class ProgressBar:
    """``simulated time  43%|#####      | 4.300e-05/1.000e-04 s [00:06<00:08]`` on one line,
    redrawn at most ten times a second. ``n`` is the simulated time shown."""

    def __init__(self, total: float, stream=None, width: int = 30, interval: float = 0.1):
        self.total = float(total)
        self.n = 0.0
        self.stream = stream if stream is not None else sys.stderr
        self.width = width
        self.interval = interval
        self.start = time.monotonic()
        self.drawn = -1.0

    def update(self, dt: float):
        self.n += dt
        now = time.monotonic()
        if now - self.drawn >= self.interval:
            self.drawn = now
            self._draw(now)

    def _draw(self, now):
        frac = min(max(self.n / self.total, 0.0), 1.0) if self.total > 0 else 1.0
        elapsed = now - self.start
        remaining = elapsed * (1 - frac) / frac if frac > 0 else float("inf")
        bar = "#" * int(round(frac * self.width))
        self.stream.write(f"\rsimulated time {100 * frac:3.0f}%|{bar:<{self.width}}| "
                          f"{self.n:.3e}/{self.total:.3e} s "
                          f"[{_clock(elapsed)}<{_clock(remaining)}]")
        self.stream.flush()

    def close(self):
        self._draw(time.monotonic())
        self.stream.write("\n")
        self.stream.flush()


def progress_bar(progress: bool | None, end: float, stream=None):
    """A bar over simulated time, or None. ``progress=None``: only on a terminal."""
    if progress is None:
        progress = sys.stderr.isatty()
    if not progress:
        return None
    return ProgressBar(end, stream)
