"""What a run returns, and how an interrupted run ends."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import Interrupted  # noqa: F401  (defined with the other exit codes)


@dataclass
class RunResult:
    """``history`` (column -> values per step), ``bodies`` (name -> point fields and mesh at
    the end), ``summary`` (as in summary.json), the output folder and its snapshots."""

    history: dict[str, np.ndarray]
    bodies: dict[str, dict[str, np.ndarray]]
    summary: dict
    output_dir: Path | None = None
    snapshots: list = field(default_factory=list)
