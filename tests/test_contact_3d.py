"""Rankine-Hugoniot contact on tetrahedral meshes: 3D bars in uniaxial strain against their
1D answers (docs/validation.md), non-matching meshes, a rigid wall, stick against slip."""

import numpy as np
import pytest
from conftest import COPPER

from impactfv import load_case, run
from impactfv.physics.materials import Material
from impactfv.mesh.dual import median_dual
from impactfv.validation.bars import bar_on_wall, pulse, two_bars

SEED = Material.from_entry(COPPER)
L, W, V0 = 0.01, 0.001, 50.0
REF = W * W * SEED.p_impedance * V0      # contact force on a W x W section, rho c_p v0 W^2
DURATION = 2 * L / SEED.p_wave_speed
MASS = SEED.density * L * W * W


def mean_velocity(body):
    omega = median_dual(body["reference_points"], body["tetrahedra"]).volumes
    return (omega[:, None] * body["velocity"]).sum(axis=0) / omega.sum()


def check_pulse(hist, h, plateau_tol, duration_tol, penetration):
    t0, t1, plateau = pulse(hist, reference=REF)
    assert plateau == pytest.approx(REF, rel=plateau_tol)
    assert t1 - t0 == pytest.approx(DURATION, rel=duration_tol)
    assert np.nanmin(hist["contact0_gap"]) > -penetration * h
    E = hist["total_energy"]
    assert np.all(np.diff(E) <= 1e-12 * E[0])


def check_bars(result, h, rebound, plateau=0.02, duration=0.03, penetration=0.01):
    hist = result.history
    check_pulse(hist, h, plateau, duration, penetration)
    left = mean_velocity(result.bodies["left"])
    right = mean_velocity(result.bodies["right"])
    assert left[0] == pytest.approx(-V0, rel=rebound)
    assert right[0] == pytest.approx(V0, rel=rebound)
    # along the bars momentum passes between them exactly (the rollers act across)
    p = hist["momentum_x"]
    assert np.abs(p - p[0]).max() < 1e-10 * 2 * MASS * V0


def test_identical_3d_bars_in_uniaxial_strain():
    """40 x 4 x 4 cells (measured with the defaults: plateau 1.0003, duration 0.992, rebound
    0.954, no penetration); the rebound approaches v0 as h falls (slow test)."""
    result = run(load_case(two_bars(divisions=(40, 4, 4))))
    check_bars(result, L / 40, rebound=0.06)
    assert result.bodies["left"]["velocity"].shape[1] == 3
    assert "contact0_fz" in result.history


@pytest.mark.slow
def test_identical_3d_bars_rebound_within_3_percent():
    """80 x 8 x 8 cells (measured with the defaults: rebound 0.972, plateau 1.0003, duration
    0.996)."""
    check_bars(run(load_case(two_bars(divisions=(80, 8, 8)))), L / 80, rebound=0.03)


def test_3d_bars_with_non_matching_meshes():
    """The right bar's section is cut 5 x 5 against the left's 4 x 4, and its length 32
    against 40 cells: the contact pressure is carried over the clipped overlaps of the
    faces."""
    result = run(load_case(two_bars(divisions=(40, 4, 4), divisions_right=(32, 5, 5))))
    check_bars(result, L / 40, rebound=0.06, plateau=0.04, duration=0.06, penetration=0.02)


def test_3d_bar_against_rigid_wall():
    result = run(load_case(bar_on_wall(divisions=(40, 4, 4))))
    hist = result.history
    check_pulse(hist, L / 40, 0.02, 0.03, 0.01)
    assert mean_velocity(result.bodies["bar"])[0] == pytest.approx(-V0, rel=0.06)
    # the slip wall pushes along its normal only
    for c in "yz":
        assert np.abs(hist[f"contact0_f{c}"]).max() < 1e-9 * REF


def test_swapping_the_3d_bodies_gives_the_same_result():
    a = run(load_case(two_bars(divisions=(20, 3, 3), divisions_right=(16, 4, 4),
                               end_time=1.2e-5))).history
    b = run(load_case(two_bars(divisions=(20, 3, 3), divisions_right=(16, 4, 4),
                               end_time=1.2e-5, bodies_order=("right", "left")))).history
    assert np.abs(a["contact0_fx"] + b["contact0_fx"]).max() < 1e-8 * REF
    assert np.allclose(a["total_energy"], b["total_energy"], rtol=1e-10)


def oblique_block(model):
    """A free 2 mm copper cube falling on a wall at 20 m/s with 10 m/s along the wall (in
    y) and 5 m/s across (in z)."""
    return {
        "run": {"end_time": 1.0e-5},
        "material": [dict(COPPER)],
        "body": [{"name": "block", "material": "copper", "velocity": [-20.0, 10.0, 5.0],
                  "mesh": {"generator": "box", "origin": [2e-5, 0.0, 0.0],
                           "size": [0.002, 0.002, 0.002], "divisions": [6, 6, 6]}}],
        "contact": [{"bodies": ["block"], "model": model,
                     "wall": {"point": [0.0, 0.0, 0.0], "normal": [1.0, 0.0, 0.0]}}],
    }


def test_a_block_on_a_wall_keeps_its_tangential_momentum_in_slip_and_loses_it_in_stick():
    out = {}
    for model in ("slip", "stick"):
        result = run(load_case(oblique_block(model)))
        hist = result.history
        E = hist["total_energy"]
        assert np.all(np.diff(E) <= 1e-12 * E[0])
        assert np.abs(hist["contact0_fx"]).max() > 0              # it did hit the wall
        assert np.nanmin(hist["contact0_gap"]) > -0.01 * 0.002 / 6
        out[model] = hist
    slip, stick = out["slip"], out["stick"]
    for c in "yz":
        p = slip[f"momentum_{c}"]
        # slip: the wall takes no tangential momentum at all
        assert np.abs(p - p[0]).max() < 1e-12 * np.abs(p[0])
        assert np.abs(slip[f"contact0_f{c}"]).max() < 1e-9 * np.abs(slip["contact0_fx"]).max()
        # stick: the wall holds the contact face, the block's tangential momentum falls
        assert stick[f"momentum_{c}"][-1] < 0.9 * stick[f"momentum_{c}"][0]
    assert slip["momentum_x"][-1] > 0 and stick["momentum_x"][-1] > 0   # bounced back
