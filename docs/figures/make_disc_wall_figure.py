"""The disc of examples/disc_wall.toml bouncing off the wall: pressure at six instants.

    python docs/figures/make_disc_wall_figure.py      # writes docs/figures/disc_wall.png
"""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.tri import Triangulation  # noqa: E402

from impactfv import load_case  # noqa: E402
from impactfv.plot import FONT  # noqa: E402
from impactfv.scheme.stepper import FVStepper  # noqa: E402

HERE = Path(__file__).resolve().parent
CASE = HERE.parents[1] / "examples" / "disc_wall.toml"
TIMES = (10e-6, 30e-6, 50e-6, 70e-6, 90e-6, 130e-6)


def main():
    solver = FVStepper(load_case(CASE))
    m = solver.disc
    cells = m.bodies[0].cells
    snapshots, t = [], 0.0
    for target in TIMES:
        while t < target:
            dt = min(solver.stable_dt(), target - t)
            solver.step(dt)
            t += dt
        p = solver.point_data()["pressure"]
        snapshots.append((t, solver.x.copy(), p / 1e6))
    vmax = max(np.abs(s[2]).max() for s in snapshots)
    with plt.rc_context(FONT):
        fig, axes = plt.subplots(1, len(TIMES), figsize=(15, 3.4), sharey=True)
        for ax, (t, x, p) in zip(axes, snapshots):
            tri = Triangulation(x[:, 0] * 1e3, x[:, 1] * 1e3, cells)
            im = ax.tripcolor(tri, p, shading="gouraud", cmap="RdBu_r", vmin=-vmax,
                              vmax=vmax)
            ax.axhline(0.0, color="k", lw=2)
            ax.set_title(f"t = {t * 1e6:.0f} \u00b5s")
            ax.set_aspect("equal")
            ax.set_xlabel("x (mm)")
        axes[0].set_ylabel("y (mm)")
        fig.colorbar(im, ax=axes, label="pressure (MPa),\ncompression positive", shrink=0.8)
        fig.savefig(HERE / "disc_wall.png", dpi=110, bbox_inches="tight")
        plt.close(fig)


if __name__ == "__main__":
    main()
