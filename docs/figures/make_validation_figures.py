"""Regenerate the validation figures and tables of docs/validation.md.

    python docs/figures/make_validation_figures.py   (a few minutes on 2 cores)
"""

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from impactfv import load_case, run  # noqa: E402
from impactfv.materials import Material  # noqa: E402
from impactfv.validation.bars import SEED_MATERIAL, bar_on_wall, pulse, two_bars  # noqa: E402
from impactfv.validation.standing_wave import case_dict, errors  # noqa: E402

HERE = Path(__file__).parent
out = {}

# -- convergence on the standing wave
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

# -- bar impacts against the 1D analytic solution
M = Material.from_entry(SEED_MATERIAL)
L, W, v0 = 0.01, 0.001, 50.0
ref = W * M.p_impedance * v0
fig, ax = plt.subplots(figsize=(7, 3.6))
bars = {}
for label, case in (("two bars, matching 100x10", two_bars(divisions=(100, 10))),
                    ("two bars, non-matching 100x10 / 80x13",
                     two_bars(divisions=(100, 10), divisions_right=(80, 13))),
                    ("bar on rigid wall, 100x10", bar_on_wall(divisions=(100, 10)))):
    result = run(load_case(case))
    h = result.history
    t0, t1, plateau = pulse(h, reference=ref)
    gap = np.nanmin(h["contact0_gap"])
    E = h["total_energy"]
    bars[label] = {"plateau_over_analytic": plateau / ref,
                   "duration_over_analytic": (t1 - t0) / (2 * L / M.p_wave_speed),
                   "min_gap_over_h": gap / (L / 100), "energy_end_over_start": E[-1] / E[0],
                   "wall_time_s": result.summary["wall_time_s"], "steps": result.summary["steps"]}
    ax.plot(h["time"] * 1e6, -h["contact0_fx"] / ref, label=label)
    print(label, bars[label], flush=True)
ti = 4e-4 / (2 * v0)
ax.plot(np.array([0, ti, ti, ti + 2 * L / M.p_wave_speed, ti + 2 * L / M.p_wave_speed, 25e-6])
        * 1e6, [0, 0, 1, 1, 0, 0], "k--", lw=1, label="1D analytic (two bars)")
ax.set_xlabel("time (us)")
ax.set_ylabel("contact force / (W rho c_p v0)")
ax.legend(fontsize=7)
ax.grid(alpha=0.3)
fig.tight_layout()
fig.savefig(HERE / "bar_impact_force.png", dpi=120)
out["bars"] = bars
(HERE / "validation_figures.json").write_text(json.dumps(out, indent=1))
