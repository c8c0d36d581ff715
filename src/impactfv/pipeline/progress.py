"""The progress bar of long runs (on standard error, when it is a terminal)."""

from __future__ import annotations

import io
import os
import shutil
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
    redrawn at most ten times a second. ``n`` is the simulated time shown; ``start_at`` the
    simulated time a continued run starts from.

    ``note``: shown after the bar until the first update (what the run is waiting for
    before its first step). The line fits in ``columns`` (default: the width of the
    terminal the bar is drawn on): the bar narrows (to nothing on a very narrow terminal),
    the note shortens or goes, so that the line does not wrap and each redraw overwrites
    it. The time left is extrapolated from the steps after the first one, so the first
    step's one-off costs (numba's compilation on a fresh install) do not inflate it."""

    def __init__(self, total: float, stream=None, width: int = 30, interval: float = 0.1,
                 note: str = "", columns: int | None = None, start_at: float = 0.0):
        self.total = float(total)
        self.n = float(start_at)
        self.stream = stream if stream is not None else sys.stderr
        self.width = width
        self.interval = interval
        self.start = time.monotonic()
        self.drawn = -1.0
        self.first = None          # (time, n) at the first update
        self.longest = 0           # longest line drawn, overwritten with blanks
        self.columns = columns if columns else _terminal_columns(self.stream)
        if note:
            self.drawn = self.start
            self._draw(self.start, note)

    def update(self, dt: float):
        self.n += dt
        now = time.monotonic()
        if self.first is None:
            self.first = (now, self.n)
        if now - self.drawn >= self.interval:
            self.drawn = now
            self._draw(now)

    def _remaining(self, now, frac):
        if frac >= 1.0:
            return 0.0
        if self.first is None or self.n <= self.first[1]:
            return float("inf")
        rate = (self.n - self.first[1]) / max(now - self.first[0], 1e-9)
        return (self.total - self.n) / rate

    def _draw(self, now, note=""):
        frac = min(max(self.n / self.total, 0.0), 1.0) if self.total > 0 else 1.0
        elapsed = now - self.start
        head = f"simulated time {100 * frac:3.0f}%"
        tail = (f" {self.n:.3e}/{self.total:.3e} s "
                f"[{_clock(elapsed)}<{_clock(self._remaining(now, frac))}]")
        limit = self.columns - 1
        # the first of: the note in full beside a bar of 10 or more, shortened ("loading
        # the kernels...") beside such a bar, shortened in place of the bar, no note; the bar
        # takes what the text leaves of the line, up to its width, and goes below 5
        free = limit - len(head) - len(tail) - 2         # for the bar between its "|"s
        shown = ""
        if note:
            short = note.split(" (")[0] + "..."
            for text, least in ((note, 10), (short, 10), (short, -2)):
                if free - len(text) - 1 >= least:
                    shown = text
                    free -= len(text) + 1
                    break
        width = min(self.width, free)
        if width >= 5:
            head += "|" + f"{'#' * int(round(frac * width)):<{width}}" + "|"
        line = (head + tail + (" " + shown if shown else ""))[:limit]
        self.stream.write("\r" + line + " " * max(min(self.longest, limit) - len(line), 0))
        self.longest = max(self.longest, len(line))
        self.stream.flush()

    def close(self):
        self._draw(time.monotonic())
        self.stream.write("\n")
        self.stream.flush()


def _terminal_columns(stream) -> int:
    """The width of the terminal ``stream`` writes to (the bar goes to standard error, whose
    terminal may differ from standard output's), else shutil's guess."""
    try:
        columns = os.get_terminal_size(stream.fileno()).columns
    except (AttributeError, OSError, ValueError, io.UnsupportedOperation):
        columns = 0
    # a pseudo-terminal may report 0 columns: shutil then reads COLUMNS or assumes 80
    return columns if columns > 0 else shutil.get_terminal_size().columns


#: the progress bar's note until the first step is done: numba compiles the kernels on the
#: first run after an install and loads them from its cache afterwards (a few seconds)
FIRST_STEP_NOTE = "loading the kernels (compiled on the first run)"


def progress_bar(progress: bool | None, end: float, stream=None, note: str = "",
                 columns: int | None = None, start_at: float = 0.0):
    """A bar over simulated time, or None. ``progress=None``: only on a terminal."""
    if progress is None:
        progress = sys.stderr.isatty()
    if not progress:
        return None
    return ProgressBar(end, stream, note=note, columns=columns, start_at=start_at)
