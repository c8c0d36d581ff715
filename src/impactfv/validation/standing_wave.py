"""The smooth plane-strain standing wave (docs/validation.md) and its error norms.

u = U0 sin(w t) [sin(pi X/2) cos(pi Y/2), cos(pi X/2) sin(pi Y/2)] on the unit square with
w = pi c_p / sqrt(2). The field is irrotational, so it solves linear elastodynamics exactly.
Started in its sine phase: zero displacement, velocity U0 w [...] at t = 0.
Boundaries: X=0 and Y=0 symmetric (normal velocity 0, no shear traction); X=1 and Y=1 zero
tangential velocity and zero normal traction.
"""

from __future__ import annotations

import numpy as np

from ..materials import Material
from ..mesh.dual import median_dual

RUBBER = dict(name="rubber", model="linear_elastic", density=1100.0, youngs_modulus=17.0e6,
              poisson_ratio=0.45)


def frequency(material: Material) -> float:
    return np.pi * material.p_wave_speed / np.sqrt(2.0)


def exact(points, t, material: Material, amplitude):
    """Velocity (n,2) and Cauchy stress components (s11, s12, s22) at the reference points."""
    w = frequency(material)
    X, Y = points[:, 0], points[:, 1]
    h = np.pi / 2
    shape = np.column_stack([np.sin(h * X) * np.cos(h * Y), np.cos(h * X) * np.sin(h * Y)])
    velocity = amplitude * w * np.cos(w * t) * shape
    s = amplitude * np.sin(w * t)
    exx = s * h * np.cos(h * X) * np.cos(h * Y)
    eyy = exx
    exy = -s * h * np.sin(h * X) * np.sin(h * Y)
    lam, mu = material.lam, material.mu
    return velocity, (lam * (exx + eyy) + 2 * mu * exx, 2 * mu * exy,
                      lam * (exx + eyy) + 2 * mu * eyy)


def case_dict(divisions, order=2, limiter="none", end_fraction=0.375, amplitude=1e-4,
              pattern="alternate", cfl=0.4, material=None):
    """Case of the standing wave run for ``end_fraction`` of a period (3/8 by default: a phase
    where neither the velocity nor the stress vanishes)."""
    material = dict(material or RUBBER)
    mat = Material.from_entry(material)
    period = 2 * np.pi / frequency(mat)

    def velocity(points):
        return exact(points, 0.0, mat, amplitude)[0]

    return {
        "run": {"end_time": end_fraction * period, "order": order, "limiter": limiter,
                "cfl": cfl},
        "material": [material],
        "body": [{
            "name": "square", "material": material["name"], "velocity": velocity,
            "mesh": {"generator": "rectangle", "origin": [0.0, 0.0], "size": [1.0, 1.0],
                     "divisions": [divisions, divisions], "pattern": pattern},
            "boundary": [{"region": "xmin", "velocity": {"x": 0.0}},
                         {"region": "ymin", "velocity": {"y": 0.0}},
                         {"region": "xmax", "velocity": {"y": 0.0}},
                         {"region": "ymax", "velocity": {"x": 0.0}}],
        }],
    }


def errors(result, case_data, amplitude=1e-4):
    """Relative L2 errors of velocity and stress at the final time."""
    mat = Material.from_entry(case_data["material"][0])
    body = result.bodies["square"]
    t = result.history["time"][-1]
    v_ex, s_ex = exact(body["reference_points"], t, mat, amplitude)
    F = body["F"]
    # small-strain stress from the computed F (linear elastic: P = sigma)
    e11, e22 = F[:, 0, 0] - 1, F[:, 1, 1] - 1
    e12 = 0.5 * (F[:, 0, 1] + F[:, 1, 0])
    lam, mu = mat.lam, mat.mu
    s_num = (lam * (e11 + e22) + 2 * mu * e11, 2 * mu * e12, lam * (e11 + e22) + 2 * mu * e22)
    w = median_dual(body["reference_points"], body["triangles"]).volumes
    v_scale = amplitude * frequency(mat)
    s_scale = amplitude * (lam + 2 * mu) * np.pi / 2
    ev = np.sqrt(np.sum(w * np.sum((body["velocity"] - v_ex) ** 2, axis=1))) / v_scale
    es = np.sqrt(np.sum(w * sum((a - b) ** 2 for a, b in zip(s_num, s_ex)))) / s_scale
    return ev, es

