"""Compiled contact loops: surface normals, bin search, node-to-segment Riemann passes.

Every loop here runs over surface nodes or surface segments only, and the search puts the
master segments in uniform bins, so the cost grows linearly with the surface size.
"""

import math

import numpy as np
from numba import njit

from .. import materials as _m
from ..scheme.compile import compile_module_functions
from . import riemann as _r

_mat = compile_module_functions(_m, ["cauchy_stress"])
cauchy_stress = _mat["cauchy_stress"]
_rie = compile_module_functions(_r, ["contact_state", "wall_state"])
contact_state = _rie["contact_state"]
wall_state = _rie["wall_state"]

RHO, MU, LAMBDA, KAPPA, CP, CS, MODEL = (_m.RHO, _m.MU, _m.LAMBDA, _m.KAPPA, _m.CP, _m.CS,
                                         _m.MODEL)
OPEN, STICK, SLIP = 0, 1, 2


@njit(cache=True)
def surface_geometry(x, F, node_mat, mat, nodes, segs, nrm, sig):
    """Outward spatial unit normal and Cauchy stress of surface nodes."""
    for i in range(nodes.shape[0]):
        a = nodes[i]
        nrm[a, 0] = 0.0
        nrm[a, 1] = 0.0
        k = node_mat[a]
        s11, s12, s22, _ = cauchy_stress(F[a, 0], F[a, 1], F[a, 2], F[a, 3], mat[k, MU],
                                         mat[k, LAMBDA], mat[k, KAPPA], int(mat[k, MODEL]))
        sig[a, 0] = s11
        sig[a, 1] = s12
        sig[a, 2] = s22
    for j in range(segs.shape[0]):
        p = segs[j, 0]
        q = segs[j, 1]
        d1 = x[q, 0] - x[p, 0]
        d2 = x[q, 1] - x[p, 1]
        for a in (p, q):
            nrm[a, 0] += 0.5 * d2
            nrm[a, 1] -= 0.5 * d1
    for i in range(nodes.shape[0]):
        a = nodes[i]
        s = math.sqrt(nrm[a, 0] ** 2 + nrm[a, 1] ** 2)
        if s > 0.0:
            nrm[a, 0] /= s
            nrm[a, 1] /= s


@njit(cache=True)
def _cells_of(x, p, q, pad, xmin, ymin, h, nx, ny):
    i0 = int((min(x[p, 0], x[q, 0]) - pad - xmin) / h)
    i1 = int((max(x[p, 0], x[q, 0]) + pad - xmin) / h)
    j0 = int((min(x[p, 1], x[q, 1]) - pad - ymin) / h)
    j1 = int((max(x[p, 1], x[q, 1]) + pad - ymin) / h)
    return max(i0, 0), min(i1, nx - 1), max(j0, 0), min(j1, ny - 1)


@njit(cache=True)
def build_bins(x, segs, pad):
    """Uniform bins over the master segments, each registered in every bin its box + pad meets.

    Returns (x0, y0, h, nx, ny, start, items): bin (i, j) holds items[start[c]:start[c+1]]
    with c = j * nx + i. The bin count is kept proportional to the number of segments.
    """
    m = segs.shape[0]
    xmin = np.inf
    ymin = np.inf
    xmax = -np.inf
    ymax = -np.inf
    lmax = 0.0
    for j in range(m):
        p = segs[j, 0]
        q = segs[j, 1]
        for a in (p, q):
            xmin = min(xmin, x[a, 0])
            xmax = max(xmax, x[a, 0])
            ymin = min(ymin, x[a, 1])
            ymax = max(ymax, x[a, 1])
        lmax = max(lmax, math.sqrt((x[q, 0] - x[p, 0]) ** 2 + (x[q, 1] - x[p, 1]) ** 2))
    xmin -= pad
    ymin -= pad
    xmax += pad
    ymax += pad
    h = max(lmax, pad, 1e-300)
    while (int((xmax - xmin) / h) + 1) * (int((ymax - ymin) / h) + 1) > 4 * m + 16:
        h *= 2.0
    nx = int((xmax - xmin) / h) + 1
    ny = int((ymax - ymin) / h) + 1
    count = np.zeros(nx * ny + 1, np.int64)
    for j in range(m):
        i0, i1, j0, j1 = _cells_of(x, segs[j, 0], segs[j, 1], pad, xmin, ymin, h, nx, ny)
        for jj in range(j0, j1 + 1):
            for ii in range(i0, i1 + 1):
                count[jj * nx + ii + 1] += 1
    for c in range(nx * ny):
        count[c + 1] += count[c]
    start = count
    fill = count[:-1].copy()
    items = np.empty(count[nx * ny], np.int64)
    for j in range(m):
        i0, i1, j0, j1 = _cells_of(x, segs[j, 0], segs[j, 1], pad, xmin, ymin, h, nx, ny)
        for jj in range(j0, j1 + 1):
            for ii in range(i0, i1 + 1):
                c = jj * nx + ii
                items[fill[c]] = j
                fill[c] += 1
    return xmin, ymin, h, nx, ny, start, items


@njit(cache=True)
def _closest_segment(px, py, nax, nay, x, segs, x0, y0, h, nx, ny, start, items, pad):
    """Closest facing master segment within pad: (segment, xi, distance) or (-1, 0, inf)."""
    i = int((px - x0) / h)
    j = int((py - y0) / h)
    best = -1
    best_xi = 0.0
    best_d = np.inf
    if i < 0 or j < 0 or i >= nx or j >= ny:
        return best, best_xi, best_d
    c = j * nx + i
    for k in range(start[c], start[c + 1]):
        s = items[k]
        p = segs[s, 0]
        q = segs[s, 1]
        d1 = x[q, 0] - x[p, 0]
        d2 = x[q, 1] - x[p, 1]
        L2 = d1 * d1 + d2 * d2
        # the segment's outward normal must face the slave node's outward normal
        if (d2 * nax - d1 * nay) >= -0.3 * math.sqrt(L2):
            continue
        xi = ((px - x[p, 0]) * d1 + (py - x[p, 1]) * d2) / L2
        L = math.sqrt(L2)
        lateral = 0.0
        if xi < 0.0:
            lateral = -xi * L
            xi = 0.0
        elif xi > 1.0:
            lateral = (xi - 1.0) * L
            xi = 1.0
        if lateral > 0.25 * L:
            continue  # beyond the end of the master surface
        cx = x[p, 0] + xi * d1 - px
        cy = x[p, 1] + xi * d2 - py
        dist = math.sqrt(cx * cx + cy * cy)
        if dist < best_d and dist <= pad:
            best = s
            best_xi = xi
            best_d = dist
    return best, best_xi, best_d


@njit(cache=True)
def _facing_length(a, n1, n2, F, hb_start, hb_list, hb_C, vhb, cover, w1, w2):
    """Spatial length of node a's contact half-edges whose outward normal is within 60 degrees
    of n (Nanson: da n = cof(F) dA N); they are covered by the contact with velocity w."""
    total = 0.0
    for k in range(hb_start[a], hb_start[a + 1]):
        h = hb_list[k]
        c1 = F[a, 3] * hb_C[h, 0] - F[a, 2] * hb_C[h, 1]
        c2 = -F[a, 1] * hb_C[h, 0] + F[a, 0] * hb_C[h, 1]
        length = math.sqrt(c1 * c1 + c2 * c2)
        if c1 * n1 + c2 * n2 > 0.5 * length:
            total += length
            vhb[h, 0] = w1
            vhb[h, 1] = w2
            cover[h] = 1.0
    return total


@njit(cache=True, inline="always")
def _candidate(g, gdot, dt, was_active, h):
    """Contact candidate: the gap g would close within dt at the rate gdot, or the node was in
    contact at the previous step (or stage) and its gap is below 5% of its edge length h."""
    return g + dt * min(gdot, 0.0) <= 0.0 or (was_active > 0 and g <= 0.05 * h)


@njit(cache=True)
def _contact_motion(a, v, vstar, n1, n2, closing, xdot):
    """Velocity moving a contact node: the contact normal velocity plus the gap-closing rate
    along n, the node's own velocity across it (so that its tangential motion stays the one
    its F equation sees)."""
    un = vstar[a, 0] * n1 + vstar[a, 1] * n2 + closing - (v[a, 0] * n1 + v[a, 1] * n2)
    xdot[a, 0] = v[a, 0] + un * n1
    xdot[a, 1] = v[a, 1] + un * n2


@njit(cache=True)
def contact_pass(x, v, F, sig, node_mat, mat, slave, nrm, hb_start, hb_list, hb_other, vhb,
                 cover, node_length, segs, x0, y0, h, nx, ny, start, items, pad, dt, weight,
                 slave_is_first, stick, was_active, apply, state, vstar, xdot, tstar_n,
                 force_acc, fsum):
    """Nodes of one body against the surface of the other; returns the smallest gap.

    A slave node is a candidate when its gap to the closest master segment would close within
    dt, or when it was in contact at the previous step and its gap is below 5% of its edge
    length. Each of its contact half-edges (node to edge midpoint) is projected on the nearby
    master segments and split where it overlaps the half-edges of the master nodes; every
    overlap of length l gets the acoustic Riemann state between the two nodes' states, and
    ``weight`` t* l acts on the slave node and -weight t* l on the master node. Overlaps in
    tension are released. So each node receives the traction over its own dual boundary, and
    a uniform contact pressure is transmitted exactly when the meshes do not match. The
    slave's half-edges carry the overlap-averaged v* in its F equation; its position moves
    with the contact normal velocity and closes ``weight`` of the remaining gap within the
    stage (a kinematic correction, no force).
    """
    gmin = np.inf
    sign = 1.0 if slave_is_first else -1.0
    for i in range(slave.shape[0]):
        a = slave[i]
        s, xi, dist = _closest_segment(x[a, 0], x[a, 1], nrm[a, 0], nrm[a, 1], x, segs, x0,
                                       y0, h, nx, ny, start, items, pad)
        if s < 0:
            continue
        p = segs[s, 0]
        q = segs[s, 1]
        d1 = x[q, 0] - x[p, 0]
        d2 = x[q, 1] - x[p, 1]
        L = math.sqrt(d1 * d1 + d2 * d2)
        n1 = -d2 / L  # from the slave into the master: minus the master's outward normal
        n2 = d1 / L
        g = (x[p, 0] + xi * d1 - x[a, 0]) * n1 + (x[p, 1] + xi * d2 - x[a, 1]) * n2
        if g < gmin:
            gmin = g
        if not apply:
            continue
        vB1 = (1.0 - xi) * v[p, 0] + xi * v[q, 0]
        vB2 = (1.0 - xi) * v[p, 1] + xi * v[q, 1]
        gdot = (vB1 - v[a, 0]) * n1 + (vB2 - v[a, 1]) * n2
        if not _candidate(g, gdot, dt, was_active[a], node_length[a]):
            continue
        kA = node_mat[a]
        zpA = mat[kA, RHO] * mat[kA, CP]
        zsA = mat[kA, RHO] * mat[kA, CS]
        reach = dist + 0.25 * L
        l_total = 0.0
        vs1 = 0.0
        vs2 = 0.0
        tn_sum = 0.0
        cell = int((x[a, 1] - y0) / h) * nx + int((x[a, 0] - x0) / h)
        for k in range(hb_start[a], hb_start[a + 1]):
            hh = hb_list[k]
            o = hb_other[hh]
            m1 = 0.5 * (x[a, 0] + x[o, 0])
            m2 = 0.5 * (x[a, 1] + x[o, 1])
            lh = math.sqrt((m1 - x[a, 0]) ** 2 + (m2 - x[a, 1]) ** 2)
            for it in range(start[cell], start[cell + 1]):
                sm = items[it]
                mp = segs[sm, 0]
                mq = segs[sm, 1]
                e1 = x[mq, 0] - x[mp, 0]
                e2 = x[mq, 1] - x[mp, 1]
                Ls = math.sqrt(e1 * e1 + e2 * e2)
                c1 = -e2 / Ls  # common normal for this master segment
                c2 = e1 / Ls
                # the half-edge must face the segment: its direction is across c
                u0 = ((x[a, 0] - x[mp, 0]) * e1 + (x[a, 1] - x[mp, 1]) * e2) / (Ls * Ls)
                u1 = ((m1 - x[mp, 0]) * e1 + (m2 - x[mp, 1]) * e2) / (Ls * Ls)
                off = abs((x[a, 0] - x[mp, 0]) * c1 + (x[a, 1] - x[mp, 1]) * c2)
                if off > reach or c1 * n1 + c2 * n2 < 0.5:
                    continue
                lo = min(u0, u1)
                hi = max(u0, u1)
                for side in range(2):
                    b = mp if side == 0 else mq
                    ov = min(hi, 0.5 + 0.5 * side) - max(lo, 0.5 * side)
                    if ov <= 0.0:
                        continue
                    ell = ov * Ls
                    kB = node_mat[b]
                    tA1 = sig[a, 0] * c1 + sig[a, 1] * c2
                    tA2 = sig[a, 1] * c1 + sig[a, 2] * c2
                    tB1 = sig[b, 0] * c1 + sig[b, 1] * c2
                    tB2 = sig[b, 1] * c1 + sig[b, 2] * c2
                    tn, ts, vn, vsA, vsB = contact_state(
                        v[a, 0], v[a, 1], tA1, tA2, v[b, 0], v[b, 1], tB1, tB2, c1, c2, zpA,
                        zsA, mat[kB, RHO] * mat[kB, CP], mat[kB, RHO] * mat[kB, CS], stick)
                    if tn > 0.0:
                        continue  # this overlap would be in tension: released
                    f1 = weight * ell * (tn * c1 - ts * c2)
                    f2 = weight * ell * (tn * c2 + ts * c1)
                    force_acc[a, 0] += f1
                    force_acc[a, 1] += f2
                    force_acc[b, 0] -= f1
                    force_acc[b, 1] -= f2
                    fsum[0] += sign * f1
                    fsum[1] += sign * f2
                    w1 = vn * c1 - vsA * c2
                    w2 = vn * c2 + vsA * c1
                    vhb[hh, 0] += w1 * ell / lh
                    vhb[hh, 1] += w2 * ell / lh
                    cover[hh] += ell / lh
                    l_total += ell
                    vs1 += w1 * ell
                    vs2 += w2 * ell
                    tn_sum += tn * ell
        if l_total == 0.0:
            continue
        state[a] = STICK if stick else SLIP
        vstar[a, 0] = vs1 / l_total
        vstar[a, 1] = vs2 / l_total
        _contact_motion(a, v, vstar, n1, n2, weight * g / dt, xdot)
        tstar_n[a] = tn_sum / l_total
    return gmin


@njit(cache=True)
def wall_pass(x, v, F, sig, node_mat, mat, slave, hb_start, hb_list, hb_C, vhb, cover,
              node_length, p0, nw, wall_v, dt, stick, was_active, apply, state, vstar, xdot,
              tstar_n, force_acc, fsum):
    """Nodes of one body against a rigid plane through p0 with normal nw (out of the wall)."""
    gmin = np.inf
    n1 = -nw[0]
    n2 = -nw[1]
    for i in range(slave.shape[0]):
        a = slave[i]
        g = (x[a, 0] - p0[0]) * nw[0] + (x[a, 1] - p0[1]) * nw[1]
        if g < gmin:
            gmin = g
        if not apply:
            continue
        gdot = (v[a, 0] - wall_v[0]) * nw[0] + (v[a, 1] - wall_v[1]) * nw[1]
        if not _candidate(g, gdot, dt, was_active[a], node_length[a]):
            continue
        k = node_mat[a]
        zpA = mat[k, RHO] * mat[k, CP]
        zsA = mat[k, RHO] * mat[k, CS]
        tA1 = sig[a, 0] * n1 + sig[a, 1] * n2
        tA2 = sig[a, 1] * n1 + sig[a, 2] * n2
        tn, ts, vn, vsA = wall_state(v[a, 0], v[a, 1], tA1, tA2, n1, n2, zpA, zsA, wall_v[0],
                                     wall_v[1], stick)
        if tn > 0.0:
            continue
        length = _facing_length(a, n1, n2, F, hb_start, hb_list, hb_C, vhb, cover,
                                vn * n1 - vsA * n2, vn * n2 + vsA * n1)
        if length == 0.0:
            continue
        state[a] = STICK if stick else SLIP
        vstar[a, 0] = vn * n1 - vsA * n2
        vstar[a, 1] = vn * n2 + vsA * n1
        _contact_motion(a, v, vstar, n1, n2, g / dt, xdot)
        tstar_n[a] = tn
        f1 = length * (tn * n1 - ts * n2)
        f2 = length * (tn * n2 + ts * n1)
        force_acc[a, 0] += f1
        force_acc[a, 1] += f2
        fsum[0] += f1
        fsum[1] += f2
    return gmin


@njit(cache=True)
def reset_surface(nodes, contact_hb, state, force_acc, tstar_n, vhb, cover):
    for i in range(nodes.shape[0]):
        a = nodes[i]
        state[a] = OPEN
        force_acc[a, 0] = 0.0
        force_acc[a, 1] = 0.0
        tstar_n[a] = 0.0
    for k in range(contact_hb.shape[0]):
        h = contact_hb[k]
        vhb[h, 0] = 0.0
        vhb[h, 1] = 0.0
        cover[h] = 0.0


@njit(cache=True)
def mark_contact_halfedges(contact_hb, cover, hb_active):
    """Half-edges touched by a contact overlap leave the free-surface flux to the contact."""
    for k in range(contact_hb.shape[0]):
        h = contact_hb[k]
        hb_active[h] = cover[h] > 0.0


@njit(cache=True)
def apply_contact(nodes, contact_hb, hb_node, hb_C, hb_active, vhb, cover, state, vstar, xdot,
                  force_acc, fixed_mask, fixed_value, force, dF):
    """Add contact forces; half-edges in contact carry their mean v* in the F equation.

    Velocity components prescribed by a boundary condition (e.g. a roller side meeting the
    contact face at a corner) win over the contact velocity.
    """
    for i in range(nodes.shape[0]):
        a = nodes[i]
        force[a, 0] += force_acc[a, 0]
        force[a, 1] += force_acc[a, 1]
        if state[a] != OPEN:
            for c in range(2):
                if fixed_mask[a, c]:
                    vstar[a, c] = fixed_value[a, c]
                    xdot[a, c] = fixed_value[a, c]
    for k in range(contact_hb.shape[0]):
        h = contact_hb[k]
        if not hb_active[h]:
            continue
        a = hb_node[h]
        w1 = vhb[h, 0] / cover[h]
        w2 = vhb[h, 1] / cover[h]
        for c in range(2):
            if fixed_mask[a, c]:
                if c == 0:
                    w1 = fixed_value[a, 0]
                else:
                    w2 = fixed_value[a, 1]
        dF[a, 0] += w1 * hb_C[h, 0]
        dF[a, 1] += w1 * hb_C[h, 1]
        dF[a, 2] += w2 * hb_C[h, 0]
        dF[a, 3] += w2 * hb_C[h, 1]
