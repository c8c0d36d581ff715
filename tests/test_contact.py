"""Rankine-Hugoniot contact: bars in uniaxial strain (numerics.md H.2, H.3), materials of
different impedance (seed eq. 5), stick against slip, symmetry and start-up checks."""

import numpy as np
import pytest
from conftest import run_cli

from impactfv import InputError, load_case, run
from impactfv.contact.riemann import contact_state, wall_state
from impactfv.materials import Material
from impactfv.mesh.dual import median_dual
from impactfv.validation.bars import SEED_MATERIAL, bar_on_wall, pulse, two_bars

SEED = Material(**SEED_MATERIAL)
L, W, V0 = 0.01, 0.001, 50.0
REF = W * SEED.p_impedance * V0          # contact force per unit thickness, W rho c_p v0
DURATION = 2 * L / SEED.p_wave_speed


def body_momentum(body, density):
    omega = median_dual(body["reference_points"], body["triangles"]).dual_areas
    return density * (omega[:, None] * body["velocity"]).sum(axis=0)


def check_bar_impact(result, h, tol):
    hist = result.history
    t0, t1, plateau = pulse(hist, reference=REF)
    assert plateau == pytest.approx(REF, rel=tol["plateau"])
    assert t1 - t0 == pytest.approx(DURATION, rel=tol["duration"])
    left = body_momentum(result.bodies["left"], SEED.density)[0]
    right = body_momentum(result.bodies["right"], SEED.density)[0]
    mass = SEED.density * L * W
    assert left / mass == pytest.approx(-V0, rel=tol["rebound"])
    assert right / mass == pytest.approx(V0, rel=tol["rebound"])
    assert np.nanmin(hist["contact0_gap"]) > -tol["penetration"] * h
    px = hist["momentum_x"]
    assert np.abs(px - px[0]).max() < 1e-10 * 2 * mass * V0
    E = hist["total_energy"]
    assert np.all(np.diff(E) <= 1e-12 * E[0])


def test_identical_bars_in_uniaxial_strain():
    result = run(load_case(two_bars(divisions=(100, 10))))
    check_bar_impact(result, L / 100, {"plateau": 0.02, "duration": 0.03, "rebound": 0.03,
                                       "penetration": 0.01})


def test_identical_bars_with_non_matching_meshes():
    result = run(load_case(two_bars(divisions=(100, 10), divisions_right=(80, 13))))
    check_bar_impact(result, L / 100, {"plateau": 0.04, "duration": 0.06, "rebound": 0.06,
                                       "penetration": 0.02})


def test_swapping_the_bodies_gives_the_same_result():
    a = run(load_case(two_bars(divisions=(40, 4), divisions_right=(30, 5)))).history
    b = run(load_case(two_bars(divisions=(40, 4), divisions_right=(30, 5),
                               bodies_order=("right", "left")))).history
    assert np.abs(a["contact0_fx"] + b["contact0_fx"]).max() < 1e-8 * REF
    assert np.allclose(a["total_energy"], b["total_energy"], rtol=1e-10)


def test_bars_of_different_materials_follow_seed_equation_5():
    stiff = {"name": "stiff", "model": "neo_hookean", "density": 7800.0,
             "youngs_modulus": 2.0e9, "poisson_ratio": 0.45}
    MB = Material(**stiff)
    za, zb = SEED.p_impedance, MB.p_impedance
    v_star = (za * V0 - zb * V0) / (za + zb)
    t_star = -za * zb * 2 * V0 / (za + zb)
    from impactfv.solver import FVSolver
    solver = FVSolver(load_case(two_bars(divisions=(100, 10), materials=(SEED_MATERIAL, stiff))))
    t, t_mid = 0.0, 4e-4 / (2 * V0) + 0.4 * 2 * L / MB.p_wave_speed
    while t < t_mid:
        dt = solver.stable_dt()
        solver.step(dt)
        t += dt
    c = solver.contact
    active = c.state > 0
    assert active.sum() >= 2 * 11 - 2
    assert c.vstar[active, 0].mean() == pytest.approx(v_star, rel=0.02)
    assert c.tstar_n[active].mean() == pytest.approx(t_star, rel=0.02)
    # the nodes at the interface move with it
    assert solver.v[active, 0].mean() == pytest.approx(v_star, rel=0.02)


def test_bar_against_rigid_wall():
    result = run(load_case(bar_on_wall(divisions=(100, 10))))
    hist = result.history
    t0, t1, plateau = pulse(hist, reference=REF)
    assert plateau == pytest.approx(REF, rel=0.02)
    assert t1 - t0 == pytest.approx(DURATION, rel=0.03)
    bar = body_momentum(result.bodies["bar"], SEED.density)[0] / (SEED.density * L * W)
    assert bar == pytest.approx(-V0, rel=0.03)
    assert np.nanmin(hist["contact0_gap"]) > -0.01 * L / 100
    assert np.all(np.diff(hist["total_energy"]) <= 0.0)


def test_stick_transfers_tangential_momentum_and_slip_does_not():
    """Oblique impact of free blocks: +-20 m/s normal, +-10 m/s tangential."""
    py = {}
    for model in ("slip", "stick"):
        case = two_bars(length=0.004, width=0.002, divisions=(40, 20), rollers=False,
                        model=model, tangential=10.0, v0=20.0, end_time=1e-5 + 6e-6)
        result = run(load_case(case))
        E = result.history["total_energy"]
        assert np.all(np.diff(E) <= 1e-12 * E[0])
        py[model] = body_momentum(result.bodies["left"], SEED.density)[1] / \
            (SEED.density * 0.004 * 0.002)
    # slip: the tangential velocity of each body is unchanged (the normal tilts a little as
    # the free corners bulge); stick: friction-like transfer slows the tangential motion
    assert py["slip"] == pytest.approx(10.0, rel=0.02)
    assert py["stick"] < 10.0 * 0.95


def test_contact_state_formulas():
    """Seed eq. (5)-(8) and the rigid-wall limit Z_B -> infinity."""
    zpA, zsA, zpB, zsB = 1.3e7, 1.3e6, 4.0e7, 6.0e6
    tn, ts, vn, vsA, vsB = contact_state(5.0, 1.0, -1e6, 2e5, -3.0, -2.0, -2e6, -1e5, 1.0, 0.0,
                                         zpA, zsA, zpB, zsB, True)
    assert vn == pytest.approx((zpA * 5 + zpB * -3 + (-2e6 + 1e6)) / (zpA + zpB))
    assert tn == pytest.approx((zpB * -1e6 + zpA * -2e6 + zpA * zpB * (-3 - 5)) / (zpA + zpB))
    assert vsA == vsB
    tn2, ts2, vn2, vsA2, vsB2 = contact_state(5.0, 1.0, -1e6, 2e5, -3.0, -2.0, -2e6, -1e5,
                                              1.0, 0.0, zpA, zsA, zpB, zsB, False)
    assert ts2 == 0.0 and tn2 == tn and vsA2 == pytest.approx(1.0 - 2e5 / zsA)
    wall = wall_state(5.0, 1.0, -1e6, 2e5, 1.0, 0.0, zpA, zsA, 0.0, 0.0, False)
    limit = contact_state(5.0, 1.0, -1e6, 2e5, 0.0, 0.0, -1e6, 0.0, 1.0, 0.0, zpA, zsA,
                          1e30, 1e30, False)
    assert wall[0] == pytest.approx(limit[0], rel=1e-9) and wall[2] == pytest.approx(0.0)


def test_overlapping_bodies_are_refused(tmp_path):
    case = two_bars(divisions=(20, 2), gap=-2e-4)  # the bars overlap by 0.2 mm
    with pytest.raises(InputError, match="overlap"):
        run(load_case(case))
    wall = bar_on_wall(divisions=(20, 2), gap=-1e-4)
    with pytest.raises(InputError, match="behind the wall"):
        run(load_case(wall))


def test_check_reports_overlap_and_run_exits_2(tmp_path):
    text = """
[run]
end_time = 1e-6
[[material]]
name = "copper"
density = 8930.0
youngs_modulus = 585.0e6
poisson_ratio = 0.495
[[body]]
name = "a"
material = "copper"
mesh = { generator = "rectangle", origin = [0.0, 0.0], size = [0.002, 0.001], divisions = [4, 2] }
[[body]]
name = "b"
material = "copper"
mesh = { generator = "rectangle", origin = [0.0015, 0.0], size = [0.002, 0.001], divisions = [4, 2] }
[[contact]]
bodies = ["a", "b"]
model = "stick"
"""
    path = tmp_path / "overlap.toml"
    path.write_text(text)
    check = run_cli("check", path)
    assert check.returncode == 0 and "PROBLEM" in check.stdout and "overlap" in check.stdout
    proc = run_cli("run", path, "-o", tmp_path / "out")
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1 and "overlap" in proc.stderr


def test_contact_outputs_in_history_and_fields(tmp_path):
    result = run(load_case(two_bars(divisions=(20, 2))), output_dir=tmp_path)
    header = (tmp_path / "history.csv").read_text().splitlines()[0].split(",")
    for col in ("contact0_fx", "contact0_fy", "contact0_gap"):
        assert col in header
    import meshio
    last = sorted(tmp_path.glob("fields_*.vtu"))[-2]  # a snapshot during contact
    data = meshio.read(last).point_data
    assert "contact_status" in data and "contact_pressure" in data
    assert result.history["contact0_gap"][0] == pytest.approx(4e-4, rel=1e-9)


def test_unknown_contact_region_is_an_input_error():
    case = two_bars(divisions=(10, 2))
    case["contact"][0]["regions"] = ["xmax", "xmin", "typo"]
    with pytest.raises(InputError, match=r"contact\[0\]\.regions: unknown region 'typo'"):
        load_case(case)
