"""The progress bar of long runs (on standard error, when it is a terminal)."""

from __future__ import annotations

import sys


def progress_bar(progress: bool | None, end: float):
    """A tqdm bar over simulated time, or None. ``progress=None``: only on a terminal."""
    if progress is None:
        progress = sys.stderr.isatty()
    if not progress:
        return None
    from tqdm import tqdm
    return tqdm(total=end, unit="s", unit_scale=True, desc="simulated time",
                bar_format="{l_bar}{bar}| {n:.3e}/{total:.3e} s [{elapsed}<{remaining}]")
