"""Figures of the 3D validation (docs/validation.md, "Three dimensions"):

    python docs/figures/make_3d_figures.py [twist] [bars]

twist: the twisting column (impactfv.validation.twisting_column) on 4 and 8 cells across,
       its energy history and the deformed column at four instants (twisting_column.png);
bars:  the seed paper's bars in 3D (examples/bars_impact_3d.toml) against the plane-strain
       example at 100 us: pressure on the mid-plane z = 3.2 mm (bars_impact_3d.png).
Measured figures are written to figures_3d.json beside the pictures.
"""

from __future__ import annotations

import json
import sys
import tomllib
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

from impactfv import load_case, run  # noqa: E402
from impactfv.mesh.edges import boundary_facets  # noqa: E402
from impactfv.validation.twisting_column import case_dict  # noqa: E402

HERE = Path(__file__).resolve().parent
EXAMPLES = HERE.parents[1] / "examples"
OUT = HERE / "figures_3d.json"
plt.rcParams.update({"font.size": 11})


def _store(key, value):
    data = json.loads(OUT.read_text()) if OUT.exists() else {}
    data[key] = value
    OUT.write_text(json.dumps(data, indent=1) + "\n")


def twisting_column(end_time=0.5):
    frames = {}
    curves = {}
    figures = {}
    for n in (4, 8):
        case = case_dict(n, end_time=end_time, output_interval=end_time / 4)
        result = run(load_case(case), progress=False)
        h = result.history
        E = h["total_energy"]
        rise = float(np.max(E - np.minimum.accumulate(E)) / E[0])
        curves[n] = (h["time"], E / E[0])
        body = result.bodies["column"]
        figures[n] = {"nodes": int(result.summary["nodes"]), "steps": int(result.summary["steps"]),
                      "energy_end_over_start": float(E[-1] / E[0]),
                      "largest_rise_over_E0": rise,
                      "J_min": float(body["J"].min()), "J_max": float(body["J"].max()),
                      "wall_s": float(result.summary["wall_time_s"])}
        if n == 8:
            # snapshots: rerun to each instant
            for t in (0.02, 0.05, 0.1, 0.2):
                snap = run(load_case(case_dict(n, end_time=t)), progress=False)
                frames[t] = snap.bodies["column"]
    _store("twisting_column", {str(k): v for k, v in figures.items()})

    fig = plt.figure(figsize=(12, 9))
    ax = fig.add_subplot(2, 1, 1)
    for n, (t, e) in curves.items():
        ax.plot(1e3 * t, e, label=f"{n} cells across ({figures[n]['nodes']} nodes)")
    ax.set_xlabel("time (ms)")
    ax.set_ylabel("total energy / initial energy")
    ax.set_ylim(0, 1.05)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right")
    ax.set_title("twisting column, rubber 1 x 6 x 1 m, base clamped: the energy never rises; "
                 "upwind dissipation falls with h", fontsize=11)
    pmax = max(np.abs(body["pressure"]).max() for body in frames.values()) / 1e6
    for k, (t, body) in enumerate(frames.items()):
        a3 = fig.add_subplot(2, len(frames), len(frames) + 1 + k, projection="3d")
        faces = boundary_facets(body["tetrahedra"], 3)
        poly = body["points"][faces]
        p = body["pressure"][faces].mean(axis=1) / 1e6
        coll = Poly3DCollection(poly, array=p, cmap="coolwarm", edgecolor="k", linewidth=0.05)
        coll.set_clim(-pmax, pmax)
        a3.add_collection3d(coll)
        a3.set_xlim(-1.5, 1.5)
        a3.set_ylim(-1.5, 1.5)
        a3.set_zlim(0, 6)
        a3.set_box_aspect((1, 1, 2))
        # the column's axis (y) drawn upright
        coll.set_verts([np.column_stack([q[:, 0], q[:, 2], q[:, 1]]) for q in poly])
        a3.view_init(elev=20, azim=-60)
        a3.set_axis_off()
        a3.set_title(f"t = {1e3 * t:.0f} ms")
    cb = fig.colorbar(coll, ax=fig.axes[1:], shrink=0.7, location="right", pad=0.02)
    cb.set_label("pressure (MPa)")
    fig.savefig(HERE / "twisting_column.png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return figures


def mid_plane(body, z):
    """Current positions (x, y) and pressure of the nodes of the reference plane z."""
    X = body["reference_points"]
    keep = np.abs(X[:, 2] - z) < 1e-9
    return body["points"][keep, 0], body["points"][keep, 1], body["pressure"][keep]


def bars():
    out = {}
    data3 = tomllib.loads((EXAMPLES / "bars_impact_3d.toml").read_text())
    data2 = tomllib.loads((EXAMPLES / "bars_impact.toml").read_text())
    r3 = run(load_case(data3, base_dir=EXAMPLES), progress=False)
    r2 = run(load_case(data2, base_dir=EXAMPLES), progress=False)
    fig, axes = plt.subplots(2, 1, figsize=(11, 4.2), sharex=True)
    levels = np.linspace(-150, 250, 17)
    for ax, (label, result) in zip(axes, (("3D, mid-plane z = 3.2 mm", r3),
                                          ("plane strain", r2))):
        for name, body in result.bodies.items():
            if body["reference_points"].shape[1] == 3:
                x, y, p = mid_plane(body, 3.2e-3)
            else:
                x, y = body["points"].T
                p = body["pressure"]
            tc = ax.tricontourf(1e3 * x, 1e3 * y, p / 1e6, levels=levels, cmap="viridis",
                                extend="both")
        ax.set_aspect("equal")
        ax.set_ylabel("y (mm)")
        ax.set_title(f"{label}: pressure at 100 us (deformed)", fontsize=11)
        out[label] = {"pressure_max_MPa": float(max(b["pressure"].max()
                                                    for b in result.bodies.values()) / 1e6),
                      "nodes": int(result.summary["nodes"]),
                      "steps": int(result.summary["steps"]),
                      "wall_s": float(result.summary["wall_time_s"]),
                      "energy_end_over_start": float(result.history["total_energy"][-1]
                                                     / result.history["total_energy"][0])}
    axes[-1].set_xlabel("x (mm)")
    cb = fig.colorbar(tc, ax=axes, shrink=0.8)
    cb.set_label("pressure (MPa)")
    fig.savefig(HERE / "bars_impact_3d.png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    _store("bars_impact_3d", out)
    return out


if __name__ == "__main__":
    which = set(sys.argv[1:]) or {"twist", "bars"}
    if "twist" in which:
        print(json.dumps(twisting_column(), indent=1))
    if "bars" in which:
        print(json.dumps(bars(), indent=1))
