"""The explicit two-stage TVD Runge-Kutta scheme (Heun), as a point function.

    U1      = U^n + dt R(U^n)
    U^{n+1} = U^n / 2 + (U1 + dt R(U1)) / 2

The same update serves both stages: alpha = 0 for the first, 1/2 for the second.
"""

from .materials import RHO, energy_second_derivative

STAGES = (0.0, 0.5)


def rk_stage(alpha, u0, u, dt, rate):
    """alpha u0 + (1 - alpha) (u + dt rate): one stage of the explicit TVD Runge-Kutta
    integrator (seed section 4)."""
    return alpha * u0 + (1.0 - alpha) * (u + dt * rate)


def heun_energy_excess(dt, props, omega, dv2, D, F):
    """The energy the two-stage step adds at a node beyond the Runge-Kutta mean of its stage
    energy rates. For an energy quadratic in the state u with Hessian M, the step
    u* = u0 + dt L0, u1 = (u0 + u* + dt L1) / 2 changes it by exactly

        dt/2 (grad E(u0) . L0 + grad E(u*) . L1) + dt^2/8 (L1 - L0) . M (L1 - L0),

    the last term returned here (docs/theory.md, "Energy balance"). The caller gives the
    change of the node's rates between the stages, L1 - L0 with L0 = (u* - u0) / dt: dv2 the
    squared change of the acceleration summed over the integrated (not held) components, D
    that of dF/dt (d x d). M is the mass rho omega for v and for F the elasticity tensor of
    the material at F (materials.energy_second_derivative), which the caller takes midway
    between u0 and u*: exact for linear elastic materials, for finite-strain ones to the
    third order in the step."""
    return 0.125 * dt * dt * omega * (props[RHO] * dv2 + energy_second_derivative(F, D, props))
