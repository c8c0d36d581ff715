"""The explicit two-stage TVD Runge-Kutta scheme (Heun), as a point function.

    U1      = U^n + dt R(U^n)
    U^{n+1} = U^n / 2 + (U1 + dt R(U1)) / 2

The same update serves both stages: alpha = 0 for the first, 1/2 for the second.
"""

STAGES = (0.0, 0.5)


def rk_stage(alpha, u0, u, dt, rate):
    """alpha u0 + (1 - alpha) (u + dt rate): one stage of the explicit TVD Runge-Kutta
    integrator (seed section 4)."""
    return alpha * u0 + (1.0 - alpha) * (u + dt * rate)
