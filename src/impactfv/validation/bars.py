"""Bar impact cases with analytic 1D answers (docs/validation.md; seed paper, section 5)."""

from __future__ import annotations

import numpy as np

SEED_MATERIAL = {"name": "copper", "model": "neo_hookean", "density": 8930.0,
                 "youngs_modulus": 585.0e6, "poisson_ratio": 0.495}


def _mesh(origin, length, width, divisions, pattern):
    """A rectangle (divisions (nx, ny)) or, with three divisions, a box of square section
    width x width."""
    if len(divisions) == 2:
        return {"generator": "rectangle", "origin": [origin, 0.0], "size": [length, width],
                "divisions": list(divisions), "pattern": pattern}
    return {"generator": "box", "origin": [origin, 0.0, 0.0],
            "size": [length, width, width], "divisions": list(divisions)}


def _rollers(dim):
    """Lateral sides held in their normal direction (uniaxial strain)."""
    return [{"region": f"{c}{end}", "velocity": {c: 0.0}}
            for c in "yz"[:dim - 1] for end in ("min", "max")]


def two_bars(length=0.01, width=0.001, gap=4e-4, v0=50.0, divisions=(50, 5),
             divisions_right=None, materials=(SEED_MATERIAL, SEED_MATERIAL), rollers=True,
             model="slip", end_time=None, tangential=0.0, pattern="alternate",
             bodies_order=("left", "right"), **run):
    """Two bars along x meeting at x = 0, velocities +-v0 (and +-tangential along y).
    Three ``divisions`` make them 3D bars of square section width x width."""
    from ..physics.materials import Material

    mats = [dict(m) for m in materials]
    if mats[0]["name"] == mats[1]["name"] and mats[0] != mats[1]:
        raise ValueError("two different materials need two names")
    unique = {m["name"]: m for m in mats}
    c = min(Material.from_entry(m).p_wave_speed for m in mats)
    if end_time is None:
        end_time = gap / (2 * v0) + 1.3 * 2 * length / c
    dim = len(divisions)
    side = _rollers(dim) if rollers else []
    right_div = divisions_right or divisions
    rest = [0.0] * (dim - 2)
    bodies = {
        "left": {"name": "left", "material": mats[0]["name"],
                 "velocity": [v0, tangential, *rest],
                 "mesh": _mesh(-length - gap / 2, length, width, divisions, pattern),
                 "boundary": side},
        "right": {"name": "right", "material": mats[1]["name"],
                  "velocity": [-v0, -tangential, *rest],
                  "mesh": _mesh(gap / 2, length, width, right_div, pattern),
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
    """A bar moving at +v0 onto a rigid wall at x = 0 (roller sides; three ``divisions``
    make it a 3D bar of square section)."""
    from ..physics.materials import Material

    c = Material.from_entry(material).p_wave_speed
    if end_time is None:
        end_time = gap / v0 + 1.3 * 2 * length / c
    dim = len(divisions)
    zero = [0.0] * (dim - 1)
    return {
        "run": {"end_time": end_time, "output_interval": end_time / 4, **run},
        "material": [dict(material)],
        "body": [{"name": "bar", "material": material["name"], "velocity": [v0, *zero],
                  "mesh": _mesh(-length - gap, length, width, divisions, "alternate"),
                  "boundary": _rollers(dim)}],
        "contact": [{"bodies": ["bar"], "model": model,
                     "wall": {"point": [0.0] * dim, "normal": [-1.0, *zero]}}],
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
