"""Acoustic Riemann solutions as small pure point functions (numerics.md B.3, B.4(b), E.2).

Waves along a spatial unit normal n: pressure waves at +-c_p and shear waves at +-c_s, each
carrying a jump [[t]] = -+ Z [[v]] with the impedance tensor
Z = rho c_p n(x)n + rho c_s (I - n(x)n). Everything is 2D and written with scalars so that the
same source compiles for any backend.
"""

import math


def spatial_normal(f11, f12, f21, f22, n1, n2):
    """Unit spatial normal n = F^-T N / |F^-T N| (F^-T N is parallel to cof(F) N)."""
    m1 = f22 * n1 - f21 * n2
    m2 = -f12 * n1 + f11 * n2
    s = math.sqrt(m1 * m1 + m2 * m2)
    return m1 / s, m2 / s


def impedance_times(zp, zs, n1, n2, w1, w2):
    """Z w with Z = zp n(x)n + zs (I - n(x)n)."""
    wn = n1 * w1 + n2 * w2
    return zs * w1 + (zp - zs) * wn * n1, zs * w2 + (zp - zs) * wn * n2


def interior_traction(tbar1, tbar2, dv1, dv2, zp, zs, n1, n2):
    """Upwind traction between two states of one material: t = tbar + Z [[v]] / 2.

    tbar is the average traction (P_a + P_b) N / 2 and [[v]] = v_b - v_a, N pointing a -> b.
    """
    z1, z2 = impedance_times(zp, zs, n1, n2, dv1, dv2)
    return tbar1 + 0.5 * z1, tbar2 + 0.5 * z2


def boundary_state(v1, v2, t1, t2, zp, zs, n1, n2, fix1, fix2, vs1, vs2, ts1, ts2):
    """State on a boundary face from the outgoing characteristic t^C - t = Z (v^C - v).

    (v, t) is the interior state (t = P N, outward). Each Cartesian component i is either a
    prescribed velocity (fix_i true, value vs_i) or a prescribed traction (value ts_i).
    Returns (vC1, vC2, tC1, tC2).
    """
    za, zb = impedance_times(zp, zs, n1, n2, 1.0, 0.0)   # first column of Z
    zc, zd = impedance_times(zp, zs, n1, n2, 0.0, 1.0)   # second column
    # unknowns dv = vC - v and dt = tC - t with dt = Z dv; one of (dv_i, dt_i) known per i
    if fix1 and fix2:
        dv1, dv2 = vs1 - v1, vs2 - v2
    elif fix1:
        dv1 = vs1 - v1
        dv2 = (ts2 - t2 - zb * dv1) / zd
    elif fix2:
        dv2 = vs2 - v2
        dv1 = (ts1 - t1 - zc * dv2) / za
    else:
        det = za * zd - zb * zc
        r1, r2 = ts1 - t1, ts2 - t2
        dv1 = (zd * r1 - zc * r2) / det
        dv2 = (-zb * r1 + za * r2) / det
    dt1 = za * dv1 + zc * dv2
    dt2 = zb * dv1 + zd * dv2
    return v1 + dv1, v2 + dv2, t1 + dt1, t2 + dt2
