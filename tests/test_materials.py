"""Point physics: P is the derivative of W, objectivity, sign conventions, wave speeds."""

import math

import numpy as np
import pytest

from impactfv.materials import (LINEAR_ELASTIC, NEO_HOOKEAN, Material, cauchy_stress, first_piola,
                                min_stretch, pressure_and_von_mises, strain_energy_density)

SEED = Material("copper", "neo_hookean", 8930.0, 585e6, 0.495)


@pytest.mark.parametrize("model", [NEO_HOOKEAN, LINEAR_ELASTIC])
def test_piola_is_derivative_of_energy(model):
    rng = np.random.default_rng(1)
    mu, lam, kappa = SEED.mu, SEED.lam, SEED.kappa
    for _ in range(5):
        F = np.eye(2) + 0.1 * rng.standard_normal((2, 2))
        P = np.array(first_piola(*F.ravel(), mu, lam, kappa, model)).reshape(2, 2)
        num = np.zeros((2, 2))
        h = 1e-7
        for i in range(2):
            for j in range(2):
                Fp, Fm = F.copy(), F.copy()
                Fp[i, j] += h
                Fm[i, j] -= h
                num[i, j] = (strain_energy_density(*Fp.ravel(), mu, lam, kappa, model)
                             - strain_energy_density(*Fm.ravel(), mu, lam, kappa, model)) / (2 * h)
        assert np.abs(P - num).max() < 1e-6 * np.abs(P).max()


def test_neo_hookean_is_objective_and_stress_free_at_rest():
    mu, lam, kappa = SEED.mu, SEED.lam, SEED.kappa
    assert np.allclose(first_piola(1.0, 0.0, 0.0, 1.0, mu, lam, kappa, NEO_HOOKEAN), 0.0,
                       atol=1e-6)
    F = np.array([[1.1, 0.2], [-0.05, 0.93]])
    c, s = math.cos(0.7), math.sin(0.7)
    R = np.array([[c, -s], [s, c]])
    P = np.array(first_piola(*F.ravel(), mu, lam, kappa, NEO_HOOKEAN)).reshape(2, 2)
    PR = np.array(first_piola(*(R @ F).ravel(), mu, lam, kappa, NEO_HOOKEAN)).reshape(2, 2)
    assert np.allclose(PR, R @ P, rtol=1e-12, atol=1e-6)
    assert min_stretch(*(R @ np.diag([0.9, 1.2])).ravel()) == pytest.approx(0.9)


def test_cauchy_is_push_forward_of_piola():
    F = np.array([[1.05, 0.1], [0.02, 0.97]])
    args = (SEED.mu, SEED.lam, SEED.kappa, NEO_HOOKEAN)
    P = np.array(first_piola(*F.ravel(), *args)).reshape(2, 2)
    s11, s12, s22, _ = cauchy_stress(*F.ravel(), *args)
    sigma = P @ F.T / np.linalg.det(F)
    assert np.allclose(sigma, [[s11, s12], [s12, s22]], rtol=1e-10)


def test_uniaxial_strain_matches_exact_neo_hookean_values():
    """numerics.md H.2: the shock of the seed bars has lambda* = 0.966397, P11 = -664.38 MPa.

    In uniaxial strain sigma11 = P11 F11 / J = P11 exactly (numerics.md's -687.48 MPa is
    P11 / lambda*, not the Cauchy stress). The state satisfies the Rankine-Hugoniot condition
    -rho U v0 = P11 with U = v0 / (1 - lambda*).
    """
    lam_star = 0.966397
    args = (SEED.mu, SEED.lam, SEED.kappa, NEO_HOOKEAN)
    P = first_piola(lam_star, 0.0, 0.0, 1.0, *args)
    s = cauchy_stress(lam_star, 0.0, 0.0, 1.0, *args)
    assert P[0] == pytest.approx(-664.38e6, rel=2e-4)
    assert s[0] == pytest.approx(P[0], rel=1e-12)
    U = 50.0 / (1 - lam_star)
    assert U == pytest.approx(1487.97, rel=2e-4)
    assert -SEED.density * U * 50.0 == pytest.approx(P[0], rel=2e-4)
    p, _ = pressure_and_von_mises(lam_star, 0.0, 0.0, 1.0, *args)
    assert p > 0  # compression is positive pressure


def test_seed_wave_speeds():
    assert SEED.p_wave_speed == pytest.approx(1487.6, abs=0.1)
    assert SEED.s_wave_speed == pytest.approx(148.0, abs=0.1)
    assert SEED.p_impedance * 50 == pytest.approx(664.2e6, rel=1e-3)
