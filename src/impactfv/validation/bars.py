"""Bar impact cases with analytic 1D answers (docs/validation.md; seed paper, section 5)."""

from __future__ import annotations

import numpy as np

SEED_MATERIAL = {"name": "copper", "model": "neo_hookean", "density": 8930.0,
                 "youngs_modulus": 585.0e6, "poisson_ratio": 0.495}


def two_bars(length=0.01, width=0.001, gap=4e-4, v0=50.0, divisions=(50, 5),
             divisions_right=None, materials=(SEED_MATERIAL, SEED_MATERIAL), rollers=True,
             model="slip", end_time=None, tangential=0.0, pattern="alternate",
             bodies_order=("left", "right"), **run):
    """Two bars along x meeting at x = 0, velocities +-v0 (and +-tangential along y)."""
    from ..materials import Material

    mats = [dict(m) for m in materials]
    if mats[0]["name"] == mats[1]["name"] and mats[0] != mats[1]:
        raise ValueError("two different materials need two names")
    unique = {m["name"]: m for m in mats}
    c = min(Material.from_entry(m).p_wave_speed for m in mats)
    if end_time is None:
        end_time = gap / (2 * v0) + 1.3 * 2 * length / c
    side = [{"region": "ymin", "velocity": {"y": 0.0}},
            {"region": "ymax", "velocity": {"y": 0.0}}] if rollers else []
    right_div = divisions_right or divisions
    bodies = {
        "left": {"name": "left", "material": mats[0]["name"], "velocity": [v0, tangential],
                 "mesh": {"generator": "rectangle", "origin": [-length - gap / 2, 0.0],
                          "size": [length, width], "divisions": list(divisions),
                          "pattern": pattern},
                 "boundary": side},
        "right": {"name": "right", "material": mats[1]["name"], "velocity": [-v0, -tangential],
                  "mesh": {"generator": "rectangle", "origin": [gap / 2, 0.0],
                           "size": [length, width], "divisions": list(right_div),
                           "pattern": pattern},
                  "boundary": side},
    }
    return {
        "title": "two bars impacting",
        "run": {"end_time": end_time, "output_interval": end_time / 4, **run},
        "material": list(unique.values()),
        "body": [bodies["left"], bodies["right"]],
        "contact": [{"bodies": list(bodies_order), "model": model}],
    }


def bar_on_wall(length=0.01, width=0.001, gap=2e-4, v0=50.0, divisions=(50, 5),
                material=SEED_MATERIAL, model="slip", end_time=None, **run):
    """A bar moving at +v0 onto a rigid wall at x = 0 (roller sides)."""
    from ..materials import Material

    c = Material.from_entry(material).p_wave_speed
    if end_time is None:
        end_time = gap / v0 + 1.3 * 2 * length / c
    return {
        "run": {"end_time": end_time, "output_interval": end_time / 4, **run},
        "material": [dict(material)],
        "body": [{"name": "bar", "material": material["name"], "velocity": [v0, 0.0],
                  "mesh": {"generator": "rectangle", "origin": [-length - gap, 0.0],
                           "size": [length, width], "divisions": list(divisions)},
                  "boundary": [{"region": "ymin", "velocity": {"y": 0.0}},
                               {"region": "ymax", "velocity": {"y": 0.0}}]}],
        "contact": [{"bodies": ["bar"], "model": model,
                     "wall": {"point": [0.0, 0.0], "normal": [-1.0, 0.0]}}],
    }


def pulse(history, k=0, sign=-1.0, threshold=0.02, reference=1.0):
    """Start, end, and plateau (mean over the middle 60%) of contact force k along x."""
    f = sign * history[f"contact{k}_fx"]
    t = history["time"]
    on = np.flatnonzero(f > threshold * reference)
    if len(on) == 0:
        return None
    t0, t1 = t[on[0]], t[on[-1]]
    mid = (t > t0 + 0.2 * (t1 - t0)) & (t < t1 - 0.2 * (t1 - t0))
    return t0, t1, float(np.mean(f[mid]))
