"""Acoustic Riemann states at a contact interface (seed eqs. 5-8; numerics.md E.2, E.5).

Body A is the "-" side, B the "+" side; n is the spatial unit normal from A into B and
s = (-n2, n1) the tangent. Tractions are Cauchy tractions t = sigma n with this same n on
both sides. Characteristics: t - Z_A v is carried from A, t + Z_B v from B, so

    v*_n = (Z_pA v_n^A + Z_pB v_n^B + t_n^B - t_n^A) / (Z_pA + Z_pB)
    t*_n = (Z_pB t_n^A + Z_pA t_n^B + Z_pA Z_pB (v_n^B - v_n^A)) / (Z_pA + Z_pB)

and the same with the shear impedances for the tangential part when sticking. Slip has
t*_s = 0 and each body keeps its own tangential velocity v*_s = v_s -+ t_s / Z_s. A rigid
wall is the limit Z_B -> infinity. t*_n > 0 (tension) means the bodies separate.
"""


def contact_state(vA1, vA2, tA1, tA2, vB1, vB2, tB1, tB2, n1, n2, zpA, zsA, zpB, zsB, stick):
    """Returns (tn, ts, vn, vsA, vsB): normal and tangential traction and velocities."""
    s1, s2 = -n2, n1
    vnA = vA1 * n1 + vA2 * n2
    vnB = vB1 * n1 + vB2 * n2
    tnA = tA1 * n1 + tA2 * n2
    tnB = tB1 * n1 + tB2 * n2
    zp = zpA + zpB
    vn = (zpA * vnA + zpB * vnB + tnB - tnA) / zp
    tn = (zpB * tnA + zpA * tnB + zpA * zpB * (vnB - vnA)) / zp
    vsA = vA1 * s1 + vA2 * s2
    vsB = vB1 * s1 + vB2 * s2
    tsA = tA1 * s1 + tA2 * s2
    tsB = tB1 * s1 + tB2 * s2
    if stick:
        zs = zsA + zsB
        vs = (zsA * vsA + zsB * vsB + tsB - tsA) / zs
        ts = (zsB * tsA + zsA * tsB + zsA * zsB * (vsB - vsA)) / zs
        return tn, ts, vn, vs, vs
    return tn, 0.0, vn, vsA - tsA / zsA, vsB + tsB / zsB


def wall_state(vA1, vA2, tA1, tA2, n1, n2, zpA, zsA, wall1, wall2, stick):
    """Body A against a rigid wall moving with velocity (wall1, wall2); n points into the wall.

    Returns (tn, ts, vn, vsA)."""
    s1, s2 = -n2, n1
    vnA = vA1 * n1 + vA2 * n2
    tnA = tA1 * n1 + tA2 * n2
    vnW = wall1 * n1 + wall2 * n2
    tn = tnA + zpA * (vnW - vnA)
    vsA = vA1 * s1 + vA2 * s2
    tsA = tA1 * s1 + tA2 * s2
    if stick:
        vsW = wall1 * s1 + wall2 * s2
        return tn, tsA + zsA * (vsW - vsA), vnW, vsW
    return tn, 0.0, vnW, vsA - tsA / zsA
