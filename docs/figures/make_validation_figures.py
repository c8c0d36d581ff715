"""Regenerate the validation figures and tables of docs/validation.md.

    python docs/figures/make_validation_figures.py            (a few minutes on 2 cores)
    python docs/figures/make_validation_figures.py bars       (the bar-impact figure only,
                                                               about 15 s)
    python docs/figures/make_validation_figures.py standing_wave

Each part updates its own entry of validation_figures.json.
"""

import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from impactfv import load_case, run  # noqa: E402
from impactfv.physics.materials import Material  # noqa: E402
from impactfv.plot import FONT  # noqa: E402
from impactfv.validation.bars import SEED_MATERIAL, bar_on_wall, pulse, two_bars  # noqa: E402
from impactfv.validation.standing_wave import case_dict, errors  # noqa: E402

HERE = Path(__file__).parent


def standing_wave(out):
    """Convergence on the standing wave."""
    rows = {}
    for label, order, limiter in (("order 2, no limiter", 2, "none"), ("order 1", 1, "none"),
                                  ("order 2, Barth-Jespersen", 2, "barth_jespersen")):
        rows[label] = []
        for n in (8, 16, 32, 64, 128, 256):
            d = case_dict(n, order=order, limiter=limiter)
            ev, es = errors(run(load_case(d)), d)
            rows[label].append((n, ev, es))
            print(label, n, ev, es, flush=True)
    out["standing_wave"] = rows
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.6))
    for label, r in rows.items():
        h = [1 / n for n, _, _ in r]
        ax[0].loglog(h, [e for _, e, _ in r], "o-", label=label)
        ax[1].loglog(h, [e for _, _, e in r], "o-", label=label)
    for a, name in zip(ax, ("velocity", "stress")):
        hh = np.array([1 / 8, 1 / 256])
        a.loglog(hh, 0.5 * (hh / hh[0]) ** 2 * a.get_lines()[0].get_ydata()[0], "k--", lw=0.8,
                 label="slope 2")
        a.loglog(hh, (hh / hh[0]) * a.get_lines()[1].get_ydata()[0], "k:", lw=0.8, label="slope 1")
        a.set_xlabel("h (m)")
        a.set_ylabel(f"relative L2 error of {name}")
        a.grid(True, which="both", alpha=0.3)
    ax[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(HERE / "standing_wave_convergence.png", dpi=120)



def bars(out):
    """Bar impacts against the 1D analytic solution: the whole pulse, and close-ups of its
    rise and its end, where the three cases are told apart."""
    M = Material.from_entry(SEED_MATERIAL)
    L, W, v0 = 0.01, 0.001, 50.0
    ref = W * M.p_impedance * v0
    results = {}
    cases = (("two bars, matching 100x10", two_bars(divisions=(100, 10))),
             ("two bars, non-matching 100x10 / 80x13",
              two_bars(divisions=(100, 10), divisions_right=(80, 13))),
             ("bar on rigid wall, 100x10", bar_on_wall(divisions=(100, 10))))
    table = {}
    for label, case in cases:
        result = run(load_case(case))
        h = result.history
        t0, t1, plateau = pulse(h, reference=ref)
        gap = np.nanmin(h["contact0_gap"])
        E = h["total_energy"]
        table[label] = {"plateau_over_analytic": plateau / ref,
                        "duration_over_analytic": (t1 - t0) / (2 * L / M.p_wave_speed),
                        "min_gap_over_h": gap / (L / 100),
                        "energy_end_over_start": E[-1] / E[0],
                        "wall_time_s": result.summary["wall_time_s"],
                        "steps": result.summary["steps"]}
        results[label] = h
        print(label, table[label], flush=True)
    ti = 4e-4 / (2 * v0)
    te = ti + 2 * L / M.p_wave_speed
    styles = [dict(color="C0", lw=3.0, ls="-"), dict(color="C1", lw=2.0, ls="--"),
              dict(color="C2", lw=2.0, ls=":")]
    with plt.rc_context(FONT):
        fig = plt.figure(figsize=(11, 6.4), constrained_layout=True)
        grid = fig.add_gridspec(2, 2, height_ratios=(1.25, 1))
        whole = fig.add_subplot(grid[0, :])
        rise = fig.add_subplot(grid[1, 0])
        fall = fig.add_subplot(grid[1, 1])
        for ax, (lo, hi) in ((whole, (0, 25)), (rise, (ti * 1e6 - 0.4, ti * 1e6 + 1.2)),
                             (fall, (te * 1e6 - 1.2, te * 1e6 + 0.4))):
            for (label, h), style in zip(results.items(), styles):
                ax.plot(h["time"] * 1e6, -h["contact0_fx"] / ref, label=label, **style)
            ax.plot(np.array([0, ti, ti, te, te, 25e-6]) * 1e6, [0, 0, 1, 1, 0, 0], "k-",
                    lw=0.9, label="1D analytic (all three)")
            ax.set_xlim(lo, hi)
            ax.grid(alpha=0.3)
            ax.set_xlabel("time (\u00b5s)")
        whole.set_ylabel("contact force / (W rho c_p v0)")
        rise.set_ylabel("contact force / (W rho c_p v0)")
        rise.set_title("close-up: the touch")
        fall.set_title("close-up: the separation")
        for ax in (rise, fall):
            ax.set_ylim(-0.05, 1.12)
        # inside the pulse, where no curve runs
        whole.legend(loc="center", frameon=True)
        fig.savefig(HERE / "bar_impact_force.png", dpi=120)
        plt.close(fig)
    out["bars"] = table


def main(parts):
    path = HERE / "validation_figures.json"
    out = json.loads(path.read_text()) if path.is_file() else {}
    for part in parts or ("standing_wave", "bars"):
        {"standing_wave": standing_wave, "bars": bars}[part](out)
    path.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main(sys.argv[1:])
