"""The progress bar of long runs (on standard error, when it is a terminal)."""

from __future__ import annotations

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
    redrawn at most ten times a second. ``n`` is the simulated time shown.

    ``note``: shown after the bar until the first update (what the run is waiting for
    before its first step). Bar and note fit in ``columns`` (default: the terminal's width),
    so that the line does not wrap and each redraw overwrites it. The time left is
    extrapolated from the steps after the first one, so the first step's one-off costs
    (numba's compilation on a fresh install) do not inflate it."""

    def __init__(self, total: float, stream=None, width: int = 30, interval: float = 0.1,
                 note: str = "", columns: int | None = None):
        self.total = float(total)
        self.n = 0.0
        self.stream = stream if stream is not None else sys.stderr
        self.interval = interval
        self.start = time.monotonic()
        self.drawn = -1.0
        self.first = None          # (time, n) at the first update
        self.longest = 0           # longest line drawn, overwritten with blanks
        self.columns = columns if columns else shutil.get_terminal_size().columns
        # the text around the bar takes 57 characters ("simulated time 100%|", "| 1.000e-04/
        # 1.000e-04 s [00:21<00:00]"): the bar gives way (down to 10) to fit the line and
        # the note in the terminal
        room = self.columns - 1 - 57 - (len(note) + 1 if note else 0)
        self.width = max(10, min(width, room))
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
        bar = "#" * int(round(frac * self.width))
        line = (f"simulated time {100 * frac:3.0f}%|{bar:<{self.width}}| "
                f"{self.n:.3e}/{self.total:.3e} s "
                f"[{_clock(elapsed)}<{_clock(self._remaining(now, frac))}]")
        room = self.columns - 1 - len(line) - 1
        if note and len(note) > room:
            note = note.split(" (")[0] + "..."       # "compiling (first run only)"
        if note and len(note) <= room:
            line += " " + note
        self.stream.write("\r" + line + " " * max(self.longest - len(line), 0))
        self.longest = max(self.longest, len(line))
        self.stream.flush()

    def close(self):
        self._draw(time.monotonic())
        self.stream.write("\n")
        self.stream.flush()


#: the progress bar's note until the first step is done
FIRST_STEP_NOTE = "compiling (first run only)"


def progress_bar(progress: bool | None, end: float, stream=None, note: str = "",
                 columns: int | None = None):
    """A bar over simulated time, or None. ``progress=None``: only on a terminal."""
    if progress is None:
        progress = sys.stderr.isatty()
    if not progress:
        return None
    return ProgressBar(end, stream, note=note, columns=columns)
