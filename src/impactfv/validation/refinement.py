"""Mesh-refinement studies of contact problems (docs/validation.md, "Refinement studies").

Two studies, each a function that runs a list of nested meshes and returns a table:

* :func:`seed_bars_study` - the seed paper's example (two copper bars, 32.4 x 6.4 mm, free
  sides, closing at 2 x 50 m/s, slip). Compared between successive meshes: the contact force
  history over the first 20 us of contact and the pressure along the bar axis (y = 3.2 mm)
  20 us after the touch (the paper's snapshot at 100 us). The 80 us of free flight before
  the touch are a uniform translation that every mesh reproduces exactly, so by default the
  bars start 0.2 mm apart (touch at 2 us) instead of 8 mm: the same problem, 5x cheaper.
* :func:`block_on_slab_study` - a 4 x 2 mm steel block hitting a clamped aluminium slab at
  (40, -100) m/s with slip. Measured: the grid-scale part of the pressure near the contact
  face (each node's pressure minus the mean over its edge neighbours, RMS over a band of
  0.5 mm on each side of the face), which a two-cell pattern would keep at a fixed size
  under refinement and a smooth field makes fall like h^2.

Successive differences d_k = ||u_{h_k} - u_{h_{k+1}}|| give the observed order
log2(d_k / d_{k+1}) without an exact solution (meshes halve h each time).
"""

from __future__ import annotations

import numpy as np

from .bars import SEED_MATERIAL

SEED_LENGTH = 32.4e-3
SEED_WIDTH = 6.4e-3
SEED_V0 = 50.0
STEEL = {"name": "steel", "model": "neo_hookean", "density": 7850.0,
         "youngs_modulus": 210.0e9, "poisson_ratio": 0.3}
ALUMINIUM = {"name": "aluminium", "model": "neo_hookean", "density": 2700.0,
             "youngs_modulus": 70.0e9, "poisson_ratio": 0.33}


def observed_orders(differences) -> list[float]:
    """log2 of the ratio of successive differences (meshes halving h)."""
    d = np.asarray(differences, float)
    return [float(np.log2(a / b)) for a, b in zip(d, d[1:])]


# ----------------------------------------------------------------------------- seed bars

def seed_bars_case(h: float, gap: float = 0.2e-3, after_touch: float = 20e-6,
                   model: str = "slip", **run) -> dict:
    """The seed paper's two bars on square cells of size ``h`` ("alternate" diagonals)."""
    nx, ny = round(SEED_LENGTH / h), round(SEED_WIDTH / h)
    if not (np.isclose(nx * h, SEED_LENGTH) and np.isclose(ny * h, SEED_WIDTH)):
        raise ValueError(f"h = {h} does not divide the 32.4 x 6.4 mm bar")
    touch = gap / (2 * SEED_V0)
    body = {"material": SEED_MATERIAL["name"]}
    mesh = {"generator": "rectangle", "size": [SEED_LENGTH, SEED_WIDTH],
            "divisions": [nx, ny], "pattern": "alternate"}
    return {
        "run": {"end_time": touch + after_touch, "output_interval": touch + after_touch,
                **run},
        "material": [dict(SEED_MATERIAL)],
        "body": [{**body, "name": "left", "velocity": [SEED_V0, 0.0],
                  "mesh": {**mesh, "origin": [-SEED_LENGTH - gap / 2, 0.0]}},
                 {**body, "name": "right", "velocity": [-SEED_V0, 0.0],
                  "mesh": {**mesh, "origin": [gap / 2, 0.0]}}],
        "contact": [{"bodies": ["left", "right"], "model": model}],
    }


def seed_reference_pressure() -> float:
    """rho c_p v0 of the seed bars (1D acoustic contact pressure, 664 MPa)."""
    from ..physics.materials import Material

    return Material.from_entry(SEED_MATERIAL).p_impedance * SEED_V0


def seed_bars_study(hs=(0.4e-3, 0.2e-3, 0.1e-3, 0.05e-3), gap: float = 0.2e-3,
                    after_touch: float = 20e-6, samples: int = 401, report=None, **run):
    """Run the seed bars on each h; return a dict of the curves and the difference table.

    ``force``: compressive contact force per unit thickness on ``times`` (s after the touch),
    ``axis_x``/``axis_p``: reference x and pressure of the left bar's axis nodes of the
    coarsest mesh (every finer mesh has them) at ``after_touch``. ``force_diff`` and
    ``axis_diff``: L1 differences between successive meshes, relative to p_ref x width
    (force) and p_ref (pressure).
    """
    from .. import load_case
    from ..pipeline.run import run as run_case

    hs = list(hs)
    p_ref = seed_reference_pressure()
    touch = gap / (2 * SEED_V0)
    times = np.linspace(0.0, after_touch, samples)
    out = {"h": hs, "p_ref": p_ref, "times": times, "force": [], "axis_p": [],
           "steps": [], "nodes": [], "energy_ratio": []}
    axis_x = None
    for h in hs:
        result = run_case(load_case(seed_bars_case(h, gap, after_touch, **run)))
        hist = result.history
        force = hist["contact0_fx"]          # force on the left bar: compressive is negative x
        out["force"].append(np.interp(times + touch, hist["time"], -force))
        left = result.bodies["left"]
        X = left["reference_points"]
        on_axis = np.isclose(X[:, 1], SEED_WIDTH / 2, atol=1e-3 * h)
        if axis_x is None:
            axis_x = np.sort(X[on_axis, 0])
        order = np.argsort(X[on_axis, 0])
        xs, ps = X[on_axis, 0][order], left["pressure"][on_axis][order]
        pick = np.searchsorted(xs, axis_x - 1e-3 * h)
        if not np.allclose(xs[pick], axis_x, atol=1e-3 * h):
            raise ValueError("meshes are not nested: the coarse axis nodes are missing")
        out["axis_p"].append(ps[pick])
        out["steps"].append(len(hist["time"]) - 1)
        out["nodes"].append(sum(len(b["reference_points"]) for b in result.bodies.values()))
        e = hist["total_energy"]
        out["energy_ratio"].append(float(e[-1] / e[0]))
        if report is not None:
            report(h, out)
    out["axis_x"] = axis_x
    width = SEED_WIDTH
    out["force_diff"] = [float(np.mean(np.abs(a - b))) / (p_ref * width)
                         for a, b in zip(out["force"], out["force"][1:])]
    out["axis_diff"] = [float(np.mean(np.abs(a - b))) / p_ref
                        for a, b in zip(out["axis_p"], out["axis_p"][1:])]
    out["force_order"] = observed_orders(out["force_diff"])
    out["axis_order"] = observed_orders(out["axis_diff"])
    return out


# ----------------------------------------------------------------------------- block on slab

def block_on_slab_case(n: int, end_time: float = 1.0e-6, gap: float = 0.01e-3,
                       **run) -> dict:
    """4 x 2 mm steel block (n x n/2 cells) at (40, -100) m/s on a 12 x 2 mm aluminium slab
    (3n x n/2 cells, same h) clamped at its base; slip; "alternate" diagonals."""
    if n % 2:
        raise ValueError("n must be even (the block has n x n/2 cells)")
    rect = {"generator": "rectangle", "pattern": "alternate"}
    return {
        "run": {"end_time": end_time, "output_interval": end_time, **run},
        "material": [dict(STEEL), dict(ALUMINIUM)],
        "body": [{"name": "block", "material": "steel", "velocity": [40.0, -100.0],
                  "mesh": {**rect, "origin": [-2e-3, gap], "size": [4e-3, 2e-3],
                           "divisions": [n, n // 2]}},
                 {"name": "slab", "material": "aluminium", "velocity": [0.0, 0.0],
                  "mesh": {**rect, "origin": [-6e-3, -2e-3], "size": [12e-3, 2e-3],
                           "divisions": [3 * n, n // 2]},
                  "boundary": [{"region": "ymin", "velocity": {"x": 0.0, "y": 0.0}}]}],
        "contact": [{"bodies": ["block", "slab"], "model": "slip"}],
    }


def grid_scale_pressure(bodies: dict, p_ref: float, band: float = 0.5e-3) -> float:
    """RMS over nodes within ``band`` of the contact face (reference y = 0 or gap) and
    |x| < 1.5 mm of p_i minus the mean of p over its edge neighbours, relative to p_ref."""
    from ..mesh.edges import unique_edges

    residuals = []
    for name, f in bodies.items():
        p = np.asarray(f["pressure"], float)
        X = f["reference_points"]
        e = unique_edges(f["triangles"])
        n = len(p)
        total = np.bincount(e[:, 0], p[e[:, 1]], n) + np.bincount(e[:, 1], p[e[:, 0]], n)
        count = np.bincount(e.ravel(), minlength=n)
        face_y = X[:, 1].min() if name == "block" else X[:, 1].max()
        near = (np.abs(X[:, 1] - face_y) < band) & (np.abs(X[:, 0]) < 1.5e-3)
        residuals.append((p - total / count)[near])
    r = np.concatenate(residuals) / p_ref
    return float(np.sqrt(np.mean(r ** 2)))


def block_on_slab_reference_pressure() -> float:
    """Normal closing speed (100 m/s) x Z_steel Z_al / (Z_steel + Z_al)."""
    from ..physics.materials import Material

    za = Material.from_entry(STEEL).p_impedance
    zb = Material.from_entry(ALUMINIUM).p_impedance
    return 100.0 * za * zb / (za + zb)


def block_on_slab_study(ns=(20, 40, 80, 160), end_time: float = 1.0e-6, report=None, **run):
    """Grid-scale pressure near the contact face for each n; its observed order."""
    from .. import load_case
    from ..pipeline.run import run as run_case

    p_ref = block_on_slab_reference_pressure()
    out = {"n": list(ns), "h": [4e-3 / n for n in ns], "p_ref": p_ref, "grid_scale": [],
           "bodies": []}
    for n in ns:
        result = run_case(load_case(block_on_slab_case(n, end_time, **run)))
        out["grid_scale"].append(grid_scale_pressure(result.bodies, p_ref))
        out["bodies"].append(result.bodies)
        if report is not None:
            report(n, out)
    out["order"] = observed_orders(out["grid_scale"])
    return out
