"""The explicit two-stage TVD Runge-Kutta scheme (Heun), as a point function.

    U1      = U^n + dt R(U^n)
    U^{n+1} = U^n / 2 + (U1 + dt R(U1)) / 2

The same update serves both stages: alpha = 0 for the first, 1/2 for the second.
"""

from ..materials import LAMBDA, MU, RHO

STAGES = (0.0, 0.5)


def rk_stage(alpha, u0, u, dt, rate):
    """alpha u0 + (1 - alpha) (u + dt rate): one stage of the explicit TVD Runge-Kutta
    integrator (seed section 4)."""
    return alpha * u0 + (1.0 - alpha) * (u + dt * rate)


def heun_energy_excess(a, dt, props, omega, fixed_mask, v0, v, force, F0, F, dF):
    """The energy the two-stage step adds at node a beyond the Runge-Kutta mean of its stage
    energy rates. For an energy quadratic in the state u with Hessian M, the step
    u* = u0 + dt L0, u1 = (u0 + u* + dt L1) / 2 changes it by exactly

        dt/2 (grad E(u0) . L0 + grad E(u*) . L1) + dt^2/8 (L1 - L0) . M (L1 - L0),

    the last term returned here (docs/theory.md, "Energy balance"). Called at the last stage
    before its update: v, F are u*, L0 = (u* - u0) / dt and L1 = (force / mass, dF / omega)
    the rates just assembled. M is the mass for v (held components, which are imposed and not
    integrated, left out) and for F the small-strain elasticity omega (lambda (tr D)^2 +
    2 mu |sym D|^2): exact for linear elastic materials, the small-strain limit of the
    neo-Hookean Hessian."""
    d = v.shape[1]
    inv_dt = 1.0 / dt
    mass = props[RHO] * omega
    kinetic = 0.0
    for i in range(d):
        if not fixed_mask[a, i]:
            change = force[a, i] / mass - (v[a, i] - v0[a, i]) * inv_dt
            kinetic += change * change
    trace = 0.0
    sym2 = 0.0
    for i in range(d):
        for J in range(d):
            D = dF[a, i, J] / omega - (F[a, i, J] - F0[a, i, J]) * inv_dt
            DT = dF[a, J, i] / omega - (F[a, J, i] - F0[a, J, i]) * inv_dt
            sym2 += 0.25 * (D + DT) * (D + DT)
            if i == J:
                trace += D
    strain = props[LAMBDA] * trace * trace + 2.0 * props[MU] * sym2
    return 0.125 * dt * dt * (mass * kinetic + omega * strain)
