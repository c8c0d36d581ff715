"""Kinematic (predictor-corrector) frictionless node-to-segment contact of the FE baselines,
as in Abaqus/Explicit: their own contact algorithm (that is the point of a baseline), on the
shared contact geometry (uniform bins of impactfv.geometry.bins).
"""

import math

import numpy as np
from numba import njit

from ..geometry.bins import bin_of, build_bins


@njit(cache=True)
def _apply_impulse(v, minv, mass, acc, hdt, n, lam, c, nx, ny):
    """v[n] += c*lam*minv[n]*nrm; returns (the change of the step's energy, momentum change
    x, y).

    The impulse changes the half-step velocity v_{n+1/2} by dv; in velocity Verlet this
    changes the energy at the end of the step, KE(v_{n+1}) + SE(x_{n+1}), by
    m (v_n + dv/2) . dv with v_n = v_{n+1/2} - dt/2 a_n the start-of-step velocity (to
    O(dt^2)): the energy the impulse puts in (negative: takes out). For several impulses
    on one node the increments add up to the same total.
    """
    de = 0.0
    dpx = 0.0
    dpy = 0.0
    for d in range(2):
        if minv[n, d] > 0.0:
            dv = c * lam * minv[n, d] * (nx if d == 0 else ny)
            v[n, d] += dv
            de += mass[n] * (v[n, d] - 0.5 * dv - hdt * acc[n, d]) * dv
            if d == 0:
                dpx += mass[n] * dv
            else:
                dpy += mass[n] * dv
    return de, dpx, dpy


@njit(cache=True)
def contact_correct(x, v, minv, mass, acc, dt, pslave_ptr, slave_nodes, pseg_ptr, segs,
                    psedge_ptr, sedges, pcontact, pslave_is_a, pdepth, normals, xp, cons_n,
                    cons_xi, cons_nrm, cons_p, cforce, cgap, maxit, tol):
    """Kinematic frictionless node-to-segment contact, two-pass.

    The predicted positions are ``xp = x + dt * v``. For every pass p (slave nodes of one
    body against master segments of the other) the master segments are binned at their
    predicted positions (impactfv.geometry.bins, padded by the search depth), so each slave
    node finds its candidates in one bin: linear cost. The retained segment has the
    projection parameter in [-0.01, 1.01], a signed gap within +-depth, a normal facing the
    slave node's surface normal (n_s . n_m < -0.3), and the smallest |gap|. The projection
    parameter (from xp) and the segment normal (from the start-of-step positions x) are
    frozen for the step (linearised constraint). Penetrations are then removed by projected
    Gauss-Seidel sweeps over the constraints: a normal impulse lambda n (on the slave) and
    -(1-xi) lambda n, -xi lambda n (on the master nodes) with lambda = -g / (dt * w),
    w = sum_i c_i^2 n.(minv_i n). The impulses sum to zero, so linear momentum is conserved
    to round-off.

    Outputs ``cforce[k]`` (force on body_a of contact k, impulse/dt) and ``cgap[k]`` (smallest
    signed gap after correction, nan if no candidate). ``v`` holds the half-step velocities
    v_{n+1/2} and ``acc`` the accelerations a_n of the start of the step. Returns the change
    of the step's end energy (kinetic + strain) caused by the correction (see
    :func:`_apply_impulse`; negative: the contact took energy out) and the number of
    constraints.
    """
    npass = pslave_ptr.shape[0] - 1
    hdt = 0.5 * dt
    cforce[:, :] = 0.0
    cgap[:] = np.nan
    ncons = 0
    for i in range(x.shape[0]):
        xp[i, 0] = x[i, 0] + dt * v[i, 0]
        xp[i, 1] = x[i, 1] + dt * v[i, 1]
    for p in range(npass):
        depth = pdepth[p]
        s0 = pslave_ptr[p]
        s1 = pslave_ptr[p + 1]
        g0 = pseg_ptr[p]
        g1 = pseg_ptr[p + 1]
        if s1 == s0 or g1 == g0:
            continue
        # slave nodal normals (predicted configuration)
        for i in range(s0, s1):
            n = slave_nodes[i]
            normals[n, 0] = 0.0
            normals[n, 1] = 0.0
        for i in range(psedge_ptr[p], psedge_ptr[p + 1]):
            a = sedges[i, 0]
            b = sedges[i, 1]
            dx = xp[b, 0] - xp[a, 0]
            dy = xp[b, 1] - xp[a, 1]
            normals[a, 0] += dy
            normals[a, 1] -= dx
            normals[b, 0] += dy
            normals[b, 1] -= dx
        master = segs[g0:g1]
        lmax = 0.0
        for s in range(master.shape[0]):
            a = master[s, 0]
            b = master[s, 1]
            lmax = max(lmax, math.sqrt((xp[b, 0] - xp[a, 0]) ** 2 + (xp[b, 1] - xp[a, 1]) ** 2))
        # any segment with |gap| <= depth and xi in [-0.01, 1.01] is within this reach
        origin, h, shape, start, items = build_bins(xp, master, depth + 0.02 * lmax)
        # closest facing segment for every slave node
        for i in range(s0, s1):
            n = slave_nodes[i]
            nl = math.sqrt(normals[n, 0] ** 2 + normals[n, 1] ** 2)
            if nl == 0.0:
                continue
            nsx = normals[n, 0] / nl
            nsy = normals[n, 1] / nl
            sx = xp[n, 0]
            sy = xp[n, 1]
            c = bin_of(xp[n], origin, h, shape)
            if c < 0:
                continue
            best = -1
            bestg = np.inf
            bestxi = 0.0
            for it in range(start[c], start[c + 1]):
                s = g0 + items[it]
                a = segs[s, 0]
                b = segs[s, 1]
                ax = xp[a, 0]
                ay = xp[a, 1]
                dx = xp[b, 0] - ax
                dy = xp[b, 1] - ay
                l2 = dx * dx + dy * dy
                xi = ((sx - ax) * dx + (sy - ay) * dy) / l2
                if -0.01 <= xi <= 1.01:
                    ll = math.sqrt(l2)
                    nmx = dy / ll
                    nmy = -dx / ll
                    g = (sx - ax) * nmx + (sy - ay) * nmy
                    if abs(g) <= depth and nsx * nmx + nsy * nmy < -0.3:
                        # smallest |gap|; between equally close segments (a node at the
                        # junction of two) the lower index, whatever the search order
                        closer = abs(g) < abs(bestg) - 1e-12 * depth
                        tie = abs(abs(g) - abs(bestg)) <= 1e-12 * depth
                        if closer or (tie and s < best):
                            bestg = g
                            best = s
                            bestxi = min(max(xi, 0.0), 1.0)
            if best >= 0:
                a = segs[best, 0]
                b = segs[best, 1]
                # contact normal frozen from the start-of-step configuration x (where the
                # constraints hold, so a flat contact face gives an exact normal)
                dx = x[b, 0] - x[a, 0]
                dy = x[b, 1] - x[a, 1]
                ll = math.sqrt(dx * dx + dy * dy)
                cons_nrm[ncons, 0] = dy / ll
                cons_nrm[ncons, 1] = -dx / ll
                cons_n[ncons, 0] = n
                cons_n[ncons, 1] = a
                cons_n[ncons, 2] = b
                cons_xi[ncons] = bestxi
                cons_p[ncons] = p
                ncons += 1
    # projected Gauss-Seidel on the predicted gaps
    dke = 0.0
    for it in range(maxit):
        worst = 0.0
        for c in range(ncons):
            n = cons_n[c, 0]
            a = cons_n[c, 1]
            b = cons_n[c, 2]
            xi = cons_xi[c]
            nx = cons_nrm[c, 0]
            ny = cons_nrm[c, 1]
            # linearised gap: fixed normal (frozen at detection), fixed projection xi
            ex = x[n, 0] + dt * v[n, 0] - (1.0 - xi) * (x[a, 0] + dt * v[a, 0]) \
                - xi * (x[b, 0] + dt * v[b, 0])
            ey = x[n, 1] + dt * v[n, 1] - (1.0 - xi) * (x[a, 1] + dt * v[a, 1]) \
                - xi * (x[b, 1] + dt * v[b, 1])
            g = ex * nx + ey * ny
            if g >= 0.0:
                continue
            if -g > worst:
                worst = -g
            wsum = (nx * nx * (minv[n, 0] + (1.0 - xi) ** 2 * minv[a, 0] + xi * xi * minv[b, 0])
                    + ny * ny * (minv[n, 1] + (1.0 - xi) ** 2 * minv[a, 1]
                                 + xi * xi * minv[b, 1]))
            if wsum <= 0.0:
                continue
            lam = -g / (dt * wsum)
            k1, sx_, sy_ = _apply_impulse(v, minv, mass, acc, hdt, n, lam, 1.0, nx, ny)
            k2, ax_, ay_ = _apply_impulse(v, minv, mass, acc, hdt, a, lam, -(1.0 - xi), nx, ny)
            k3, bx_, by_ = _apply_impulse(v, minv, mass, acc, hdt, b, lam, -xi, nx, ny)
            dke += k1 + k2 + k3
            k = pcontact[cons_p[c]]
            if pslave_is_a[cons_p[c]]:
                cforce[k, 0] += sx_ / dt
                cforce[k, 1] += sy_ / dt
            else:
                cforce[k, 0] += (ax_ + bx_) / dt
                cforce[k, 1] += (ay_ + by_) / dt
        if worst <= tol:
            break
    # final gaps
    for c in range(ncons):
        n = cons_n[c, 0]
        a = cons_n[c, 1]
        b = cons_n[c, 2]
        xi = cons_xi[c]
        ax = x[a, 0] + dt * v[a, 0]
        ay = x[a, 1] + dt * v[a, 1]
        dx = x[b, 0] + dt * v[b, 0] - ax
        dy = x[b, 1] + dt * v[b, 1] - ay
        ll = math.sqrt(dx * dx + dy * dy)
        g = ((x[n, 0] + dt * v[n, 0] - ax - xi * dx) * dy
             - (x[n, 1] + dt * v[n, 1] - ay - xi * dy) * dx) / ll
        k = pcontact[cons_p[c]]
        if not (cgap[k] <= g):
            cgap[k] = g
    return dke, ncons
