"""Regenerate the figures and table of docs/comparison.md (about 1 to 2 minutes).

    python docs/figures/make_comparison_figures.py

Runs ``impactfv compare examples/bars_impact.toml`` into a temporary folder and copies its
pressure_contours.png, histories.png and comparison.csv here as bars_impact_*.
"""

import shutil
import tempfile
from pathlib import Path

from impactfv import load_case
from impactfv.compare import compare_case

HERE = Path(__file__).resolve().parent
CASE = HERE.parents[1] / "examples" / "bars_impact.toml"


def main():
    with tempfile.TemporaryDirectory() as tmp:
        compare_case(load_case(CASE), tmp)
        for name, target in (("pressure_contours.png", "bars_impact_pressure_contours.png"),
                             ("histories.png", "bars_impact_histories.png"),
                             ("comparison.csv", "bars_impact_comparison.csv")):
            shutil.copyfile(Path(tmp) / name, HERE / target)


if __name__ == "__main__":
    main()
