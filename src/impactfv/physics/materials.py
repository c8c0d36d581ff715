"""Material laws: hyperelastic stress and energy as small point functions of F.

The point functions take the deformation gradient ``F`` (a d x d array, d = 2 for plane
strain or 3) and ``props``, one row of the material table (columns RHO .. LAW below); they
never allocate, so the same source compiles for a CPU loop (numba) or a GPU.

Plane strain (d = 2): the 3D deformation gradient is diag(F, 1), so J = det F, the
out-of-plane stretch is 1 and F3:F3 = F:F + 1. Written with ``F:F + (3 - d)`` the same
formula serves both dimensions.

Nearly incompressible neo-Hookean (the polyconvex split of Bonet et al.; docs/theory.md)::

    W = mu/2 J^(-2/3) F3:F3 - 3 mu/2 + kappa/2 (J - 1)^2
    P = mu J^(-2/3) F + [ -mu/3 J^(-5/3) F3:F3 + kappa (J - 1) ] cof F

Linear elastic (small strain, P = sigma)::

    eps = sym(F) - I,  sigma = lambda tr(eps) I + 2 mu eps   (plane strain: sigma_zz = lambda tr eps)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .tensors import (cofactor_entry, determinant, smallest_stretch_squared,
                      smallest_stretch_squared_bounds, stress_power)

NEO_HOOKEAN = 0
LINEAR_ELASTIC = 1
LAW_IDS = {"neo_hookean": NEO_HOOKEAN, "linear_elastic": LINEAR_ELASTIC}

# Columns of the material table the kernels read (one row per material).
RHO, MU, LAMBDA, KAPPA, CP, CS, LAW = range(7)
N_PROPS = 7


@dataclass(frozen=True)
class Material:
    """An isotropic elastic material; SI units. ``law`` is the material law's name."""

    name: str
    law: str
    density: float
    youngs_modulus: float
    poisson_ratio: float

    @classmethod
    def from_entry(cls, entry: dict) -> "Material":
        """From a ``[[material]]`` entry of a case (its ``model`` key names the law)."""
        return cls(entry["name"], entry.get("model", "neo_hookean"), entry["density"],
                   entry["youngs_modulus"], entry["poisson_ratio"])

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
    def s_impedance(self) -> float:
        return self.density * self.s_wave_speed

    def table_row(self) -> list[float]:
        return [self.density, self.mu, self.lam, self.kappa, self.p_wave_speed,
                self.s_wave_speed, float(LAW_IDS[self.law])]


# --------------------------------------------------------------------------- point functions

def strain_power(sigma, F, D, props):
    """P : D, the power of a deformation-gradient rate D for the Cauchy stress sigma at F:
    P = sigma cof F for finite-strain laws (tensors.stress_power), P = sigma for the
    small-strain law, whose energy is a function of sym(F) - I (the energy balance,
    docs/theory.md)."""
    if int(props[LAW]) == LINEAR_ELASTIC:
        d = F.shape[0]
        power = 0.0
        for i in range(d):
            for J in range(d):
                power += sigma[i, J] * D[i, J]
        return power
    return stress_power(sigma, F, D)


def small_strain(props):
    """True for laws posed in the reference configuration (linear elastic: P = sigma(eps)),
    whose faces keep their reference normal and area."""
    return int(props[LAW]) == LINEAR_ELASTIC


def _squared_norm_3d(F):
    """F3:F3 of the 3D deformation gradient (plane strain adds the out-of-plane 1)."""
    d = F.shape[0]
    s = 0.0
    for i in range(d):
        for J in range(d):
            s += F[i, J] * F[i, J]
    return s + (3 - d)


def _linear_stress_tensor(F, props, out):
    """Small-strain stress of the linear elastic law into out (d x d), the same for P and
    sigma at this order; returns tr(F - I)."""
    d = F.shape[0]
    tr = 0.0
    for i in range(d):
        tr += F[i, i] - 1.0
    for i in range(d):
        for J in range(d):
            out[i, J] = _linear_stress(F, i, J, tr, props[LAMBDA], props[MU])
    return tr


def first_piola(F, props, P):
    """First Piola-Kirchhoff stress P(F) of the momentum equation (seed eq. 1a), written
    into P (d x d)."""
    d = F.shape[0]
    mu = props[MU]
    if int(props[LAW]) == LINEAR_ELASTIC:
        _linear_stress_tensor(F, props, P)
        return
    J_ = determinant(F)
    # one power for both: J^(-5/3) = J^(-2/3) / J
    j23 = J_ ** (-2.0 / 3.0)
    a = mu * j23
    b = -mu / 3.0 * (j23 / J_) * _squared_norm_3d(F) + props[KAPPA] * (J_ - 1.0)
    for i in range(d):
        for J in range(d):
            P[i, J] = a * F[i, J] + b * cofactor_entry(F, i, J)


def _small_strain(F, i, J):
    return 0.5 * (F[i, J] + F[J, i]) - (1.0 if i == J else 0.0)


def _linear_energy(G, identity, props):
    """lambda/2 tr(E)^2 + mu E:E with E = sym(G) - identity I: the linear elastic energy of
    F = G (identity = 1), or of the displacement gradient G (identity = 0)."""
    d = G.shape[0]
    tr = 0.0
    ee = 0.0
    for i in range(d):
        tr += G[i, i] - identity
        for J in range(d):
            ee += (0.5 * (G[i, J] + G[J, i]) - (identity if i == J else 0.0)) ** 2
    return 0.5 * props[LAMBDA] * tr * tr + props[MU] * ee


def _linear_stress(F, i, J, tr, lam, mu):
    """sigma_iJ = lambda tr(eps) delta_iJ + 2 mu eps_iJ (small strain)."""
    return (lam * tr if i == J else 0.0) + 2.0 * mu * _small_strain(F, i, J)


def strain_energy_density(F, props):
    """Stored energy per unit reference volume W(F), whose derivative is the P of seed
    eq. 1a."""
    mu = props[MU]
    if int(props[LAW]) == LINEAR_ELASTIC:
        return _linear_energy(F, 1.0, props)
    J_ = determinant(F)
    return (0.5 * mu * J_ ** (-2.0 / 3.0) * _squared_norm_3d(F) - 1.5 * mu
            + 0.5 * props[KAPPA] * (J_ - 1.0) ** 2)


def energy_second_derivative(F, D, props):
    """D : A(F) : D = d^2/de^2 W(F + e D) at e = 0, the second derivative of the stored
    energy along the direction D (d x d), A = d^2 W / dF dF the elasticity tensor. Linear
    elastic: lambda (tr D)^2 + 2 mu |sym D|^2. Neo-Hookean, with M = adj(F) D (so that
    dJ/de = tr M and d^2J/de^2 = ((tr M)^2 - tr(M^2)) / J), S = F3 : F3 and f = J^(-2/3):

        mu/2 (f'' S + 2 f' S' + 2 f D:D) + kappa (J'^2 + (J - 1) J'')

    with S' = 2 F:D, f' = -2/3 J^(-5/3) J', f'' = 10/9 J^(-8/3) J'^2 - 2/3 J^(-5/3) J''."""
    d = F.shape[0]
    mu = props[MU]
    if int(props[LAW]) == LINEAR_ELASTIC:
        # the energy is quadratic in F - I: its second derivative along D is twice its value
        # at F - I = D
        return 2.0 * _linear_energy(D, 0.0, props)
    J_ = determinant(F)
    # M = adj(F) D, adj(F)_ik = (cof F)_ki; tr M and tr(M^2)
    trM = 0.0
    trM2 = 0.0
    for i in range(d):
        for j in range(d):
            mij = 0.0
            mji = 0.0
            for k in range(d):
                mij += cofactor_entry(F, k, i) * D[k, j]
                mji += cofactor_entry(F, k, j) * D[k, i]
            trM2 += mij * mji
            if i == j:
                trM += mij
    dJ = trM
    d2J = (trM * trM - trM2) / J_
    FD = 0.0
    DD = 0.0
    for i in range(d):
        for J in range(d):
            FD += F[i, J] * D[i, J]
            DD += D[i, J] * D[i, J]
    f = J_ ** (-2.0 / 3.0)
    f1 = -2.0 / 3.0 * f / J_ * dJ
    f2 = 10.0 / 9.0 * f / (J_ * J_) * dJ * dJ - 2.0 / 3.0 * f / J_ * d2J
    S = _squared_norm_3d(F)
    return (0.5 * mu * (f2 * S + 4.0 * f1 * FD + 2.0 * f * DD)
            + props[KAPPA] * (dJ * dJ + (J_ - 1.0) * d2J))


def _neo_hookean_cauchy_stress(F, props, sigma):
    """sigma = mu J^(-5/3) dev(b) + kappa (J - 1) I with b = F F^T (b3 = diag(b, 1) in 2D)
    into sigma; returns (J, J^(-5/3), tr b3, kappa (J - 1)) for the callers' other
    quantities."""
    d = F.shape[0]
    for i in range(d):
        for k in range(d):
            b = 0.0
            for J in range(d):
                b += F[i, J] * F[k, J]
            sigma[i, k] = b
    trb = 0.0
    for i in range(d):
        trb += sigma[i, i]
    trb += 3.0 - d
    J_ = determinant(F)
    j53 = J_ ** (-5.0 / 3.0)
    c = props[MU] * j53
    p = props[KAPPA] * (J_ - 1.0)
    for i in range(d):
        for k in range(d):
            if i == k:
                sigma[i, k] = c * (sigma[i, k] - trb / 3.0) + p
            else:
                sigma[i, k] = c * sigma[i, k]
    return J_, j53, trb, p


def cauchy_stress(F, props, sigma):
    """Cauchy stress sigma = P F^T / J of the material law (seed eq. 1a) into sigma (d x d);
    returns the out-of-plane normal stress sigma_zz of plane strain (0 when d = 3, where
    sigma holds it)."""
    d = F.shape[0]
    if int(props[LAW]) == LINEAR_ELASTIC:
        tr = _linear_stress_tensor(F, props, sigma)
        return props[LAMBDA] * tr if d == 2 else 0.0
    _, j53, trb, p = _neo_hookean_cauchy_stress(F, props, sigma)
    return props[MU] * j53 * (1.0 - trb / 3.0) + p if d == 2 else 0.0


def cauchy_stress_and_energy(F, props, sigma):
    """:func:`cauchy_stress` into sigma, and returns :func:`strain_energy_density` of the same
    F, with one power of J for both (J^(-2/3) = J J^(-5/3)): the stress exactly as
    cauchy_stress gives it, the energy equal to strain_energy_density's to round-off."""
    if int(props[LAW]) == LINEAR_ELASTIC:
        cauchy_stress(F, props, sigma)
        return strain_energy_density(F, props)
    J_, j53, trb, _ = _neo_hookean_cauchy_stress(F, props, sigma)
    mu = props[MU]
    # tr(b3) = F3 : F3 (plane strain adds the out-of-plane 1), as strain_energy_density
    return 0.5 * mu * (j53 * J_) * trb - 1.5 * mu + 0.5 * props[KAPPA] * (J_ - 1.0) ** 2


def pressure_and_von_mises(F, props, sigma):
    """Mean pressure -tr(sigma)/3 (compression positive; plane strain includes sigma_zz), the
    von Mises stress, and sigma_zz of plane strain (0 in 3D); the Cauchy stress into
    ``sigma`` (d x d)."""
    d = F.shape[0]
    s_zz = cauchy_stress(F, props, sigma)
    tr = 0.0
    for i in range(d):
        tr += sigma[i, i]
    tr += s_zz
    p = -tr / 3.0
    # von Mises = sqrt(3 J2) = sqrt(3/2 s:s), s the deviator of the 3D stress
    ss = 0.0
    for i in range(d):
        for k in range(d):
            ss += (sigma[i, k] - (tr / 3.0 if i == k else 0.0)) ** 2
    if d == 2:
        ss += (s_zz - tr / 3.0) ** 2
    return p, math.sqrt(max(1.5 * ss, 0.0)), s_zz


#: slack of min_stretch_bounds, as a fraction of the mean eigenvalue q of C, on both bounds
#: of lambda_min^2: more than the rounding of q - 2p and of min_stretch's own trigonometric
#: solution (whose arccosine near +-1 loses half the digits: up to about 4e-8 q), which for
#: strongly compressed nodes is far more than a relative margin on lambda_min itself
STRETCH_BOUND_SLACK = 1e-6


def min_stretch_bounds(F):
    """(lo, hi) with lo <= min_stretch(F) <= hi, as computed, in 3D from bounds on the
    smallest eigenvalue of C (tensors.smallest_stretch_squared_bounds), each widened by
    STRETCH_BOUND_SLACK q, without the trigonometric solution: what the smallest time step
    over many nodes needs to skip the nodes that cannot give it."""
    lo2, hi2, q = smallest_stretch_squared_bounds(F)
    slack = STRETCH_BOUND_SLACK * abs(q)
    lo2 -= slack
    lo = math.sqrt(lo2) if lo2 > 0.0 else 0.0
    return lo, math.sqrt(max(hi2 + slack, 0.0))


def min_stretch(F):
    """Smallest principal stretch sqrt(min eig(F^T F)); in plane strain capped at 1 (the
    out-of-plane stretch)."""
    lam2 = smallest_stretch_squared(F)
    if lam2 <= 0.0:
        return 0.0
    if F.shape[0] == 2:
        return min(math.sqrt(lam2), 1.0)
    return math.sqrt(lam2)
