"""Contact laws: the acoustic Riemann states at a contact interface (seed paper, eqs. 5-8),
as point functions in vector form, the same in 2D and 3D.

Body A is the "-" side, B the "+" side; n is the spatial unit normal from A into B. t^A and
t^B are the tractions of each body on a surface of normal n (sigma n with this same n on both
sides), so in contact t^A = t^B = t*. The characteristics carry t - Z_A v out of A and
t + Z_B v out of B (Z = rho c, p-wave impedance along n, s-wave impedance across it):

    t* - t^A =  Z_A (v* - v^A)        t* - t^B = -Z_B (v* - v^B)

which are the Rankine-Hugoniot conditions (seed eqs. 3-4) across the wave each body sends
back. The seed writes each body's traction with its own outward normal, t_n^R = -t_n^B here,
hence the signs of its eq. (5). Tangential vectors are v_t = v - (v . n) n.
"""

from ..tensors import dot


def normal_state(vnA, tnA, vnB, tnB, zpA, zpB):
    """Normal contact velocity and traction (seed eq. 5): continuity of both across the
    interface. Returns (v*_n, t*_n); t*_n < 0 is compression."""
    z = zpA + zpB
    vn = (zpA * vnA + zpB * vnB + tnB - tnA) / z
    tn = (zpB * tnA + zpA * tnB + zpA * zpB * (vnB - vnA)) / z
    return vn, tn


def stick_tangential(vtA, ttA, vtB, ttB, zsA, zsB, i):
    """Component i of the common tangential velocity and traction in stick (seed eq. 6)."""
    z = zsA + zsB
    vt = (zsA * vtA[i] + zsB * vtB[i] + ttB[i] - ttA[i]) / z
    tt = (zsB * ttA[i] + zsA * ttB[i] + zsA * zsB * (vtB[i] - vtA[i])) / z
    return vt, tt


def slip_tangential_velocity(vt, tt, zs, sign):
    """Tangential velocity of one body in slip (seed eq. 8): the tangential traction
    vanishes, so its shear characteristic gives v*_t = v_t - sign t_t / Z_s (sign +1 for A,
    -1 for B)."""
    return vt - sign * tt / zs


def releases(tn):
    """The contact surface cannot support tension (seed section 3): a tensile normal
    traction t*_n > 0 releases the contact, and each side becomes a free surface."""
    return tn > 0.0


def _tangential(u, n, un, out):
    for i in range(n.shape[0]):
        out[i] = u[i] - un * n[i]


def contact_state(vA, tA, vB, tB, n, zpA, zsA, zpB, zsB, stick, vtA, ttA, vtB, ttB,
                  vstarA, vstarB, tstar):
    """The contact state (seed eq. 7): t* = t*_n n + t*_t and each body's contact velocity
    v*^K = v*_n n + v*_t^K, with stick (eq. 6: v*_t common) or slip (eq. 8: t*_t = 0).

    Writes vstarA, vstarB and tstar; vtA .. ttB are scratch vectors. Returns t*_n.
    """
    vnA = dot(vA, n)
    vnB = dot(vB, n)
    tnA = dot(tA, n)
    tnB = dot(tB, n)
    vn, tn = normal_state(vnA, tnA, vnB, tnB, zpA, zpB)
    _tangential(vA, n, vnA, vtA)
    _tangential(vB, n, vnB, vtB)
    _tangential(tA, n, tnA, ttA)
    _tangential(tB, n, tnB, ttB)
    for i in range(n.shape[0]):
        if stick:
            vt, tt = stick_tangential(vtA, ttA, vtB, ttB, zsA, zsB, i)
            vstarA[i] = vn * n[i] + vt
            vstarB[i] = vn * n[i] + vt
            tstar[i] = tn * n[i] + tt
        else:
            vstarA[i] = vn * n[i] + slip_tangential_velocity(vtA[i], ttA[i], zsA, 1.0)
            vstarB[i] = vn * n[i] + slip_tangential_velocity(vtB[i], ttB[i], zsB, -1.0)
            tstar[i] = tn * n[i]
    return tn


def kinematic_velocity(v, t, tstar, n, zp, i):
    """Component i of the contact velocity of a body that enters its F equation and moves its
    contact nodes: v + n (n . (t* - t)) / Z_p, its own velocity corrected along the contact
    normal n by the jump from its traction t to the contact traction t* over its p-wave
    impedance Z_p = rho c_p / (da/dA) (v, t and t* in that body's own orientation: t, t*
    per unit spatial area on a surface of normal n out of it; the sign of n does not matter).

    Along n this is exactly the contact velocity v*_n of seed eq. 5 (t*_n - t_n =
    Z_p (v*_n - v_n) is the p characteristic). Across n the body keeps its own velocity: the
    tangential correction of eqs. 6/8, (t*_t - t_t) / (rho c_s), or the same over Z_p as
    used before, puts into F a rotation rate (tau (x) n) that the positions of the contact
    nodes never get; at the ends of a contact zone, where the nodal stress is not the face's,
    that turned F against the positions until the cells next to the corners folded
    (docs/contact.md). The tangential tractions of eqs. 6-8 still act in the momentum
    equation (stick, slip), and the tractions of eqs. 5-8 are unchanged.
    """
    jn = 0.0
    for k in range(n.shape[0]):
        jn += (tstar[k] - t[k]) * n[k]
    return v[i] + jn * n[i] / zp


def wall_state(vA, tA, n, zpA, zsA, wall_velocity, stick, vt, tt, vstar, tstar):
    """Body A against a rigid wall moving with ``wall_velocity``, n pointing into the wall:
    the limit Z_B -> infinity of the contact state of seed eq. 7. The wall imposes its normal velocity (and in
    stick its tangential velocity). Writes vstar and tstar; returns t*_n."""
    vnA = dot(vA, n)
    tnA = dot(tA, n)
    vnW = dot(wall_velocity, n)
    tn = tnA + zpA * (vnW - vnA)
    _tangential(vA, n, vnA, vt)
    _tangential(tA, n, tnA, tt)
    for i in range(n.shape[0]):
        if stick:
            vw = wall_velocity[i] - vnW * n[i]
            vstar[i] = vnW * n[i] + vw
            tstar[i] = tn * n[i] + tt[i] + zsA * (vw - vt[i])
        else:
            vstar[i] = vnW * n[i] + slip_tangential_velocity(vt[i], tt[i], zsA, 1.0)
            tstar[i] = tn * n[i]
    return tn
