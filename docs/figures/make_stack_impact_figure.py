"""The disc of examples/stack_impact.toml striking the stack: pressure at five instants, and
each body's mean velocity along the floor against time.

    python docs/figures/make_stack_impact_figure.py   # writes docs/figures/stack_impact.png
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
CASE = HERE.parents[1] / "examples" / "stack_impact.toml"
TIMES = (20e-6, 60e-6, 100e-6, 200e-6, 400e-6)


def main():
    solver = FVStepper(load_case(CASE))
    m = solver.disc
    snapshots, t = [], 0.0
    times = [0.0]
    velocities = [[solver.v[b.start:b.stop, 0].mean() for b in m.bodies]]
    for target in TIMES:
        while t < target * (1 - 1e-12):
            dt = min(solver.stable_dt(), target - t)
            solver.step(dt)
            t += dt
            times.append(t)
            velocities.append([solver.v[b.start:b.stop, 0].mean() for b in m.bodies])
        p = solver.point_data()["pressure"]
        snapshots.append((t, solver.x.copy(), p / 1e6))
    vmax = 0.5 * max(np.abs(s[2]).max() for s in snapshots)
    velocities = np.array(velocities)
    with plt.rc_context(FONT):
        fig = plt.figure(figsize=(16, 4.6))
        grid = fig.add_gridspec(1, len(TIMES) + 1, width_ratios=[1] * len(TIMES) + [1.3],
                                wspace=0.25)
        for k, (t, x, p) in enumerate(snapshots):
            ax = fig.add_subplot(grid[0, k])
            for b in m.bodies:
                tri = Triangulation(x[:, 0] * 1e3, x[:, 1] * 1e3, b.cells)
                im = ax.tripcolor(tri, p, shading="gouraud", cmap="RdBu_r", vmin=-vmax,
                                  vmax=vmax)
            ax.axhline(0.0, color="k", lw=2)
            ax.set_title(f"t = {t * 1e6:.0f} \u00b5s")
            ax.set_aspect("equal")
            ax.set_xlim(-1, 22)
            ax.set_ylim(-0.5, 17)
            ax.set_xlabel("x (mm)")
            if k == 0:
                ax.set_ylabel("y (mm)")
            else:
                ax.set_yticklabels([])
        fig.colorbar(im, ax=list(fig.axes), label="pressure (MPa), compression positive",
                     shrink=0.5, pad=0.2, location="bottom", aspect=40)
        ax = fig.add_subplot(grid[0, -1])
        for j, b in enumerate(m.bodies):
            ax.plot(np.array(times) * 1e6, velocities[:, j], label=b.name)
        ax.set_xlabel("t (\u00b5s)")
        ax.set_ylabel("mean x-velocity (m/s)")
        ax.legend(frameon=False)
        ax.yaxis.set_label_position("right")
        ax.yaxis.tick_right()
        fig.savefig(HERE / "stack_impact.png", dpi=110, bbox_inches="tight")
        plt.close(fig)


if __name__ == "__main__":
    main()
