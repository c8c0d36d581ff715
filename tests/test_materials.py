"""Material laws: P is the derivative of W, objectivity, sign conventions, wave speeds, in
plane strain and in 3D."""

import math

import numpy as np
import pytest
from conftest import COPPER, material

from impactfv.physics.materials import (LINEAR_ELASTIC, NEO_HOOKEAN, cauchy_stress,
                                energy_second_derivative, first_piola, min_stretch,
                                pressure_and_von_mises, strain_energy_density)

SEED = material(COPPER)


def props(law):
    row = np.array(SEED.table_row())
    row[-1] = law
    return row


def piola(F, law=NEO_HOOKEAN):
    P = np.zeros_like(F)
    first_piola(F, props(law), P)
    return P


def cauchy(F, law=NEO_HOOKEAN):
    sigma = np.zeros_like(F)
    s_zz = cauchy_stress(F, props(law), sigma)
    return sigma, s_zz


def rotation(d, angle):
    c, s = math.cos(angle), math.sin(angle)
    if d == 2:
        return np.array([[c, -s], [s, c]])
    axis = np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + s * K + (1 - c) * K @ K


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("law", [NEO_HOOKEAN, LINEAR_ELASTIC])
def test_piola_is_derivative_of_energy(law, d):
    rng = np.random.default_rng(1)
    for _ in range(5):
        F = np.eye(d) + 0.1 * rng.standard_normal((d, d))
        P = piola(F, law)
        num = np.zeros((d, d))
        h = 1e-7
        for i in range(d):
            for j in range(d):
                Fp, Fm = F.copy(), F.copy()
                Fp[i, j] += h
                Fm[i, j] -= h
                num[i, j] = (strain_energy_density(Fp, props(law))
                             - strain_energy_density(Fm, props(law))) / (2 * h)
        assert np.abs(P - num).max() < 1e-6 * np.abs(P).max()


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("law", [NEO_HOOKEAN, LINEAR_ELASTIC])
def test_elasticity_is_the_second_derivative_of_energy(law, d):
    """D : A(F) : D (the energy norm of Heun's excess, docs/theory.md "Energy balance") is
    the derivative of P(F + e D) : D in e, at large strain too (F - I of order 0.3), and for
    the linear law lambda (tr D)^2 + 2 mu |sym D|^2 whatever F."""
    rng = np.random.default_rng(2)
    for _ in range(5):
        F = np.eye(d) + 0.3 * rng.standard_normal((d, d))
        if np.linalg.det(F) < 0.2:
            continue
        D = rng.standard_normal((d, d))
        h = 1e-6
        num = np.sum((piola(F + h * D, law) - piola(F - h * D, law)) * D) / (2 * h)
        exact = energy_second_derivative(F, D, props(law))
        assert exact == pytest.approx(num, rel=1e-6)
        if law == LINEAR_ELASTIC:
            sym = 0.5 * (D + D.T)
            assert exact == pytest.approx(SEED.lam * np.trace(D) ** 2
                                          + 2 * SEED.mu * np.sum(sym * sym), rel=1e-13)


@pytest.mark.parametrize("d", [2, 3])
def test_neo_hookean_is_objective_and_stress_free_at_rest(d):
    assert np.abs(piola(np.eye(d))).max() < 1e-6
    F = np.eye(d) + 0.1 * np.arange(d * d).reshape(d, d) / (d * d) - 0.05
    R = rotation(d, 0.7)
    assert np.allclose(piola(R @ F), R @ piola(F), rtol=1e-12, atol=1e-6)
    stretches = np.diag([0.9, 1.2, 1.05][:d])
    assert min_stretch(R @ stretches) == pytest.approx(0.9, rel=1e-12)


def test_plane_strain_is_the_3d_law_with_unit_out_of_plane_stretch():
    F2 = np.array([[1.05, 0.1], [0.02, 0.97]])
    F3 = np.eye(3)
    F3[:2, :2] = F2
    P2, P3 = piola(F2), piola(F3)
    assert np.allclose(P2, P3[:2, :2], rtol=1e-12)
    s2, s_zz = cauchy(F2)
    s3, _ = cauchy(F3)
    assert np.allclose(s2, s3[:2, :2], rtol=1e-12) and s_zz == pytest.approx(s3[2, 2])
    assert strain_energy_density(F2, props(NEO_HOOKEAN)) == pytest.approx(
        strain_energy_density(F3, props(NEO_HOOKEAN)), rel=1e-12)


@pytest.mark.parametrize("d", [2, 3])
def test_cauchy_is_push_forward_of_piola(d):
    F = np.eye(d) + 0.04 * np.cos(np.arange(d * d)).reshape(d, d)
    sigma, _ = cauchy(F)
    assert np.allclose(sigma, piola(F) @ F.T / np.linalg.det(F), rtol=1e-10)


def test_uniaxial_strain_matches_exact_neo_hookean_values():
    """The shock of the seed bars (docs/theory.md, "Validation"): lambda* = 0.966397,
    P11 = -664.38 MPa. In uniaxial strain sigma11 = P11 F11 / J = P11 exactly. The state
    satisfies the Rankine-Hugoniot condition -rho U v0 = P11 with U = v0 / (1 - lambda*)."""
    lam_star = 0.966397
    F = np.diag([lam_star, 1.0])
    P = piola(F)
    sigma, _ = cauchy(F)
    assert P[0, 0] == pytest.approx(-664.38e6, rel=2e-4)
    assert sigma[0, 0] == pytest.approx(P[0, 0], rel=1e-12)
    U = 50.0 / (1 - lam_star)
    assert U == pytest.approx(1487.97, rel=2e-4)
    assert -SEED.density * U * 50.0 == pytest.approx(P[0, 0], rel=2e-4)
    p, _, _ = pressure_and_von_mises(F, props(NEO_HOOKEAN), np.zeros((2, 2)))
    assert p > 0  # compression is positive pressure


@pytest.mark.parametrize("d", [2, 3])
def test_von_mises_of_pure_shear(d):
    """Small shear gamma of a linear solid: von Mises = sqrt(3) mu gamma, pressure 0."""
    gamma = 1e-4
    F = np.eye(d)
    F[0, 1] = gamma
    p, vm, _ = pressure_and_von_mises(F, props(LINEAR_ELASTIC), np.zeros((d, d)))
    assert vm == pytest.approx(math.sqrt(3) * SEED.mu * gamma, rel=1e-9)
    assert abs(p) < 1e-9 * SEED.mu * gamma


def test_seed_wave_speeds():
    assert SEED.p_wave_speed == pytest.approx(1487.6, abs=0.1)
    assert SEED.s_wave_speed == pytest.approx(148.0, abs=0.1)
    assert SEED.p_impedance * 50 == pytest.approx(664.2e6, rel=1e-3)
