"""``impactfv compare``: the FV scheme against the two explicit FE baselines on one case.

:func:`compare_case` runs ``fv``, ``fem-t3`` and ``fem-q4md`` on matching meshes (the same
rectangle grids: FV and T3 on the case's triangles, Q4MD on the quads of the same grid) and
writes, into the output folder (default ``results/<stem>_compare``):

* ``pressure_contours.png``: the nodal pressure at the final time on the deformed bodies, one
  panel per method, one shared colour scale (MPa);
* ``histories.png``: the contact force (compressive positive, per unit thickness) and the
  kinetic, strain and total (kinetic + strain) energies of the three methods;
* ``comparison.csv`` (also printed): one row per method with the metrics below;
* ``<method>/``: each run's own ``history.csv``, ``summary.json`` and ``fields.pvd``.

Metrics (``p_ref`` is the 1D acoustic contact pressure of the first contact,
``p_ref = v_close Z_a Z_b / (Z_a + Z_b)`` with ``Z = rho c_p`` and ``v_close`` the closing
speed of the two bodies' mean initial velocities along the line joining their centroids;
for two equal bodies ``p_ref = rho c_p v0`` with ``v0 = v_close / 2``):

* ``roughness``: median over the *loaded* nodes (``|p| > 1 % p_ref``) of
  ``|p_i - mean_j p_j| / p_ref``, the mean over the nodes j joined to i by a mesh edge
  (triangle edges for FV and T3, quad edges for Q4MD).  Nodes outside the loaded region are
  left out because there ``p = 0`` exactly and they would pull the median to zero whatever
  the quality of the loaded part.  FE nodal pressures are the reference-area-weighted
  averages of the element pressures (this averaging already smooths element checkerboards);
  FV pressures are the nodal values of the scheme.
* ``peak_pressure_MPa``: largest nodal pressure at the final time, and its ratio to p_ref;
* ``peak_contact_pressure_MPa``: largest contact force over the run (history, every step)
  divided by the reference length of the contact surface (below), and its ratio to p_ref:
  the mean pressure on the contact face, which equals p_ref in the first instants of a flat
  impact, before the release waves from the free corners arrive;
* ``plateau_pressure_MPa``: mean contact force over the middle 60 % of the contact phase
  (:func:`impactfv.validation.bars.pulse`) divided by the reference length of the contact
  surface (the shorter of the two bodies' extents across the contact direction);
* ``impulse_Ns_per_m``: the contact impulse (the time integral of the contact force on the
  first body, per unit thickness), i.e. the momentum the contact exchanged over the run;
* ``wall_time_s``, ``steps``;
* ``penetration_per_h``: the deepest penetration (``-min gap``, 0 if the gap never closes
  below 0) over the run divided by the shortest reference mesh edge;
* ``momentum_drift``: ``max_t |P(t) - P(0)|`` divided by ``sum_b m_b |v_b|`` (the momentum
  the bodies carry; the total is zero for a symmetric impact);
* ``energy_end_over_start``: (kinetic + strain) at the end over the start; for the FE
  methods also ``energy_with_contact_end_over_start`` with the contact work term added
  (``total_energy`` of the FE history).
"""

from __future__ import annotations

import csv
import time
from pathlib import Path

import numpy as np

from .case import Case, RunSettings, load_case
from .errors import InputError
from .mesh.edges import unique_edges

METHODS = ("fv", "fem-t3", "fem-q4md")
LABELS = {"fv": "FV (upwind vertex-centred)", "fem-t3": "FE T3 (linear triangles)",
          "fem-q4md": "FE Q4 mean dilatation"}
COLORS = {"fv": "C0", "fem-t3": "C3", "fem-q4md": "C2"}
COLUMNS = ("method", "nodes", "steps", "wall_time_s", "roughness", "peak_pressure_MPa",
           "peak_over_pref", "peak_contact_pressure_MPa", "peak_contact_over_pref",
           "plateau_pressure_MPa", "plateau_over_pref", "impulse_Ns_per_m", "penetration_per_h",
           "momentum_drift", "energy_end_over_start", "energy_with_contact_end_over_start")


# ----------------------------------------------------------------------------- cases

def method_case(case: Case, method: str, divisions=None) -> Case:
    """A copy of ``case`` run with ``method`` (and, optionally, every rectangle body meshed
    with ``divisions``), with a history row every step (the metrics integrate it)."""
    data = case.spec.model_dump(exclude_none=True, by_alias=True)
    data["run"]["method"] = method
    if method != "fv":
        # the FV scheme's own options (order, limiter, ...) are not the FE methods' to take
        for key in RunSettings.FV_ONLY:
            data["run"].pop(key, None)
    data.setdefault("output", {})["history_every"] = 1
    for body in data["body"]:
        if divisions is not None and body["mesh"].get("generator") == "rectangle":
            body["mesh"]["divisions"] = list(divisions)
    return load_case(data, base_dir=case.base_dir)


def reference_pressure(case: Case, k: int = 0) -> dict:
    """``p_ref`` of contact k (see the module docstring) and what it is made of."""
    if not case.contacts:
        raise InputError(f"{case.source}: compare needs a [[contact]] between two bodies")
    spec = case.contacts[k]
    if len(spec.bodies) != 2:
        raise InputError(f"{case.source}: compare needs a contact between two bodies")
    byname = {b.name: b for b in case.bodies}
    a, b = byname[spec.bodies[0]], byname[spec.bodies[1]]
    info = {}
    for key, body in (("a", a), ("b", b)):
        pts = body.mesh.points
        area = _areas(pts, body.mesh.cells)
        centre = np.array([np.sum(area * pts[body.mesh.cells][:, :, d].mean(axis=1))
                           for d in range(2)]) / area.sum()
        v = body.initial_velocity(pts).mean(axis=0)
        info[key] = (centre, v, body.material)
    d = info["b"][0] - info["a"][0]
    d /= np.linalg.norm(d)
    v_close = float(np.dot(info["a"][1] - info["b"][1], d))
    za, zb = info["a"][2].p_impedance, info["b"][2].p_impedance
    # bodies that do not approach each other at the start (at rest, pushed by their loads,
    # or moving apart) have no acoustic reference: the ratios to it are not given (NaN)
    p_ref = v_close * za * zb / (za + zb) if v_close > 0 else float("nan")
    # extent of each body across the contact direction: the width that carries the force
    t = np.array([-d[1], d[0]])
    widths = [float(np.ptp(body.mesh.points @ t)) for body in (a, b)]
    return {"p_ref": p_ref, "v_close": v_close, "v0": 0.5 * v_close, "direction": d,
            "width": min(widths), "Z": (za, zb), "bodies": (a.name, b.name)}


def _areas(pts, tri):
    p = pts[tri]
    return 0.5 * np.abs((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                        - (p[:, 2, 0] - p[:, 0, 0]) * (p[:, 1, 1] - p[:, 0, 1]))


def external_loads(case: Case) -> list[str]:
    """The boundary conditions through which a case exchanges momentum (prescribed velocity
    components: their supports push back) or energy (tractions, non-zero velocities), as
    'body[i] region r: what' texts; empty for free bodies."""
    out = []
    for i, body in enumerate(case.bodies):
        for bc in body.boundary:
            what = []
            if bc.velocity is not None:
                comps = [c for c, v in zip("xy", bc.velocity.components(2)) if v is not None]
                moving = any(v for v in bc.velocity.components(2) if v is not None)
                what.append(f"{'moving' if moving else 'held'} velocity "
                            f"{'/'.join(comps)}")
            if bc.traction is not None and any(bc.traction):
                what.append("traction")
            out.append(f"body {body.name!r} region {bc.region!r}: {', '.join(what)}")
    return out


# ----------------------------------------------------------------------------- metrics

def _cells(fields):
    return fields.get("cells", fields["triangles"])


def pressure_roughness(bodies: dict, p_ref: float, threshold: float = 0.01) -> float:
    """Median over loaded nodes of |p_i - mean of p over edge neighbours| / p_ref; NaN
    without a reference pressure."""
    if not p_ref > 0:
        return float("nan")
    values = []
    for f in bodies.values():
        p = np.asarray(f["pressure"], float)
        e = unique_edges(_cells(f))
        n = len(p)
        s = np.bincount(e[:, 0], p[e[:, 1]], n) + np.bincount(e[:, 1], p[e[:, 0]], n)
        c = np.bincount(e.ravel(), minlength=n)
        mean = s / np.maximum(c, 1)
        loaded = np.abs(p) > threshold * abs(p_ref)
        values.append(np.abs(p - mean)[loaded] / abs(p_ref))
    values = np.concatenate(values)
    return float(np.median(values)) if len(values) else 0.0


def min_edge_length(bodies: dict) -> float:
    h = np.inf
    for f in bodies.values():
        e = unique_edges(_cells(f))
        X = f["reference_points"]
        h = min(h, float(np.linalg.norm(X[e[:, 1]] - X[e[:, 0]], axis=1).min()))
    return h


def contact_force(history, ref, k=0):
    """Compressive-positive contact force (per unit thickness) on the first body."""
    d = ref["direction"]
    return -(history[f"contact{k}_fx"] * d[0] + history[f"contact{k}_fy"] * d[1])


def plateau_force(history, ref, k=0):
    """Mean compressive force over the middle 60 % of the contact phase (or nan)."""
    f = contact_force(history, ref, k)
    t = history["time"]
    on = np.flatnonzero(f > 0.02 * ref["p_ref"] * ref["width"])
    if len(on) == 0:
        return float("nan"), (float("nan"), float("nan"))
    t0, t1 = t[on[0]], t[on[-1]]
    mid = (t > t0 + 0.2 * (t1 - t0)) & (t < t1 - 0.2 * (t1 - t0))
    return float(np.mean(f[mid])), (float(t0), float(t1))


def _ratio(values, moving: bool) -> float:
    """values[-1] / values[0]; NaN when the bodies start at rest (their start energy is
    zero or round-off)."""
    return float(values[-1] / values[0]) if moving else float("nan")


def metrics(method, result, ref, case) -> dict:
    h = result.history
    bodies = result.bodies
    p_ref = ref["p_ref"]
    roughness = pressure_roughness(bodies, p_ref)
    peak = max(float(np.max(f["pressure"])) for f in bodies.values())
    plateau, (t0, t1) = plateau_force(h, ref)
    force = contact_force(h, ref)
    fmax = float(np.max(force))
    t = h["time"]
    impulse = float(np.sum(0.5 * (force[1:] + force[:-1]) * np.diff(t)))
    gaps = np.concatenate([h[k] for k in h if k.startswith("contact") and k.endswith("_gap")])
    gaps = gaps[np.isfinite(gaps)]
    pen = max(0.0, -float(gaps.min())) if len(gaps) else 0.0
    hmin = min_edge_length(bodies)
    scale = 0.0
    for body in case.bodies:
        pts, tri = body.mesh.points, body.mesh.cells
        mass = body.material.density * _areas(pts, tri).sum()
        scale += mass * float(np.linalg.norm(body.initial_velocity(pts).mean(axis=0)))
    P = np.column_stack([h["momentum_x"], h["momentum_y"]])
    drift = float(np.max(np.linalg.norm(P - P[0], axis=1))) / scale if scale > 0 else 0.0
    if external_loads(case):
        drift = float("nan")   # the supports and loads exchange momentum with the outside
    mech = h["kinetic_energy"] + h["strain_energy"]
    row = {
        "method": method, "nodes": int(result.summary["nodes"]),
        "steps": int(result.summary["steps"]),
        "wall_time_s": float(result.summary["wall_time_s"]),
        "roughness": roughness, "peak_pressure_MPa": peak / 1e6, "peak_over_pref": peak / p_ref,
        "peak_contact_pressure_MPa": fmax / ref["width"] / 1e6,
        "peak_contact_over_pref": fmax / ref["width"] / p_ref,
        "plateau_pressure_MPa": plateau / ref["width"] / 1e6,
        "plateau_over_pref": plateau / ref["width"] / p_ref,
        "impulse_Ns_per_m": impulse,
        "penetration_per_h": pen / hmin, "momentum_drift": drift,
        "energy_end_over_start": _ratio(mech, scale > 0),
        "energy_with_contact_end_over_start":
            _ratio(h["total_energy"], scale > 0) if method != "fv" else _ratio(mech, scale > 0),
        # not in the table: used by tests and plots
        "plateau_force": plateau, "contact_start": t0, "contact_end": t1, "h": hmin,
        "penetration": pen,
    }
    return row


# ----------------------------------------------------------------------------- figures

def _pressure_figure(results, ref, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.tri import Triangulation

    allp = np.concatenate([f["pressure"] for r in results.values() for f in r.bodies.values()])
    lo, hi = np.percentile(allp / 1e6, [0.5, 99.5])
    lo, hi = min(lo, 0.0), max(hi, 1e-9)
    pts = np.concatenate([f["points"] for r in results.values() for f in r.bodies.values()])
    span = np.ptp(pts, axis=0)
    aspect = span[1] / span[0] if span[0] > 0 else 1.0
    fig_w = 12.0
    panel_h = max(fig_w * aspect * 0.85, 1.2)
    fig, axes = plt.subplots(len(results), 1, figsize=(fig_w, panel_h * len(results) + 1.2),
                             sharex=True, sharey=True, constrained_layout=True)
    axes = np.atleast_1d(axes)
    for ax, (method, r) in zip(axes, results.items()):
        for f in r.bodies.values():
            x = f["points"] * 1e3
            tri = Triangulation(x[:, 0], x[:, 1], f["triangles"])
            im = ax.tripcolor(tri, f["pressure"] / 1e6, shading="gouraud", cmap="viridis",
                              vmin=lo, vmax=hi, rasterized=True)
        ax.set_aspect("equal")
        ax.set_title(f"{LABELS[method]}: pressure at t = "
                     f"{r.history['time'][-1] * 1e6:.1f} \u00b5s", fontsize=12)
        ax.set_ylabel("y (mm)", fontsize=11)
    axes[-1].set_xlabel("x (mm)", fontsize=11)
    cb = fig.colorbar(im, ax=list(axes), shrink=0.9, extend="both")
    cb.set_label(f"pressure (MPa, compression positive); 1D acoustic p_ref = "
                 f"{ref['p_ref'] / 1e6:.0f} MPa")
    fig.savefig(path, dpi=150)
    plt.close(fig)


def _history_figure(results, ref, path):
    """Contact force and energies of the methods; both per metre of thickness (MN/m and
    kJ/m), time in microseconds."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .plot import FONT

    with plt.rc_context(FONT):
        fig, (a1, a2) = plt.subplots(2, 1, figsize=(9, 8), sharex=True,
                                     constrained_layout=True)
        for method, r in results.items():
            h = r.history
            t = h["time"] * 1e6
            a1.plot(t, contact_force(h, ref) / 1e6, color=COLORS[method], lw=1.4,
                    label=LABELS[method], zorder=3 if method == "fv" else 2)
            a2.plot(t, (h["kinetic_energy"] + h["strain_energy"]) / 1e3,
                    color=COLORS[method], lw=1.8, label=f"{LABELS[method]}: kinetic + strain")
            a2.plot(t, h["kinetic_energy"] / 1e3, color=COLORS[method], lw=1.1, ls="--")
            a2.plot(t, h["strain_energy"] / 1e3, color=COLORS[method], lw=1.1, ls=":")
        a1.axhline(ref["p_ref"] * ref["width"] / 1e6, color="k", lw=0.9, ls="--",
                   label="1D acoustic: p_ref x contact width")
        # start shortly before the first contact: the free flight before it is uneventful
        starts = []
        for r in results.values():
            on = np.flatnonzero(contact_force(r.history, ref) > 0)
            if len(on):
                starts.append(r.history["time"][on[0]])
        end = max(r.history["time"][-1] for r in results.values())
        if starts:
            t0 = min(starts)
            a1.set_xlim(max(0.0, t0 - 0.1 * (end - t0)) * 1e6, end * 1e6)
        a1.set_ylabel("contact force, compressive\n(MN/m, per metre of thickness)")
        a1.legend(loc="upper right")
        a1.grid(alpha=0.3)
        a2.set_ylabel("energy (kJ/m, per metre of thickness)")
        a2.set_xlabel("time (\u00b5s)")
        a2.plot([], [], color="gray", ls="--", label="kinetic")
        a2.plot([], [], color="gray", ls=":", label="strain")
        a2.legend(loc="center right")
        a2.grid(alpha=0.3)
        fig.savefig(path, dpi=150)
        plt.close(fig)


# ----------------------------------------------------------------------------- driver

def _or_dash(value, spec):
    return f"{'-':>8}" if not np.isfinite(value) else format(value, spec)


def format_table(rows) -> str:
    head = (f"{'method':<9} {'nodes':>6} {'steps':>6} {'wall s':>7} {'rough':>7} "
            f"{'peak MPa':>9} {'peak/pref':>9} {'pkF MPa':>8} {'pkF/pref':>8} {'plat MPa':>9} {'plat/pref':>9} "
            f"{'pen/h':>8} {'dP':>8} {'E/E0':>6} {'E+W/E0':>7}")
    lines = [head]
    for r in rows:
        lines.append(f"{r['method']:<9} {r['nodes']:>6d} {r['steps']:>6d} "
                     f"{r['wall_time_s']:>7.2f} {r['roughness']:>7.4f} "
                     f"{r['peak_pressure_MPa']:>9.1f} {r['peak_over_pref']:>9.3f} "
                     f"{r['peak_contact_pressure_MPa']:>8.1f} {r['peak_contact_over_pref']:>8.3f} "
                     f"{r['plateau_pressure_MPa']:>9.1f} {r['plateau_over_pref']:>9.3f} "
                     f"{r['penetration_per_h']:>8.1e} "
                     f"{_or_dash(r['momentum_drift'], '>8.1e')} "
                     f"{r['energy_end_over_start']:>6.3f} "
                     f"{r['energy_with_contact_end_over_start']:>7.3f}")
    return "\n".join(lines)


def compare_case(case: Case, output_dir=None, divisions=None, methods=METHODS,
                 figures=True, verbose=True) -> dict:
    """Run the methods on matching meshes; write figures, table and runs into output_dir.

    Returns ``{"rows": [...], "results": {method: RunResult}, "reference": {...},
    "output_dir": Path}``.
    """
    from .pipeline import run

    out = Path(output_dir) if output_dir is not None else \
        Path("results") / f"{case.stem}_compare"
    ref = reference_pressure(case)
    methods, skipped = runnable_methods(case, methods)
    out.mkdir(parents=True, exist_ok=True)
    if verbose:
        for line in summary_lines(case, ref, skipped):
            print(line, flush=True)
    results, rows = {}, []
    for method in methods:
        mcase = method_case(case, method, divisions)
        if verbose:
            print(f"[{method}] running ...", flush=True)
        start = time.perf_counter()
        results[method] = r = run(mcase, out / method, progress=False)
        row = metrics(method, r, ref, mcase)
        rows.append(row)
        if verbose:
            print(f"[{method}] {r.summary['steps']} steps, {r.summary['nodes']} nodes, "
                  f"{time.perf_counter() - start:.1f} s", flush=True)
    with open(out / "comparison.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(COLUMNS)
        for r in rows:
            w.writerow([r[c] if isinstance(r[c], str) else f"{r[c]:.6g}" for c in COLUMNS])
    if figures:
        if verbose:
            print("writing figures ...", flush=True)
        _pressure_figure(results, ref, out / "pressure_contours.png")
        _history_figure(results, ref, out / "histories.png")
    if verbose:
        print(format_table(rows))
        print(f"results in {out}/ (pressure_contours.png, histories.png, comparison.csv)")
    return {"rows": rows, "results": results, "reference": ref, "output_dir": out}


def runnable_methods(case: Case, methods=METHODS):
    """(the methods that can run ``case``, {method: why not} for the others). Checks the
    case only, before anything runs; refuses (InputError naming the case file) when no FE
    baseline is left to compare with, or no method at all."""
    from .fem.stepper import unsupported

    ok, skipped = [], {}
    for method in methods:
        problem = None if method == "fv" else unsupported(case, method)
        if problem:
            prefix = f"{case.source}: "
            skipped[method] = problem[len(prefix):] if problem.startswith(prefix) else problem
        else:
            ok.append(method)
    if len(ok) < 2:
        why = "; ".join(f"{m}: {w}" for m, w in skipped.items())
        raise InputError(f"{case.source}: compare needs the FV scheme and at least one FE "
                         f"baseline, and {'only ' + ok[0] if ok else 'no method'} can run "
                         f"this case ({why})")
    return ok, skipped


def summary_lines(case: Case, ref: dict, skipped: dict) -> list[str]:
    """What compare prints before it runs: the reference pressure and how it was made, the
    methods it skips and why, and what the momentum and energy metrics can show."""
    za, zb = ref["Z"]
    if np.isclose(za, zb, rtol=1e-9):
        how = (f"rho c_p v0 with rho c_p = {za:.4g} kg/(m^2 s) and v0 = half the closing "
               f"speed = {ref['v0']:.3g} m/s")
    else:
        na, nb = ref["bodies"]
        how = (f"v_close Z_a Z_b / (Z_a + Z_b) with closing speed v_close = "
               f"{ref['v_close']:.3g} m/s and impedances Z = rho c_p of {na!r} "
               f"{za:.4g} and of {nb!r} {zb:.4g} kg/(m^2 s)")
    lines = [f"1D acoustic contact pressure p_ref = {ref['p_ref'] / 1e6:.1f} MPa ({how}; "
             "the closing speed is that of the mean initial velocities along the line "
             "joining the centroids)"]
    lines += [f"[{m}] skipped: {why}" for m, why in skipped.items()]
    loads = external_loads(case)
    if loads:
        lines.append("momentum drift (dP) not reported: the boundary conditions exchange "
                     f"momentum with the outside ({'; '.join(loads)})")
        if any("moving" in x or "traction" in x for x in loads):
            lines.append("energy ratios include the work of moving supports or tractions")
    return lines


def compare_main(args) -> int:
    case = load_case(args.case, overrides=getattr(args, "overrides", None))
    out = Path(args.output) if getattr(args, "output", None) else \
        Path("results") / f"{Path(args.case).stem}_compare"
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: output path exists and is not a folder")
    compare_case(case, out)
    return 0
