"""Acoustic Riemann point functions (numerics.md B.3, B.4(b))."""

import numpy as np
import pytest

from impactfv.scheme.riemann import boundary_state, interior_traction, spatial_normal

ZP, ZS = 1.3e7, 1.3e6


def test_equal_states_give_the_physical_traction():
    t = interior_traction(5.0, -3.0, 0.0, 0.0, ZP, ZS, 0.6, 0.8)
    assert t == (5.0, -3.0)


def test_upwind_term_follows_the_impedances():
    n = (0.6, 0.8)
    dv_normal = (2 * 0.6, 2 * 0.8)
    t = interior_traction(0.0, 0.0, *dv_normal, ZP, ZS, *n)
    assert np.allclose(t, (ZP * 0.6, ZP * 0.8))
    dv_tangent = (-0.8, 0.6)
    t = interior_traction(0.0, 0.0, *dv_tangent, ZP, ZS, *n)
    assert np.allclose(t, (-0.5 * ZS * 0.8, 0.5 * ZS * 0.6))


@pytest.mark.parametrize("fix", [(False, False), (True, False), (False, True), (True, True)])
def test_boundary_state_meets_prescriptions_and_characteristic(fix):
    n = spatial_normal(1.1, 0.1, -0.05, 0.95, 1.0, 0.0)
    v, t = (1.0, -2.0), (3.0e6, 1.0e6)
    vs, ts = (0.5, -0.25), (-1.0e6, 2.0e6)
    vc1, vc2, tc1, tc2 = boundary_state(*v, *t, ZP, ZS, *n, *fix, *vs, *ts)
    for i, (vc, tc) in enumerate(((vc1, tc1), (vc2, tc2))):
        if fix[i]:
            assert vc == pytest.approx(vs[i])
        else:
            assert tc == pytest.approx(ts[i])
    # outgoing characteristic: tC - t = Z (vC - v)
    n = np.array(n)
    Z = ZP * np.outer(n, n) + ZS * (np.eye(2) - np.outer(n, n))
    assert np.allclose(np.array([tc1, tc2]) - t, Z @ (np.array([vc1, vc2]) - v), rtol=1e-10)
