"""Every example in examples/ loads and runs (shortened to a few dozen steps)."""

import tomllib
from pathlib import Path

import numpy as np
import pytest

from impactfv import load_case, run

EXAMPLES = sorted((Path(__file__).resolve().parents[1] / "examples").glob("*.toml"))


def test_there_are_examples():
    assert len(EXAMPLES) >= 2


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_example_runs(path):
    data = tomllib.loads(path.read_text())
    data["run"]["max_steps"] = 30
    result = run(load_case(data, base_dir=path.parent))
    status, steps = result.summary["status"], result.summary["steps"]
    assert (status, steps) == ("stopped at max_steps", 30) or \
        (status == "completed" and steps < 30 and
         result.history["time"][-1] == pytest.approx(data["run"]["end_time"], rel=1e-12))
    E = result.history["total_energy"]
    assert np.all(np.isfinite(E)) and E[-1] <= E[0] * (1 + 1e-12)
