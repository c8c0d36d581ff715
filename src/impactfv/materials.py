"""Hyperelastic material laws in plane strain, as small pure point functions.

The point functions take and return scalars (no arrays, no numba specifics) so that the
same source can be compiled for a CPU loop (``numba.njit``) or, later, for a GPU.

Plane strain: the 3D deformation gradient is diag(F, 1) with F the 2x2 in-plane block;
J = det F and cof F = J F^-T = [[F22, -F21], [-F12, F11]].

Nearly incompressible neo-Hookean (numerics.md F, polyconvex split of Bonet et al.)::

    W = mu/2 J^(-2/3) (F:F + 1) - 3 mu/2 + kappa/2 (J - 1)^2
    P = mu J^(-2/3) F + [ -mu/3 J^(-5/3) (F:F + 1) + kappa (J - 1) ] cof F

Linear elastic (small strain, P = sigma)::

    eps = sym(F) - I,  sigma = lambda tr(eps) I + 2 mu eps,  sigma_zz = lambda tr(eps)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

NEO_HOOKEAN = 0
LINEAR_ELASTIC = 1
MODEL_IDS = {"neo_hookean": NEO_HOOKEAN, "linear_elastic": LINEAR_ELASTIC}

# Column layout of the material table the kernels read (one row per material).
RHO, MU, LAMBDA, KAPPA, CP, CS, MODEL = range(7)
N_PROPS = 7


@dataclass(frozen=True)
class Material:
    """An isotropic elastic material; SI units."""

    name: str
    model: str
    density: float
    youngs_modulus: float
    poisson_ratio: float

    @property
    def mu(self) -> float:
        return self.youngs_modulus / (2.0 * (1.0 + self.poisson_ratio))

    @property
    def lam(self) -> float:
        nu = self.poisson_ratio
        return nu * self.youngs_modulus / ((1.0 + nu) * (1.0 - 2.0 * nu))

    @property
    def kappa(self) -> float:
        return self.lam + 2.0 * self.mu / 3.0

    @property
    def p_wave_speed(self) -> float:
        """Reference dilatational speed sqrt((lambda + 2 mu)/rho)."""
        return math.sqrt((self.lam + 2.0 * self.mu) / self.density)

    @property
    def s_wave_speed(self) -> float:
        return math.sqrt(self.mu / self.density)

    @property
    def p_impedance(self) -> float:
        return self.density * self.p_wave_speed

    @property
    def model_id(self) -> int:
        return MODEL_IDS[self.model]

    def table_row(self) -> list[float]:
        return [self.density, self.mu, self.lam, self.kappa, self.p_wave_speed,
                self.s_wave_speed, float(self.model_id)]


# --------------------------------------------------------------------------- point functions

def first_piola(f11, f12, f21, f22, mu, lam, kappa, model):
    """First Piola-Kirchhoff stress P(F) in plane strain. Returns (P11, P12, P21, P22)."""
    if model == LINEAR_ELASTIC:
        e11 = f11 - 1.0
        e22 = f22 - 1.0
        e12 = 0.5 * (f12 + f21)
        tr = e11 + e22
        return (lam * tr + 2.0 * mu * e11, 2.0 * mu * e12,
                2.0 * mu * e12, lam * tr + 2.0 * mu * e22)
    J = f11 * f22 - f12 * f21
    ff = f11 * f11 + f12 * f12 + f21 * f21 + f22 * f22 + 1.0
    a = mu * J ** (-2.0 / 3.0)
    b = -mu / 3.0 * J ** (-5.0 / 3.0) * ff + kappa * (J - 1.0)
    return (a * f11 + b * f22, a * f12 - b * f21, a * f21 - b * f12, a * f22 + b * f11)


def strain_energy_density(f11, f12, f21, f22, mu, lam, kappa, model):
    """Stored energy per unit reference volume W(F)."""
    if model == LINEAR_ELASTIC:
        e11 = f11 - 1.0
        e22 = f22 - 1.0
        e12 = 0.5 * (f12 + f21)
        tr = e11 + e22
        return 0.5 * lam * tr * tr + mu * (e11 * e11 + e22 * e22 + 2.0 * e12 * e12)
    J = f11 * f22 - f12 * f21
    ff = f11 * f11 + f12 * f12 + f21 * f21 + f22 * f22 + 1.0
    return 0.5 * mu * J ** (-2.0 / 3.0) * ff - 1.5 * mu + 0.5 * kappa * (J - 1.0) ** 2


def cauchy_stress(f11, f12, f21, f22, mu, lam, kappa, model):
    """Cauchy stress in plane strain. Returns (s11, s12, s22, s33)."""
    if model == LINEAR_ELASTIC:
        e11 = f11 - 1.0
        e22 = f22 - 1.0
        e12 = 0.5 * (f12 + f21)
        tr = e11 + e22
        return (lam * tr + 2.0 * mu * e11, 2.0 * mu * e12, lam * tr + 2.0 * mu * e22, lam * tr)
    J = f11 * f22 - f12 * f21
    b11 = f11 * f11 + f12 * f12
    b12 = f11 * f21 + f12 * f22
    b22 = f21 * f21 + f22 * f22
    trb = b11 + b22 + 1.0
    c = mu * J ** (-5.0 / 3.0)
    p = kappa * (J - 1.0)
    return (c * (b11 - trb / 3.0) + p, c * b12, c * (b22 - trb / 3.0) + p,
            c * (1.0 - trb / 3.0) + p)


def pressure_and_von_mises(f11, f12, f21, f22, mu, lam, kappa, model):
    """Mean pressure -tr(sigma)/3 (compression positive, sigma_zz included) and von Mises."""
    s11, s12, s22, s33 = cauchy_stress(f11, f12, f21, f22, mu, lam, kappa, model)
    p = -(s11 + s22 + s33) / 3.0
    vm = math.sqrt(max(0.5 * ((s11 - s22) ** 2 + (s22 - s33) ** 2 + (s33 - s11) ** 2)
                       + 3.0 * s12 * s12, 0.0))
    return p, vm


def min_stretch(f11, f12, f21, f22):
    """Smallest principal stretch sqrt(min eig(F^T F)), capped at 1 (out-of-plane stretch)."""
    c11 = f11 * f11 + f21 * f21
    c12 = f11 * f12 + f21 * f22
    c22 = f12 * f12 + f22 * f22
    half_tr = 0.5 * (c11 + c22)
    disc = math.sqrt(max(0.25 * (c11 - c22) ** 2 + c12 * c12, 0.0))
    lam_min2 = half_tr - disc
    if lam_min2 <= 0.0:
        return 0.0
    return min(math.sqrt(lam_min2), 1.0)
