"""Numba kernels of the explicit FE baselines (element forces, contact, one time step).

All kernels work on global (all-bodies concatenated) arrays:

* ``x (N,2)`` current positions, ``v (N,2)`` velocities, ``minv (N,2)`` inverse lumped mass
  per component (0 where the component is prescribed), ``mass (N,)`` lumped mass;
* ``cells (M,k)`` element connectivity, k=3 (T3) or 4 (Q4), ``grads (M,ngp,k,2)`` reference
  shape-function gradients at the integration points, ``wj (M,ngp)`` weight * reference
  Jacobian, ``area0 (M,)`` reference element area, ``emat (M,)`` material row, ``mtab`` the
  material table of :mod:`impactfv.materials`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..materials import (CP, KAPPA, LAMBDA, MODEL, MU, cauchy_stress, first_piola,
                         strain_energy_density)

_first_piola = njit(cache=True)(first_piola)
_energy = njit(cache=True)(strain_energy_density)
_cauchy = njit(cache=True)(cauchy_stress)


@njit(cache=True)
def _shoelace(x, cells, e):
    k = cells.shape[1]
    a = 0.0
    for i in range(k):
        p = cells[e, i]
        q = cells[e, (i + 1) % k]
        a += x[p, 0] * x[q, 1] - x[q, 0] * x[p, 1]
    return 0.5 * a


@njit(cache=True)
def _deformation_gradient(x, cells, grads, e, g):
    f11 = 0.0
    f12 = 0.0
    f21 = 0.0
    f22 = 0.0
    for i in range(cells.shape[1]):
        n = cells[e, i]
        g1 = grads[e, g, i, 0]
        g2 = grads[e, g, i, 1]
        f11 += x[n, 0] * g1
        f12 += x[n, 0] * g2
        f21 += x[n, 1] * g1
        f22 += x[n, 1] * g2
    return f11, f12, f21, f22


@njit(cache=True)
def internal_forces(x, cells, grads, wj, area0, emat, mtab, f):
    """Assemble internal nodal forces ``f`` (= dE/dx, overwritten) of the whole mesh.

    Returns ``(strain_energy, min_e(l_e / c_e), min J)`` where l_e is the current
    characteristic length (2a/longest side for T3, a/longest side for Q4) and c_e the
    reference p-wave speed of the element's material.
    """
    f[:, :] = 0.0
    k = cells.shape[1]
    ngp = grads.shape[1]
    energy = 0.0
    dtlim = np.inf
    jmin = np.inf
    for e in range(cells.shape[0]):
        m = emat[e]
        mu = mtab[m, MU]
        lam = mtab[m, LAMBDA]
        kap = mtab[m, KAPPA]
        model = int(mtab[m, MODEL])
        a = _shoelace(x, cells, e)
        jbar = a / area0[e]
        if jbar < jmin:
            jmin = jbar
        # characteristic length for the stable time step
        lmax = 0.0
        for i in range(k):
            p = cells[e, i]
            q = cells[e, (i + 1) % k]
            d = math.sqrt((x[q, 0] - x[p, 0]) ** 2 + (x[q, 1] - x[p, 1]) ** 2)
            if d > lmax:
                lmax = d
        le = (2.0 * a / lmax) if k == 3 else (a / lmax)
        r = le / mtab[m, CP]
        if r < dtlim:
            dtlim = r
        if k == 3:
            f11, f12, f21, f22 = _deformation_gradient(x, cells, grads, e, 0)
            p11, p12, p21, p22 = _first_piola(f11, f12, f21, f22, mu, lam, kap, model)
            w = wj[e, 0]
            energy += w * _energy(f11, f12, f21, f22, mu, lam, kap, model)
            for i in range(3):
                n = cells[e, i]
                g1 = grads[e, 0, i, 0]
                g2 = grads[e, 0, i, 1]
                f[n, 0] += w * (p11 * g1 + p12 * g2)
                f[n, 1] += w * (p21 * g1 + p22 * g2)
            continue
        # ---- Q4 with mean dilatation (see solver docstring for the derivation)
        coef = 0.0
        for g in range(ngp):
            f11, f12, f21, f22 = _deformation_gradient(x, cells, grads, e, g)
            J = f11 * f22 - f12 * f21
            if J < jmin:
                jmin = J
            s = math.sqrt(jbar / J)
            b11 = s * f11
            b12 = s * f12
            b21 = s * f21
            b22 = s * f22
            p11, p12, p21, p22 = _first_piola(b11, b12, b21, b22, mu, lam, kap, model)
            w = wj[e, g]
            energy += w * _energy(b11, b12, b21, b22, mu, lam, kap, model)
            pf = p11 * f11 + p12 * f12 + p21 * f21 + p22 * f22  # Pbar : F
            ws = w * s
            h = 0.5 * pf / J
            # F^-T = cof F / J, cof F = [[F22, -F21], [-F12, F11]]
            c11 = f22
            c12 = -f21
            c21 = -f12
            c22 = f11
            for i in range(4):
                n = cells[e, i]
                g1 = grads[e, g, i, 0]
                g2 = grads[e, g, i, 1]
                f[n, 0] += ws * (p11 * g1 + p12 * g2 - h * (c11 * g1 + c12 * g2))
                f[n, 1] += ws * (p21 * g1 + p22 * g2 - h * (c21 * g1 + c22 * g2))
            coef += ws * 0.5 * pf / jbar
        coef /= area0[e]
        for i in range(4):
            n = cells[e, i]
            nn = cells[e, (i + 1) % 4]
            np_ = cells[e, (i + 3) % 4]
            f[n, 0] += coef * 0.5 * (x[nn, 1] - x[np_, 1])
            f[n, 1] += coef * 0.5 * (x[np_, 0] - x[nn, 0])
    return energy, dtlim, jmin


@njit(cache=True)
def element_pressure_von_mises(x, cells, grads, wj, area0, emat, mtab, pe, vme):
    """Element-average pressure (-tr sigma / 3, sigma_zz included) and von Mises stress.

    Q4 uses the mean-dilatation F_bar at each Gauss point (so its pressure is the element one).
    """
    k = cells.shape[1]
    ngp = grads.shape[1]
    for e in range(cells.shape[0]):
        m = emat[e]
        mu = mtab[m, MU]
        lam = mtab[m, LAMBDA]
        kap = mtab[m, KAPPA]
        model = int(mtab[m, MODEL])
        jbar = _shoelace(x, cells, e) / area0[e]
        ps = 0.0
        vs = 0.0
        ws = 0.0
        for g in range(ngp):
            f11, f12, f21, f22 = _deformation_gradient(x, cells, grads, e, g)
            if k == 4:
                s = math.sqrt(jbar / (f11 * f22 - f12 * f21))
                f11 *= s
                f12 *= s
                f21 *= s
                f22 *= s
            s11, s12, s22, s33 = _cauchy(f11, f12, f21, f22, mu, lam, kap, model)
            p = -(s11 + s22 + s33) / 3.0
            vm = math.sqrt(max(0.5 * ((s11 - s22) ** 2 + (s22 - s33) ** 2 + (s33 - s11) ** 2)
                               + 3.0 * s12 * s12, 0.0))
            w = wj[e, g]
            ps += w * p
            vs += w * vm
            ws += w
        pe[e] = ps / ws
        vme[e] = vs / ws


@njit(cache=True)
def nodal_average(cells, area0, ve, nnodes):
    """Reference-area-weighted nodal average of an element field."""
    acc = np.zeros(nnodes)
    wsum = np.zeros(nnodes)
    for e in range(cells.shape[0]):
        for i in range(cells.shape[1]):
            n = cells[e, i]
            acc[n] += area0[e] * ve[e]
            wsum[n] += area0[e]
    for n in range(nnodes):
        if wsum[n] > 0.0:
            acc[n] /= wsum[n]
    return acc


# --------------------------------------------------------------------------- contact

@njit(cache=True)
def _apply_impulse(v, minv, mass, n, lam, c, nx, ny):
    """v[n] += c*lam*minv[n]*nrm; returns (work I.v_new / 1, momentum change x, y)."""
    dke = 0.0
    dpx = 0.0
    dpy = 0.0
    for d in range(2):
        if minv[n, d] > 0.0:
            dv = c * lam * minv[n, d] * (nx if d == 0 else ny)
            v[n, d] += dv
            dke += mass[n] * v[n, d] * dv
            if d == 0:
                dpx += mass[n] * dv
            else:
                dpy += mass[n] * dv
    return dke, dpx, dpy


@njit(cache=True)
def contact_correct(x, v, minv, mass, dt,
                    pslave_ptr, slave_nodes, pseg_ptr, segs, psedge_ptr, sedges,
                    pcontact, pslave_is_a, pdepth,
                    normals, head, nxt, cons_n, cons_xi, cons_nrm, cons_p,
                    cforce, cgap, maxit, tol):
    """Kinematic (predictor-corrector) frictionless node-to-segment contact, two-pass.

    The predicted positions are ``x + dt * v``.  For every pass p (slave nodes of one body
    against master segments of the other) a uniform-bin cell list of the master segments
    (binned by midpoint, bin size >= 1.1 * longest segment + 2 * search depth) finds, for each
    slave node, the candidate segments in the 3x3 neighbouring bins: linear cost.  The
    retained segment has the projection parameter in [-0.01, 1.01], a signed gap within
    +-depth, a normal facing the slave node's surface normal (n_s . n_m < -0.3), and the
    smallest |gap|.  The projection parameter (from x*) and the segment normal (from the
    start-of-step positions x_n) are frozen for the step (linearised constraint).  Penetrations are then
    removed by projected Gauss-Seidel sweeps over the constraints: a normal impulse lambda n (on the slave) and -(1-xi) lambda n, -xi lambda n
    (on the master nodes) with lambda = -g / (dt * w), w = sum_i c_i^2 n.(minv_i n).  The
    impulses sum to zero, so linear momentum is conserved to round-off.

    Outputs ``cforce[k]`` (force on body_a of contact k, impulse/dt) and ``cgap[k]`` (smallest
    signed gap after correction, nan if no candidate).  Returns the kinetic-energy change of
    the (half-step) velocities caused by the correction and the number of constraints.
    """
    npass = pslave_ptr.shape[0] - 1
    cforce[:, :] = 0.0
    cgap[:] = np.nan
    ncons = 0
    ncap = head.shape[0]
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
            dx = (x[b, 0] + dt * v[b, 0]) - (x[a, 0] + dt * v[a, 0])
            dy = (x[b, 1] + dt * v[b, 1]) - (x[a, 1] + dt * v[a, 1])
            normals[a, 0] += dy
            normals[a, 1] -= dx
            normals[b, 0] += dy
            normals[b, 1] -= dx
        # bin the master segments by midpoint
        xmin = np.inf
        ymin = np.inf
        xmax = -np.inf
        ymax = -np.inf
        lmax = 0.0
        for s in range(g0, g1):
            a = segs[s, 0]
            b = segs[s, 1]
            ax = x[a, 0] + dt * v[a, 0]
            ay = x[a, 1] + dt * v[a, 1]
            bx = x[b, 0] + dt * v[b, 0]
            by = x[b, 1] + dt * v[b, 1]
            mx = 0.5 * (ax + bx)
            my = 0.5 * (ay + by)
            xmin = min(xmin, mx)
            xmax = max(xmax, mx)
            ymin = min(ymin, my)
            ymax = max(ymax, my)
            lmax = max(lmax, math.sqrt((bx - ax) ** 2 + (by - ay) ** 2))
        hb = 1.1 * lmax + 2.0 * depth
        nbx = int((xmax - xmin) / hb) + 1
        nby = int((ymax - ymin) / hb) + 1
        while nbx * nby > ncap:
            hb *= 1.5
            nbx = int((xmax - xmin) / hb) + 1
            nby = int((ymax - ymin) / hb) + 1
        head[:nbx * nby] = -1
        for s in range(g0, g1):
            a = segs[s, 0]
            b = segs[s, 1]
            mx = 0.5 * (x[a, 0] + dt * v[a, 0] + x[b, 0] + dt * v[b, 0])
            my = 0.5 * (x[a, 1] + dt * v[a, 1] + x[b, 1] + dt * v[b, 1])
            ib = min(int((mx - xmin) / hb), nbx - 1) + nbx * min(int((my - ymin) / hb), nby - 1)
            nxt[s - g0] = head[ib]
            head[ib] = s - g0
        # closest facing segment for every slave node
        for i in range(s0, s1):
            n = slave_nodes[i]
            sx = x[n, 0] + dt * v[n, 0]
            sy = x[n, 1] + dt * v[n, 1]
            nl = math.sqrt(normals[n, 0] ** 2 + normals[n, 1] ** 2)
            if nl == 0.0:
                continue
            nsx = normals[n, 0] / nl
            nsy = normals[n, 1] / nl
            fx = (sx - xmin) / hb
            fy = (sy - ymin) / hb
            if fx < -1.0 or fy < -1.0 or fx > nbx + 1.0 or fy > nby + 1.0:
                continue
            ix = int(math.floor(fx))
            iy = int(math.floor(fy))
            best = -1
            bestg = np.inf
            bestxi = 0.0
            for jy in range(iy - 1, iy + 2):
                if jy < 0 or jy >= nby:
                    continue
                for jx in range(ix - 1, ix + 2):
                    if jx < 0 or jx >= nbx:
                        continue
                    s = head[jx + nbx * jy]
                    while s >= 0:
                        a = segs[g0 + s, 0]
                        b = segs[g0 + s, 1]
                        ax = x[a, 0] + dt * v[a, 0]
                        ay = x[a, 1] + dt * v[a, 1]
                        dx = x[b, 0] + dt * v[b, 0] - ax
                        dy = x[b, 1] + dt * v[b, 1] - ay
                        l2 = dx * dx + dy * dy
                        xi = ((sx - ax) * dx + (sy - ay) * dy) / l2
                        if -0.01 <= xi <= 1.01:
                            ll = math.sqrt(l2)
                            nmx = dy / ll
                            nmy = -dx / ll
                            g = (sx - ax) * nmx + (sy - ay) * nmy
                            if abs(g) <= depth and nsx * nmx + nsy * nmy < -0.3:
                                if abs(g) < abs(bestg):
                                    bestg = g
                                    best = g0 + s
                                    bestxi = min(max(xi, 0.0), 1.0)
                        s = nxt[s]
            if best >= 0:
                a = segs[best, 0]
                b = segs[best, 1]
                # contact normal frozen from the start-of-step configuration x_n (where the
                # constraints hold, so a flat contact face gives an exact normal)
                dx = x[b, 0] - x[a, 0]
                dy = x[b, 1] - x[a, 1]
                ll = math.sqrt(dx * dx + dy * dy)
                cons_nrm[ncons, 0] = dy / ll
                cons_nrm[ncons, 1] = -dx / ll
                cons_n[ncons, 0] = n
                cons_n[ncons, 1] = segs[best, 0]
                cons_n[ncons, 2] = segs[best, 1]
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
            k1, sx_, sy_ = _apply_impulse(v, minv, mass, n, lam, 1.0, nx, ny)
            k2, ax_, ay_ = _apply_impulse(v, minv, mass, a, lam, -(1.0 - xi), nx, ny)
            k3, bx_, by_ = _apply_impulse(v, minv, mass, b, lam, -xi, nx, ny)
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


# --------------------------------------------------------------------------- time step

@njit(cache=True)
def step(x, v, acc, f, minv, mass, fmask, fval, dt,
         cells, grads, wj, area0, emat, mtab,
         pslave_ptr, slave_nodes, pseg_ptr, segs, psedge_ptr, sedges,
         pcontact, pslave_is_a, pdepth,
         normals, head, nxt, cons_n, cons_xi, cons_nrm, cons_p, cforce, cgap, maxit, tol):
    """One velocity-Verlet (central-difference) step with kinematic contact.

    v_{n+1/2} = v_n + dt/2 a_n; contact correction of v_{n+1/2} so that x_n + dt v_{n+1/2}
    does not penetrate; x_{n+1} = x_n + dt v_{n+1/2}; a_{n+1} = -M^-1 f_int(x_{n+1});
    v_{n+1} = v_{n+1/2} + dt/2 a_{n+1}.  Prescribed components are reset each half step.

    Returns (strain energy, kinetic energy, px, py, contact dKE, dt limit ratio, min J,
    number of contact constraints), all at t_{n+1}.
    """
    nn = x.shape[0]
    hdt = 0.5 * dt
    for i in range(nn):
        for d in range(2):
            if fmask[i, d]:
                v[i, d] = fval[i, d]
            else:
                v[i, d] += hdt * acc[i, d]
    dke, ncons = contact_correct(x, v, minv, mass, dt, pslave_ptr, slave_nodes, pseg_ptr,
                                 segs, psedge_ptr, sedges, pcontact, pslave_is_a, pdepth,
                                 normals, head, nxt, cons_n, cons_xi, cons_nrm, cons_p, cforce,
                                 cgap, maxit, tol)
    for i in range(nn):
        x[i, 0] += dt * v[i, 0]
        x[i, 1] += dt * v[i, 1]
    se, dtlim, jmin = internal_forces(x, cells, grads, wj, area0, emat, mtab, f)
    ke = 0.0
    px = 0.0
    py = 0.0
    for i in range(nn):
        for d in range(2):
            acc[i, d] = -f[i, d] * minv[i, d]
            if fmask[i, d]:
                v[i, d] = fval[i, d]
            else:
                v[i, d] += hdt * acc[i, d]
        ke += 0.5 * mass[i] * (v[i, 0] ** 2 + v[i, 1] ** 2)
        px += mass[i] * v[i, 0]
        py += mass[i] * v[i, 1]
    return se, ke, px, py, dke, dtlim, jmin, ncons


@njit(cache=True)
def kinetic_and_momentum(v, mass):
    ke = 0.0
    px = 0.0
    py = 0.0
    for i in range(v.shape[0]):
        ke += 0.5 * mass[i] * (v[i, 0] ** 2 + v[i, 1] ** 2)
        px += mass[i] * v[i, 0]
        py += mass[i] * v[i, 1]
    return ke, px, py
