"""The smooth standing wave (docs/validation.md) and its error norms, on the unit square
(plane strain) or the unit cube.

    u = U0 sin(w t) grad(psi) / h,   psi = -prod_i cos(h X_i),   h = pi / 2,

i.e. u_x = U0 sin(w t) sin(h X) cos(h Y) [cos(h Z)] and alike, with w = sqrt(d) h c_p. The
field is irrotational, so it solves linear elastodynamics exactly. Started in its sine phase:
zero displacement, velocity U0 w [...] at t = 0.
Boundaries: X_i = 0 symmetric (normal velocity 0, no shear traction); X_i = 1 zero
tangential velocity and zero normal traction.
"""

from __future__ import annotations

import numpy as np

from ..physics.materials import Material
from ..mesh.dual import median_dual

RUBBER = dict(name="rubber", model="linear_elastic", density=1100.0, youngs_modulus=17.0e6,
              poisson_ratio=0.45)
H = np.pi / 2


def frequency(material: Material, dim: int = 2) -> float:
    return np.sqrt(dim) * H * material.p_wave_speed


def _shape(points):
    """grad(psi) / h and the second derivatives d^2 psi / dX_i dX_j / h^2 of the mode."""
    d = points.shape[1]
    s = np.sin(H * points)
    c = np.cos(H * points)
    grad = np.empty_like(points)
    for i in range(d):
        grad[:, i] = s[:, i] * np.prod([c[:, j] for j in range(d) if j != i], axis=0)
    hess = np.empty((len(points), d, d))
    for i in range(d):
        for j in range(d):
            if i == j:
                hess[:, i, i] = np.prod(c, axis=1)
            else:
                others = [c[:, k] for k in range(d) if k not in (i, j)]
                rest = np.prod(others, axis=0) if others else 1.0
                hess[:, i, j] = -s[:, i] * s[:, j] * rest
    return grad, hess


def exact(points, t, material: Material, amplitude):
    """Velocity (n, d) and the independent Cauchy stress components (i <= j, row by row:
    s11, s12, s22 in 2D) at the reference points."""
    d = points.shape[1]
    w = frequency(material, d)
    grad, hess = _shape(points)
    velocity = amplitude * w * np.cos(w * t) * grad
    strain = amplitude * np.sin(w * t) * H * hess
    return velocity, linear_stress(strain, material)


def linear_stress(strain, material: Material):
    """sigma = lambda tr(eps) I + 2 mu eps of small strains (n, d, d), as the list of its
    components i <= j."""
    d = strain.shape[1]
    tr = np.trace(strain, axis1=1, axis2=2)
    return [(material.lam * tr if i == j else 0.0) + 2 * material.mu * strain[:, i, j]
            for i in range(d) for j in range(i, d)]


def case_dict(divisions, order=2, limiter="none", end_fraction=0.375, amplitude=1e-4,
              pattern="alternate", cfl=0.4, material=None, dim=2):
    """Case of the standing wave run for ``end_fraction`` of a period (3/8 by default: a phase
    where neither the velocity nor the stress vanishes); ``dim`` 3 runs it on the unit cube
    (``box`` mesh, ``pattern`` unused)."""
    material = dict(material or RUBBER)
    mat = Material.from_entry(material)
    period = 2 * np.pi / frequency(mat, dim)

    def velocity(points):
        return exact(points, 0.0, mat, amplitude)[0]

    names = "xyz"[:dim]
    boundary = [{"region": f"{c}min", "velocity": {c: 0.0}} for c in names]
    boundary += [{"region": f"{c}max", "velocity": {o: 0.0 for o in names if o != c}}
                 for c in names]
    if dim == 2:
        mesh = {"generator": "rectangle", "origin": [0.0, 0.0], "size": [1.0, 1.0],
                "divisions": [divisions, divisions], "pattern": pattern}
    else:
        mesh = {"generator": "box", "origin": [0.0] * 3, "size": [1.0] * 3,
                "divisions": [divisions] * 3}
    return {
        "run": {"end_time": end_fraction * period, "order": order, "limiter": limiter,
                "cfl": cfl},
        "material": [material],
        "body": [{"name": "square" if dim == 2 else "cube", "material": material["name"],
                  "velocity": velocity, "mesh": mesh, "boundary": boundary}],
    }


def errors(result, case_data, amplitude=1e-4):
    """Relative L2 errors of velocity and stress at the final time."""
    mat = Material.from_entry(case_data["material"][0])
    (body,) = result.bodies.values()
    t = result.history["time"][-1]
    X = body["reference_points"]
    d = X.shape[1]
    v_ex, s_ex = exact(X, t, mat, amplitude)
    # small-strain stress from the computed F (linear elastic: P = sigma)
    F = body["F"]
    strain = 0.5 * (F + np.swapaxes(F, 1, 2)) - np.eye(d)
    s_num = linear_stress(strain, mat)
    w = median_dual(X, body["cells"]).volumes
    v_scale = amplitude * frequency(mat, d)
    s_scale = amplitude * (mat.lam + 2 * mat.mu) * H
    ev = np.sqrt(np.sum(w * np.sum((body["velocity"] - v_ex) ** 2, axis=1))) / v_scale
    es = np.sqrt(np.sum(w * sum((a - b) ** 2 for a, b in zip(s_num, s_ex)))) / s_scale
    return ev, es
