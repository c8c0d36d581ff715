"""The twisting column: a demanding large-rotation test of 3D solid dynamics (docs/validation.md).

A 1 x 6 x 1 m rubber column (neo-Hookean, E = 17 MPa, nu = 0.45, rho = 1100 kg/m^3) stands
on its clamped base Y = 0; every other face is free. It starts with the twist velocity
v = omega(Y) x (X - X_axis), omega = (0, 105 sin(pi Y / 12), 0) rad/s, zero at the base and
largest at the top, and no deformation: it twists by more than a right angle, untwists and
swings back. No external work is done after the start, so the total energy must never rise.
"""

from __future__ import annotations

RUBBER = {"name": "rubber", "model": "neo_hookean", "density": 1100.0,
          "youngs_modulus": 17.0e6, "poisson_ratio": 0.45}


def case_dict(cells_across: int = 4, end_time: float = 0.25, output_interval=None, **run):
    """The column with ``cells_across`` cubic cells across its 1 m width (six times as many
    along its height)."""
    n = int(cells_across)
    return {
        "title": "twisting column",
        "run": {"end_time": end_time, "output_interval": output_interval or end_time / 25,
                **run},
        "material": [dict(RUBBER)],
        "body": [{"name": "column", "material": "rubber",
                  "velocity": ["105*sin(pi*y/12)*z", "0.0", "-105*sin(pi*y/12)*x"],
                  "mesh": {"generator": "box", "origin": [-0.5, 0.0, -0.5],
                           "size": [1.0, 6.0, 1.0], "divisions": [n, 6 * n, n]},
                  "boundary": [{"region": "ymin",
                                "velocity": {"x": 0.0, "y": 0.0, "z": 0.0}}]}],
    }
