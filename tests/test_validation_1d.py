"""Exact 1D acoustic Riemann problem in a strip with roller sides (docs/validation.md)."""

import numpy as np
import pytest

from conftest import COPPER_03

from impactfv import load_case, run
from impactfv.physics.materials import Material, cauchy_stress


def sigma_11(F, M):
    sigma = np.zeros((2, 2))
    cauchy_stress(F, np.array(M.table_row()), sigma)
    return sigma[0, 0]


@pytest.mark.parametrize("model", ["linear_elastic", "neo_hookean"])
def test_star_state_between_the_waves(model):
    mat = dict(COPPER_03, model=model)
    M = Material.from_entry(mat)
    L, vL, vR = 0.1, 2.0, -1.0
    case = {"run": {"end_time": 0.25 * L / M.p_wave_speed},
            "material": [mat],
            "body": [{"name": "strip", "material": mat["name"],
                      "velocity": lambda p: np.column_stack(
                          [np.where(p[:, 0] < L / 2, vL, vR), np.zeros(len(p))]),
                      "mesh": {"generator": "rectangle", "origin": [0, 0],
                               "size": [L, L / 40], "divisions": [200, 5]},
                      "boundary": [{"region": "ymin", "velocity": {"y": 0.0}},
                                   {"region": "ymax", "velocity": {"y": 0.0}}]}]}
    b = run(load_case(case)).bodies["strip"]
    v_star = 0.5 * (vL + vR)
    s_star = M.p_impedance * (vR - vL) / 2
    between = np.abs(b["reference_points"][:, 0] - L / 2) < 0.12 * L
    s11 = np.array([sigma_11(F, M) for F in b["F"][between]])
    assert np.abs(b["velocity"][between, 0] - v_star).max() < 0.01 * abs(vL - vR)
    assert np.abs(s11 - s_star).max() < 0.01 * abs(s_star)
    # the waves have left the middle at +-c_p: undisturbed material beyond the fronts
    ahead = b["reference_points"][:, 0] > L / 2 + 0.25 * L + 0.02 * L
    assert np.abs(b["velocity"][ahead, 0] - vR).max() < 0.01 * abs(vL - vR)
