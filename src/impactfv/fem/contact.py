"""Kinematic (predictor-corrector) frictionless node-to-segment contact of the FE baselines,
as in Abaqus/Explicit: their own contact algorithm (that is the point of a baseline), on the
shared contact geometry (uniform bins of impactfv.geometry.bins).

The contact surfaces come as one bundle, :class:`ContactPasses`, and the scratch arrays as
another, :class:`ContactWork`.
"""

import math
from collections import namedtuple

import numpy as np
from numba import njit

from ..geometry.bins import bin_of, build_bins

#: the contact passes, each the slave nodes of one body against the master segments of the
#: other: pass p has the slave nodes ``slave_nodes[slave_ptr[p]:slave_ptr[p+1]]``, the master
#: segments ``segs[seg_ptr[p]:seg_ptr[p+1]]`` (node pairs) and the slave surface's own
#: segments ``sedges[sedge_ptr[p]:sedge_ptr[p+1]]`` (for its nodal normals); it belongs to
#: contact ``contact[p]``, its slaves are that contact's body_a if ``slave_is_a[p]``, and its
#: search depth is ``depth[p]``
ContactPasses = namedtuple("ContactPasses", ["slave_ptr", "slave_nodes", "seg_ptr", "segs",
                                             "sedge_ptr", "sedges", "contact", "slave_is_a",
                                             "depth"])

#: scratch of the contact correction: slave nodal ``normals (N,2)``, predicted positions
#: ``xp (N,2)``, and per constraint c its slave and master nodes ``cons_nodes[c] = (n, a,
#: b)``, projection parameter ``cons_xi[c]``, normal ``cons_normal[c]`` and pass
#: ``cons_pass[c]``
ContactWork = namedtuple("ContactWork", ["normals", "xp", "cons_nodes", "cons_xi",
                                         "cons_normal", "cons_pass"])


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
def _slave_normals(xp, passes, p, normals):
    """Nodal normals (not normalised) of the slave surface of pass p at the predicted
    positions: each slave segment a->b adds its outward normal (dy, -dx) to both nodes."""
    for i in range(passes.slave_ptr[p], passes.slave_ptr[p + 1]):
        n = passes.slave_nodes[i]
        normals[n, 0] = 0.0
        normals[n, 1] = 0.0
    for i in range(passes.sedge_ptr[p], passes.sedge_ptr[p + 1]):
        a = passes.sedges[i, 0]
        b = passes.sedges[i, 1]
        dx = xp[b, 0] - xp[a, 0]
        dy = xp[b, 1] - xp[a, 1]
        normals[a, 0] += dy
        normals[a, 1] -= dx
        normals[b, 0] += dy
        normals[b, 1] -= dx


@njit(cache=True, inline="always")
def _closest_facing_segment(xp, segs, g0, candidates, n, nsx, nsy, depth):
    """Among the master segments ``g0 + candidates`` the one slave node n (unit normal
    (nsx, nsy)) is paired with: projection parameter in [-0.01, 1.01], |gap| <= depth,
    facing (n_s . n_m < -0.3), smallest |gap|. Returns (segment, projection parameter
    clipped to [0, 1]), segment -1 if none."""
    sx = xp[n, 0]
    sy = xp[n, 1]
    best = -1
    bestg = np.inf
    bestxi = 0.0
    for it in range(candidates.shape[0]):
        s = g0 + candidates[it]
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
    return best, bestxi


@njit(cache=True, inline="always")
def _add_constraint(x, work, c, n, a, b, xi, p):
    """Constraint c: slave node n on segment a->b at projection parameter xi, pass p."""
    # contact normal frozen from the start-of-step configuration x (where the
    # constraints hold, so a flat contact face gives an exact normal)
    dx = x[b, 0] - x[a, 0]
    dy = x[b, 1] - x[a, 1]
    ll = math.sqrt(dx * dx + dy * dy)
    work.cons_normal[c, 0] = dy / ll
    work.cons_normal[c, 1] = -dx / ll
    work.cons_nodes[c, 0] = n
    work.cons_nodes[c, 1] = a
    work.cons_nodes[c, 2] = b
    work.cons_xi[c] = xi
    work.cons_pass[c] = p


@njit(cache=True)
def _detect(x, passes, work, p, ncons):
    """The constraints of pass p, stored from index ``ncons`` on; returns the new number of
    constraints. The master segments are binned at their predicted positions ``work.xp``,
    padded so that any segment within reach of a slave node is in the node's bin."""
    xp = work.xp
    normals = work.normals
    segs = passes.segs
    depth = passes.depth[p]
    s0 = passes.slave_ptr[p]
    s1 = passes.slave_ptr[p + 1]
    g0 = passes.seg_ptr[p]
    g1 = passes.seg_ptr[p + 1]
    if s1 == s0 or g1 == g0:
        return ncons
    _slave_normals(xp, passes, p, normals)
    master = segs[g0:g1]
    lmax = 0.0
    for s in range(master.shape[0]):
        a = master[s, 0]
        b = master[s, 1]
        lmax = max(lmax, math.sqrt((xp[b, 0] - xp[a, 0]) ** 2 + (xp[b, 1] - xp[a, 1]) ** 2))
    # any segment with |gap| <= depth and xi in [-0.01, 1.01] is within this reach
    origin, h, shape, start, items = build_bins(xp, master, depth + 0.02 * lmax)
    for i in range(s0, s1):
        n = passes.slave_nodes[i]
        nl = math.sqrt(normals[n, 0] ** 2 + normals[n, 1] ** 2)
        if nl == 0.0:
            continue
        c = bin_of(xp[n], origin, h, shape)
        if c < 0:
            continue
        best, xi = _closest_facing_segment(xp, segs, g0, items[start[c]:start[c + 1]], n,
                                           normals[n, 0] / nl, normals[n, 1] / nl, depth)
        if best >= 0:
            _add_constraint(x, work, ncons, n, segs[best, 0], segs[best, 1], xi, p)
            ncons += 1
    return ncons


@njit(cache=True, inline="always")
def _linearised_gap(x, v, dt, n, a, b, xi, nx, ny):
    """Predicted gap of slave node n to segment a->b, with the normal (nx, ny) and the
    projection parameter xi frozen at detection."""
    ex = x[n, 0] + dt * v[n, 0] - (1.0 - xi) * (x[a, 0] + dt * v[a, 0]) \
        - xi * (x[b, 0] + dt * v[b, 0])
    ey = x[n, 1] + dt * v[n, 1] - (1.0 - xi) * (x[a, 1] + dt * v[a, 1]) \
        - xi * (x[b, 1] + dt * v[b, 1])
    return ex * nx + ey * ny


@njit(cache=True, inline="always")
def _normal_inverse_mass(minv, n, a, b, xi, nx, ny):
    """w = sum_i c_i^2 n.(minv_i n) with c = (1, 1 - xi, xi) on (n, a, b)."""
    return (nx * nx * (minv[n, 0] + (1.0 - xi) ** 2 * minv[a, 0] + xi * xi * minv[b, 0])
            + ny * ny * (minv[n, 1] + (1.0 - xi) ** 2 * minv[a, 1] + xi * xi * minv[b, 1]))


@njit(cache=True)
def _gauss_seidel(x, v, acc, minv, mass, dt, passes, work, ncons, cforce, maxit, tol):
    """Projected Gauss-Seidel sweeps on the predicted gaps of the ``ncons`` constraints,
    until the largest penetration is at most ``tol`` (at most ``maxit`` sweeps). Adds the
    impulses / dt on body_a to ``cforce``; returns the change of the step's end energy."""
    hdt = 0.5 * dt
    dke = 0.0
    for it in range(maxit):
        worst = 0.0
        for c in range(ncons):
            n = work.cons_nodes[c, 0]
            a = work.cons_nodes[c, 1]
            b = work.cons_nodes[c, 2]
            xi = work.cons_xi[c]
            nx = work.cons_normal[c, 0]
            ny = work.cons_normal[c, 1]
            g = _linearised_gap(x, v, dt, n, a, b, xi, nx, ny)
            if g >= 0.0:
                continue
            if -g > worst:
                worst = -g
            wsum = _normal_inverse_mass(minv, n, a, b, xi, nx, ny)
            if wsum <= 0.0:
                continue
            lam = -g / (dt * wsum)
            k1, sx_, sy_ = _apply_impulse(v, minv, mass, acc, hdt, n, lam, 1.0, nx, ny)
            k2, ax_, ay_ = _apply_impulse(v, minv, mass, acc, hdt, a, lam, -(1.0 - xi), nx, ny)
            k3, bx_, by_ = _apply_impulse(v, minv, mass, acc, hdt, b, lam, -xi, nx, ny)
            dke += k1 + k2 + k3
            k = passes.contact[work.cons_pass[c]]
            if passes.slave_is_a[work.cons_pass[c]]:
                cforce[k, 0] += sx_ / dt
                cforce[k, 1] += sy_ / dt
            else:
                cforce[k, 0] += (ax_ + bx_) / dt
                cforce[k, 1] += (ay_ + by_) / dt
        if worst <= tol:
            break
    return dke


@njit(cache=True)
def _final_gaps(x, v, dt, passes, work, ncons, cgap):
    """cgap[k]: the smallest signed gap of contact k's constraints at x + dt v (exact
    segment normal, frozen projection parameter); nan where it has none."""
    for c in range(ncons):
        n = work.cons_nodes[c, 0]
        a = work.cons_nodes[c, 1]
        b = work.cons_nodes[c, 2]
        xi = work.cons_xi[c]
        ax = x[a, 0] + dt * v[a, 0]
        ay = x[a, 1] + dt * v[a, 1]
        dx = x[b, 0] + dt * v[b, 0] - ax
        dy = x[b, 1] + dt * v[b, 1] - ay
        ll = math.sqrt(dx * dx + dy * dy)
        g = ((x[n, 0] + dt * v[n, 0] - ax - xi * dx) * dy
             - (x[n, 1] + dt * v[n, 1] - ay - xi * dy) * dx) / ll
        k = passes.contact[work.cons_pass[c]]
        if not (cgap[k] <= g):
            cgap[k] = g


@njit(cache=True)
def contact_correct(x, v, acc, minv, mass, dt, passes, work, cforce, cgap, maxit, tol):
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

    ``passes`` are the contact surfaces (:class:`ContactPasses`), ``work`` the scratch
    (:class:`ContactWork`). Outputs ``cforce[k]`` (force on body_a of contact k,
    impulse/dt) and ``cgap[k]`` (smallest signed gap after correction, nan if no
    candidate). ``v`` holds the half-step velocities v_{n+1/2} and ``acc`` the accelerations
    a_n of the start of the step. Returns the change of the step's end energy (kinetic +
    strain) caused by the correction (see :func:`_apply_impulse`; negative: the contact took
    energy out) and the number of constraints.
    """
    cforce[:, :] = 0.0
    cgap[:] = np.nan
    xp = work.xp
    for i in range(x.shape[0]):
        xp[i, 0] = x[i, 0] + dt * v[i, 0]
        xp[i, 1] = x[i, 1] + dt * v[i, 1]
    ncons = 0
    for p in range(passes.slave_ptr.shape[0] - 1):
        ncons = _detect(x, passes, work, p, ncons)
    dke = _gauss_seidel(x, v, acc, minv, mass, dt, passes, work, ncons, cforce, maxit, tol)
    _final_gaps(x, v, dt, passes, work, ncons, cgap)
    return dke, ncons
