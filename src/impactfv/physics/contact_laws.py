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

import math

from .tensors import dot


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


def sliding_tangential_velocity(vt, tt, tt_star, zs, sign):
    """Tangential velocity of one body sliding under the tangential contact traction t*_t:
    its shear characteristic t*_t - t_t = sign Z_s (v*_t - v_t) (sign +1 for A, -1 for B).
    With t*_t = 0 this is the slip velocity of seed eq. 8."""
    return vt + sign * (tt_star - tt) / zs


def friction_scale(tt_norm, tn, mu):
    """Coulomb's law on the stick trial state (Kozdon, Dunham and Nordstrom 2012, on the
    Riemann problem of a frictional interface): the factor by which the trial tangential
    traction of seed eq. 6 is scaled, 1 if it does not exceed mu times the contact pressure
    -t*_n (stick), mu (-t*_n) / |t_t| if it does (the bodies slide, the traction stays on the
    Coulomb limit along the trial direction). mu = inf is stick, mu = 0 slip."""
    if mu == math.inf:
        return 1.0
    limit = mu * max(-tn, 0.0)
    if tt_norm <= limit:
        return 1.0
    return limit / tt_norm


def releases(tn):
    """The contact surface cannot support tension (seed section 3): a tensile normal
    traction t*_n > 0 releases the contact, and each side becomes a free surface."""
    return tn > 0.0


def _tangential(u, n, un, out):
    for i in range(n.shape[0]):
        out[i] = u[i] - un * n[i]


def contact_state(vA, tA, vB, tB, n, zpA, zsA, zpB, zsB, mu, vtA, ttA, vtB, ttB,
                  vstarA, vstarB, tstar):
    """The contact state (seed eq. 7): t* = t*_n n + t*_t and each body's contact velocity
    v*^K = v*_n n + v*_t^K, with the friction coefficient mu: stick (mu = inf, eq. 6: v*_t
    common), slip (mu = 0, eq. 8: t*_t = 0), or Coulomb friction (friction_scale: the stick
    trial traction capped at mu (-t*_n), each body's tangential velocity then from its own
    shear characteristic, sliding_tangential_velocity).

    Writes vstarA, vstarB and tstar; vtA .. ttB are scratch vectors. Returns (t*_n, whether
    the bodies slide)."""
    d = n.shape[0]
    vnA = dot(vA, n)
    vnB = dot(vB, n)
    tnA = dot(tA, n)
    tnB = dot(tB, n)
    vn, tn = normal_state(vnA, tnA, vnB, tnB, zpA, zpB)
    _tangential(vA, n, vnA, vtA)
    _tangential(vB, n, vnB, vtB)
    _tangential(tA, n, tnA, ttA)
    _tangential(tB, n, tnB, ttB)
    if mu == 0.0:
        for i in range(d):
            vstarA[i] = vn * n[i] + slip_tangential_velocity(vtA[i], ttA[i], zsA, 1.0)
            vstarB[i] = vn * n[i] + slip_tangential_velocity(vtB[i], ttB[i], zsB, -1.0)
            tstar[i] = tn * n[i]
        return tn, True
    trial = 0.0
    for i in range(d):
        vt, tt = stick_tangential(vtA, ttA, vtB, ttB, zsA, zsB, i)
        vstarA[i] = vn * n[i] + vt
        vstarB[i] = vn * n[i] + vt
        tstar[i] = tn * n[i] + tt
        trial += tt * tt
    scale = friction_scale(math.sqrt(trial), tn, mu)
    if scale == 1.0:
        return tn, False
    for i in range(d):
        tt_star = scale * (tstar[i] - tn * n[i])
        vstarA[i] = vn * n[i] + sliding_tangential_velocity(vtA[i], ttA[i], tt_star, zsA, 1.0)
        vstarB[i] = vn * n[i] + sliding_tangential_velocity(vtB[i], ttB[i], tt_star, zsB, -1.0)
        tstar[i] = tn * n[i] + tt_star
    return tn, True


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


def wall_state(vA, tA, n, zpA, zsA, wall_velocity, mu, vt, tt, vstar, tstar):
    """Body A against a rigid wall moving with ``wall_velocity``, n pointing into the wall:
    the limit Z_B -> infinity of the contact state of seed eq. 7. The wall imposes its normal
    velocity; in stick (mu = inf) its tangential velocity, in slip (mu = 0) no tangential
    traction, and with Coulomb friction the stick traction capped at mu (-t*_n)
    (friction_scale). Writes vstar and tstar; returns (t*_n, whether the body slides)."""
    d = n.shape[0]
    vnA = dot(vA, n)
    tnA = dot(tA, n)
    vnW = dot(wall_velocity, n)
    tn = tnA + zpA * (vnW - vnA)
    _tangential(vA, n, vnA, vt)
    _tangential(tA, n, tnA, tt)
    if mu == 0.0:
        for i in range(d):
            vstar[i] = vnW * n[i] + slip_tangential_velocity(vt[i], tt[i], zsA, 1.0)
            tstar[i] = tn * n[i]
        return tn, True
    trial = 0.0
    for i in range(d):
        vw = wall_velocity[i] - vnW * n[i]
        vstar[i] = vnW * n[i] + vw
        tstar[i] = tn * n[i] + tt[i] + zsA * (vw - vt[i])
        trial += (tstar[i] - tn * n[i]) ** 2
    scale = friction_scale(math.sqrt(trial), tn, mu)
    if scale == 1.0:
        return tn, False
    for i in range(d):
        tt_star = scale * (tstar[i] - tn * n[i])
        vstar[i] = vnW * n[i] + sliding_tangential_velocity(vt[i], tt[i], tt_star, zsA, 1.0)
        tstar[i] = tn * n[i] + tt_star
    return tn, True
