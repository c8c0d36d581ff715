"""Acoustic Riemann point functions of the scheme (docs/theory.md, "Interface flux",
"Boundaries"), in 2D and 3D."""

import numpy as np
import pytest

from impactfv.physics.materials import LAW, N_PROPS, NEO_HOOKEAN
from impactfv.physics.riemann import (boundary_state, face_area_normal, face_traction,
                                     impedance_times, spatial_normal, upwind_traction,
                                     upwind_traction_area)

ZP, ZS = 1.3e7, 1.3e6


def unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def traction(tbar, dv, n):
    t = np.zeros(len(n))
    upwind_traction(np.asarray(tbar, float), np.asarray(dv, float), ZP, ZS, n, t)
    return t


@pytest.mark.parametrize("n", [unit([0.6, 0.8]), unit([0.3, -0.5, 0.8])])
def test_equal_states_give_the_physical_traction(n):
    tbar = np.arange(len(n)) + 5.0
    assert np.array_equal(traction(tbar, np.zeros(len(n)), n), tbar)


@pytest.mark.parametrize("n", [unit([0.6, 0.8]), unit([0.3, -0.5, 0.8])])
def test_upwind_term_follows_the_impedances(n):
    """A jump along n is resisted by rho c_p, one across n by rho c_s (each half)."""
    assert np.allclose(traction(np.zeros(len(n)), 2 * n, n), ZP * n)
    across = np.cross(n, [1.0, 0.0, 0.0])[:len(n)] if len(n) == 3 else np.array([-n[1], n[0]])
    across = unit(across)
    assert np.allclose(traction(np.zeros(len(n)), across, n), 0.5 * ZS * across)


@pytest.mark.parametrize("d", [2, 3])
def test_spatial_normal_is_nanson(d):
    rng = np.random.default_rng(2)
    F = np.eye(d) + 0.2 * rng.standard_normal((d, d))
    N = unit(rng.standard_normal(d))
    n = np.zeros(d)
    spatial_normal(F, N, n)
    assert np.allclose(n, unit(np.linalg.inv(F).T @ N), rtol=1e-12)


@pytest.mark.parametrize("d", [2, 3])
def test_the_area_vector_flux_is_the_unit_normal_flux_times_the_area(d):
    """The interior flux assembly works with a face's area vectors (m = cof(F) A, forces
    sigma m, impedances rho c |A|): the same force as the nominal traction of the unit-normal
    form (seed eq. 9a) times the reference area |A|."""
    rng = np.random.default_rng(7 + d)
    F = np.eye(d) + 0.2 * rng.standard_normal((d, d))
    S = rng.standard_normal((d, d))
    sigma_a, sigma_b = 1e6 * (S + S.T), 1e6 * (S @ S.T)
    dv = rng.standard_normal(d)
    N = unit(rng.standard_normal(d))
    area = 3.7e-4
    finite_strain = np.zeros(N_PROPS)
    finite_strain[LAW] = NEO_HOOKEAN
    m = np.zeros(d)
    inverse_m2 = face_area_normal(F, area * N, finite_strain, m)
    n = np.zeros(d)
    ratio = spatial_normal(F, N, n)          # da/dA
    assert np.allclose(m, area * ratio * n, rtol=1e-13)
    assert inverse_m2 * (area * ratio) ** 2 == pytest.approx(1.0, rel=1e-13)
    # the unit-normal form: mean nominal traction plus Z [[v]] / 2, times |A|
    ta, tb, t = np.zeros(d), np.zeros(d), np.zeros(d)
    face_traction(sigma_a, n, ratio, ta)
    face_traction(sigma_b, n, ratio, tb)
    upwind_traction(0.5 * (ta + tb), dv, ZP, ZS, n, t)
    # the area-vector form
    fa, fb, f = np.zeros(d), np.zeros(d), np.zeros(d)
    face_traction(sigma_a, m, 1.0, fa)
    face_traction(sigma_b, m, 1.0, fb)
    upwind_traction_area(0.5 * (fa + fb), dv, ZP * area, ZS * area, m, inverse_m2, f)
    assert np.allclose(f, area * t, rtol=1e-12, atol=1e-12 * np.abs(area * t).max())
    assert np.allclose(fb - fa, area * (tb - ta), rtol=1e-12,
                       atol=1e-12 * np.abs(area * (tb - ta)).max())


@pytest.mark.parametrize("fix", [(False, False), (True, False), (False, True), (True, True),
                                 (False, False, False), (True, False, True), (False, True, False)])
def test_boundary_state_meets_prescriptions_and_characteristic(fix):
    d = len(fix)
    rng = np.random.default_rng(len(fix) + sum(fix))
    F = np.eye(d) + 0.1 * rng.standard_normal((d, d))
    n = np.zeros(d)
    spatial_normal(F, unit(np.eye(d)[0] + 0.1), n)
    v, t = rng.standard_normal(d), 1e6 * rng.standard_normal(d)
    vs, ts = rng.standard_normal(d), 1e6 * rng.standard_normal(d)
    vC, tC = np.zeros(d), np.zeros(d)
    boundary_state(v, t, ZP, ZS, n, np.array(fix), vs, ts, np.zeros((d, d)), np.zeros(d), vC,
                   tC)
    for i in range(d):
        if fix[i]:
            assert vC[i] == pytest.approx(vs[i], rel=1e-14)
        else:
            assert tC[i] == pytest.approx(ts[i], rel=1e-12)
    # the outgoing characteristic: tC - t = Z (vC - v)
    Zdv = np.zeros(d)
    impedance_times(ZP, ZS, n, vC - v, Zdv)
    assert np.allclose(tC - t, Zdv, rtol=1e-10, atol=1e-6)


def test_smoothness_switch_factor():
    """switch_factor (docs/theory.md, "Smoothness switch"): 1 - chi where the reconstructed
    jump vanishes, rising continuously to 1 where the jump reaches SWITCH_RATIO times the
    nodal change, and 1 beyond it, also where the nodes agree but the reconstructions do not
    (a change of 0)."""
    from impactfv.physics.limiters import SWITCH_RATIO, switch_factor

    chi, change = 0.6, 2.0
    assert switch_factor(chi, 0.0, change**2) == pytest.approx(1.0 - chi)
    edge = (SWITCH_RATIO * change) ** 2
    assert switch_factor(chi, edge, change**2) == 1.0
    assert switch_factor(chi, 4.0 * edge, change**2) == 1.0
    assert switch_factor(chi, 0.999 * edge, change**2) == pytest.approx(1.0, abs=1e-3)
    assert switch_factor(chi, 0.5 * edge, change**2) == pytest.approx(1.0 - 0.5 * chi)
    assert switch_factor(chi, 1e-20, 0.0) == 1.0
