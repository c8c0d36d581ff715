"""Mesh-refinement studies of contact (docs/validation.md, "Refinement studies").

    python benchmarks/bench_refinement.py                   # both studies, full mesh lists
    python benchmarks/bench_refinement.py --study seed --h 0.4,0.2,0.1
    python benchmarks/bench_refinement.py --figures docs/figures

* seed: the seed paper's bars (32.4 x 6.4 mm copper, free sides, 2 x 50 m/s, slip) on
  h = 0.4, 0.2, 0.1, 0.05 mm (2.8k to 167k nodes). Prints, per mesh, the steps, nodes and
  wall time, and between successive meshes the L1 difference of the contact force history
  (first 20 us of contact, relative to p_ref x width) and of the pressure along the axis 20 us
  after the touch (relative to p_ref = rho c_p v0 = 664 MPa), with the observed orders.
* block: a steel block on a clamped aluminium slab (40, -100) m/s, slip, n = 20..160 cells
  across the block: the RMS grid-scale pressure near the contact face and its order.

The full seed study takes about 6 minutes on one core (the 0.05 mm mesh dominates).
See impactfv.validation.refinement for the definitions.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

WIDTH = 6.4e-3      # the seed bars' width (m): the contact force per unit thickness scale


def seed_figure(out, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.4))
    p_ref = out["p_ref"]
    for h, force, p in zip(out["h"], out["force"], out["axis_p"]):
        label = f"h = {h * 1e3:g} mm"
        a.plot(out["times"] * 1e6, force / (p_ref * WIDTH), label=label, lw=1.2)
        b.plot(np.asarray(out["axis_x"]) * 1e3, p / p_ref, label=label, lw=1.2)
    a.axhline(1.0, color="k", lw=0.6, ls=":")
    a.set_xlabel("time after first touch (us)")
    a.set_ylabel("contact force / (rho c_p v0 x width)")
    a.set_title("contact force history")
    b.axhline(1.0, color="k", lw=0.6, ls=":")
    b.set_xlabel("reference x along the left bar's axis (mm); contact face at right")
    b.set_ylabel("pressure / rho c_p v0")
    b.set_title("pressure on the axis 20 us after the touch (paper's 100 us)")
    for ax in (a, b):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def block_figure(out, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    k = len(out["n"])
    fig, axes = plt.subplots(k, 1, figsize=(8, 2.4 * k), sharex=True)
    for ax, n, bodies in zip(axes, out["n"], out["bodies"]):
        for f in bodies.values():
            x = f["points"] * 1e3
            tc = ax.tripcolor(x[:, 0], x[:, 1], f["triangles"], f["pressure"] / 1e6,
                              shading="gouraud", vmin=-200, vmax=1800, cmap="viridis")
        ax.set_aspect("equal")
        ax.set_xlim(-3.0, 3.0)
        ax.set_ylim(-1.2, 1.2)
        ax.set_title(f"n = {n} ({4.0 / n:g} mm cells): pressure at 1 us", fontsize=9)
    axes[-1].set_xlabel("x (mm)")
    fig.colorbar(tc, ax=list(axes), label="pressure (MPa)")
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--study", choices=("seed", "block", "both"), default="both")
    parser.add_argument("--h", default="0.4,0.2,0.1,0.05", help="seed meshes, mm")
    parser.add_argument("--n", default="20,40,80,160", help="block meshes, cells across")
    parser.add_argument("--figures", default=None, help="folder for the PNG figures")
    args = parser.parse_args(argv)
    from impactfv.validation.refinement import block_on_slab_study, seed_bars_study

    start = time.perf_counter()

    def seed_row(h, out):
        print(f"  h = {h * 1e3:5.3f} mm  nodes {out['nodes'][-1]:7d}  steps {out['steps'][-1]:5d}"
              f"  E/E0 {out['energy_ratio'][-1]:.4f}"
              f"  peak force / (rho c_p v0 width) {out['force'][-1].max() / (out['p_ref'] * WIDTH):.3f}"
              f"  wall {time.perf_counter() - start:7.1f} s",
              flush=True)

    if args.study in ("seed", "both"):
        print("seed bars (slip, free sides): contact force and axis pressure")
        hs = [float(v) * 1e-3 for v in args.h.split(",")]
        out = seed_bars_study(hs, report=seed_row)
        print("| meshes (mm) | force diff | order | axis pressure diff | order |")
        print("|---|---|---|---|---|")
        for i in range(len(hs) - 1):
            fo = f"{out['force_order'][i - 1]:.2f}" if i else ""
            ao = f"{out['axis_order'][i - 1]:.2f}" if i else ""
            print(f"| {hs[i] * 1e3:g} -> {hs[i + 1] * 1e3:g} | {out['force_diff'][i]:.2e} | {fo} "
                  f"| {out['axis_diff'][i]:.2e} | {ao} |")
        if args.figures:
            path = Path(args.figures) / "seed_bars_convergence.png"
            seed_figure(out, path)
            print("wrote", path)
    if args.study in ("block", "both"):
        print("steel block on aluminium slab: grid-scale pressure near the contact face")
        ns = [int(v) for v in args.n.split(",")]
        out = block_on_slab_study(ns, report=lambda n, o: print(
            f"  n = {n:4d}  grid-scale RMS / p_ref {o['grid_scale'][-1]:.2e}"
            f"  wall {time.perf_counter() - start:7.1f} s", flush=True))
        print("observed orders:", ", ".join(f"{v:.2f}" for v in out["order"]))
        if args.figures:
            path = Path(args.figures) / "block_on_slab_refinement.png"
            block_figure(out, path)
            print("wrote", path)


if __name__ == "__main__":
    main()
