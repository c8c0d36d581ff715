"""The loop bodies of one Runge-Kutta stage, written once for every backend (docs/theory.md).

Each body is a point function for one node or one dual face: it gathers what it needs by
index from the global arrays, calls the physics (impactfv.physics) and leaves its result in
scratch arrays that the caller provides (it never allocates). The loops around them live in
the backends: backends/cpu.py compiles them with ``compiled.point`` and scatters edge
results by node runs in thread blocks; backends/cuda.py compiles them with
``compiled.device`` and scatters with atomic additions. Per node a (seed eq. 9)::

    Omega_a rho_a dv_a/dt = sum_b t_ab |C_ab| + sum_gamma t_gamma |C_gamma|
    Omega_a dF_a/dt      = sum_b v_ab (x) C_ab + sum_gamma v_gamma (x) C_gamma
    dx_a/dt              = v_a

``options`` of the edge flux is the tuple (reconstruct, stress_reconstructed,
upwind_geometric, muscl_chi, smooth_switch) of the run (scheme.stepper): the first three
compile-time variants (compiled.variant, or constants of the CUDA kernels), the last two
values.
"""

import math

from ..physics.limiters import BARTH_JESPERSEN, NONE, blend_weight, limiter_factor, switch_scales
from ..physics.materials import CP, CS, RHO, strain_power
from ..physics.riemann import (boundary_state, central_velocity, face_area_normal,
                               face_geometry, face_traction, geometric_boundary_velocity,
                               upwind_traction_area, upwind_velocity)
from ..physics.runge_kutta import rk_stage
from ..physics.tensors import symmetric_index

#: rows of the edge flux's ``work`` (d-vectors): the face's results are its last two rows
EDGE_WORK_ROWS = 11
EDGE_FORCE, EDGE_VELOCITY = 9, 10
#: rows of the boundary face's ``work``: its results are the contact-free face's
#: traction t^C, velocity v^C and F-equation velocity u
FACE_WORK_ROWS = 11
FACE_TRACTION, FACE_STATE_VELOCITY, FACE_VELOCITY = 8, 9, 10


def reconstructed_pair(ua, ub, ra, rb, phi_a, phi_b, bias):
    """The two sides' values of one field at the midpoint of edge ab, from the nodes' values
    ua, ub and their limited linear reconstructions ra = grad u_a . (X_mid - X_a),
    rb = grad u_b . (X_mid - X_a): ua + ra and ub - rb, or with the U-MUSCL blend (``bias``
    chi > 0) ua + (1 - c) ra + c phi_a (ub - ua) / 2 and ub - (1 - c) rb - c phi_b (ub - ua) / 2,
    phi the limiter factors and c the edge's weight (physics.limiters.blend_weight)."""
    if bias == 0.0:
        return ua + ra, ub - rb
    change = ub - ua
    c = blend_weight(bias, change, ra, rb)
    return (ua + ((1.0 - c) * ra + 0.5 * c * phi_a * change),
            ub - ((1.0 - c) * rb + 0.5 * c * phi_b * change))


def reconstructed_stresses(sigma, grad, a, b, e, half, stress_reconstructed, bias, Sa, Sb):
    """Sa = sigma_a and Sb = sigma_b, reconstructed to the midpoint of edge e = ab (offset
    half[e] = X_mid - X_a) when the stress is reconstructed:
    each component by :func:`reconstructed_pair` with r = grad sigma . (X_mid - X_a)
    (limited) and phi the limiter factor (grad[., row, d])."""
    d = Sa.shape[0]
    for i in range(d):
        for j in range(i, d):
            sa = sigma[a, i, j]
            sb = sigma[b, i, j]
            if stress_reconstructed:
                row = d + symmetric_index(i, j, d)
                ra = 0.0
                rb = 0.0
                for K in range(d):
                    ra += grad[a, row, K] * half[e, K]
                    rb += grad[b, row, K] * half[e, K]
                sa, sb = reconstructed_pair(sa, sb, ra, rb, grad[a, row, d], grad[b, row, d],
                                            bias)
            Sa[i, j] = sa
            Sa[j, i] = sa
            Sb[i, j] = sb
            Sb[j, i] = sb


def edge_flux(e, a, b, v, F, sigma, grad, props, C, C_len, half, options, contact_state, Fe,
              Sa, Sb, work):
    """Upwind traction (seed eqs. 9a-9b: eq. 9a) and geometric velocity (eq. 9b) of the
    interior dual face of edge e = ab, area vector C[e] (length C_len[e]), midpoint offset
    half[e] = X_mid - X_a:
    the force on a's cell into work[EDGE_FORCE] (b's is its negative) and the velocity whose
    product with C_e enters Omega dF/dt into work[EDGE_VELOCITY].

    Both sides' forces are sigma m, with m = da n = cof(F) C_ab the face's own spatial area
    vector (from the mean F of the edge), so a rigid rotation of a stressed state makes no
    traction jump; the face is handled through its area vectors throughout (impedances
    rho c |C_ab|), which needs neither its unit normal nor a division by its area. With
    ``reconstruct`` the velocities are reconstructed linearly to the edge midpoint from each
    side (grad rows 0..d-1); with ``stress_reconstructed`` the stresses as well (grad rows
    d..). ``smooth_switch``: the smoothness switch's chi (0: off), not applied on the edges
    of nodes in contact (contact_state != 0), which keep the whole upwind dissipation.
    Fe, Sa, Sb: d x d scratch; work: EDGE_WORK_ROWS x d scratch."""
    reconstruct, stress_reconstructed, upwind_geometric, bias, switch = options
    d = Fe.shape[0]
    A, m, va, vb, w, fa, fb = work[0], work[1], work[2], work[3], work[4], work[5], work[6]
    fbar, fjump, f, u = work[7], work[8], work[EDGE_FORCE], work[EDGE_VELOCITY]
    area = C_len[e]
    zp = props[RHO] * props[CP] * area
    zs = props[RHO] * props[CS] * area
    for i in range(d):
        A[i] = C[e, i]
        for J in range(d):
            Fe[i, J] = 0.5 * (F[a, i, J] + F[b, i, J])
    inverse_m2 = face_area_normal(Fe, A, props, m)
    for i in range(d):
        va[i] = v[a, i]
        vb[i] = v[b, i]
    if not upwind_geometric:
        # central (seed eq. 9b as written): keeps F the gradient of x at interior nodes
        central_velocity(va, vb, u)
    if reconstruct:
        for i in range(d):
            ra = 0.0
            rb = 0.0
            for J in range(d):
                ra += grad[a, i, J] * half[e, J]
                rb += grad[b, i, J] * half[e, J]
            va[i], vb[i] = reconstructed_pair(va[i], vb[i], ra, rb, grad[a, i, d],
                                              grad[b, i, d], bias)
    reconstructed_stresses(sigma, grad, a, b, e, half, stress_reconstructed, bias, Sa, Sb)
    face_traction(Sa, m, 1.0, fa)
    face_traction(Sb, m, 1.0, fb)
    for i in range(d):
        w[i] = vb[i] - va[i]
        fbar[i] = 0.5 * (fa[i] + fb[i])
        fjump[i] = fb[i] - fa[i]
    zp_v = zp
    zs_v = zs
    if switch != 0.0 and contact_state[a] == 0 and contact_state[b] == 0:
        # the smoothness switch (docs/theory.md) scales the momentum flux's upwind term
        # through its impedances and the geometric flux's through the force jump
        scale_v, scale_t = switch_scales(switch, v, sigma, a, b, w, Sa, Sb, upwind_geometric)
        zp_v = zp * scale_v
        zs_v = zs * scale_v
        for i in range(d):
            fjump[i] *= scale_t
    upwind_traction_area(fbar, w, zp_v, zs_v, m, inverse_m2, f)
    if upwind_geometric:
        # [[f]] / (2 rho c_p |C|) = [[t]] / (2 rho c_p)
        upwind_velocity(va, vb, fjump, zp, u)


def boundary_face_flux(h, a, v, F, sigma, props, bface_others, bface_C, own,
                       inverse_denominator, bc_fixed, bc, prescribed_velocity,
                       prescribed_traction, tangential_correction, Fi, Si, Z, work):
    """The Riemann state of dual boundary face h of node a (seed eqs. 9a-9b at the
    boundary): the traction t^C into work[FACE_TRACTION], the velocity v^C into
    work[FACE_STATE_VELOCITY], the F equation's velocity into work[FACE_VELOCITY]; returns
    the face's area |C|. The interior state on the face is (own u_a + the sum over the
    facet's other nodes) * inverse_denominator (the boundary closure). bc_fixed[bc]: the
    face's boundary condition, which components it prescribes (velocity) or not
    (traction); a component the node's velocity is held at (e.g. by the clamp of a
    neighbouring region at a corner) is held on all its faces. Fi, Si, Z: d x d scratch;
    work: FACE_WORK_ROWS x d scratch."""
    d = Fi.shape[0]
    N, n, vi, ti, rhs = work[0], work[1], work[2], work[3], work[4]
    fix, given, tgiven = work[5], work[6], work[7]
    tC, vC, u = work[FACE_TRACTION], work[FACE_STATE_VELOCITY], work[FACE_VELOCITY]
    zp = props[RHO] * props[CP]
    zs = props[RHO] * props[CS]
    ln = 0.0
    for J in range(d):
        ln += bface_C[h, J] * bface_C[h, J]
    ln = math.sqrt(ln)
    for J in range(d):
        N[J] = bface_C[h, J] / ln
    # the facet's other nodes by index: a view bface_others[h] would cost a reference count
    # on the CPU, twice the time of the face
    for i in range(d):
        vi[i] = own * v[a, i]
        for q in range(d - 1):
            vi[i] += v[bface_others[h, q], i]
        vi[i] *= inverse_denominator
        for J in range(d):
            Fi[i, J] = own * F[a, i, J]
            Si[i, J] = own * sigma[a, i, J]
            for q in range(d - 1):
                o = bface_others[h, q]
                Fi[i, J] += F[o, i, J]
                Si[i, J] += sigma[o, i, J]
            Fi[i, J] *= inverse_denominator
            Si[i, J] *= inverse_denominator
    area = face_geometry(Fi, N, props, n)
    face_traction(Si, n, area, ti)
    for i in range(d):
        fix[i] = 1.0 if bc_fixed[bc, i] else 0.0
        given[i] = prescribed_velocity[h, i]
        tgiven[i] = prescribed_traction[h, i]
    boundary_state(vi, ti, zp, zs, n, fix, given, tgiven, Z, rhs, vC, tC)
    # the F equation's velocity: the prescribed one, or the interior one corrected along
    # the normal only or in every direction (physics.riemann.geometric_boundary_velocity)
    geometric_boundary_velocity(vi, ti, tC, vC, fix, zp, n, tangential_correction, u)
    return ln


def node_update(a, alpha, dt, v0, F0, x0, v, F, x, force, dF, in_contact, contact_xdot,
                props, volume, fixed_mask, fixed_value, Fa):
    """One Runge-Kutta stage (seed section 4; physics.runge_kutta.rk_stage) of node a's
    v, F and x, the new F also into Fa (d x d). Positions move with the nodal velocity, or
    in contact with the contact velocity; prescribed velocity components are imposed
    strongly. Returns whether the new velocity is finite."""
    d = Fa.shape[0]
    inv_volume = 1.0 / volume[a]
    inv_mass = inv_volume / props[RHO]
    finite = True
    for i in range(d):
        xdot = contact_xdot[a, i] if in_contact else v[a, i]
        x[a, i] = rk_stage(alpha, x0[a, i], x[a, i], dt, xdot)
        vn = rk_stage(alpha, v0[a, i], v[a, i], dt, force[a, i] * inv_mass)
        if fixed_mask[a, i]:
            vn = fixed_value[a, i]
        v[a, i] = vn
        finite = finite and math.isfinite(vn)
    for i in range(d):
        for J in range(d):
            f = rk_stage(alpha, F0[a, i, J], F[a, i, J], dt, dF[a, i, J] * inv_volume)
            F[a, i, J] = f
            Fa[i, J] = f
    return finite


def node_monitors(a, v, props, volume, strain_energy_density):
    """Node a's share of its body's monitors: kinetic energy m v.v / 2, strain energy
    Omega W (``strain_energy_density`` W of its F) and the components of linear momentum
    m v (the third 0 in 2D), m = rho Omega."""
    d = v.shape[1]
    mass = props[RHO] * volume[a]
    v2 = 0.0
    for i in range(d):
        v2 += v[a, i] * v[a, i]
    third = mass * v[a, d - 1] if d == 3 else 0.0
    return 0.5 * mass * v2, volume[a] * strain_energy_density, mass * v[a, 0], \
        mass * v[a, 1], third


def node_energy_rate(a, v, force, F, sigma, dF, fixed_mask, props, Fa, Sa, Da):
    """The rate of node a's kinetic and strain energy as its rates give it (docs/theory.md,
    "Energy balance"): v . f over the velocity components that are not held, plus
    P : Omega dF/dt with the first Piola stress P = sigma cof F, or P = sigma for the
    small-strain law (physics.materials.strain_power). Read before the node's state is
    updated. Fa, Sa, Da: d x d scratch."""
    d = Fa.shape[0]
    rate = 0.0
    for i in range(d):
        if not fixed_mask[a, i]:
            rate += v[a, i] * force[a, i]
    for i in range(d):
        for J in range(d):
            Fa[i, J] = F[a, i, J]
            Sa[i, J] = sigma[a, i, J]
            Da[i, J] = dF[a, i, J]
    return rate + strain_power(Sa, Fa, Da, props)


def stage_change(a, inv_dt, v0, F0, v, F, force, dF, props, volume, fixed_mask, change,
                 midway):
    """What the energy the two-stage step adds at node a needs (docs/theory.md, "Energy
    balance"; physics.runge_kutta.heun_energy_excess), read at the last stage before the
    update: the change of the rates between the stages, L1 - (u* - u0) / dt, as the squared
    change of the acceleration over the components not held (returned) and the change of
    dF/dt into ``change``; the state midway between u0 and u* into ``midway`` (d x d)."""
    d = change.shape[0]
    inv_volume = 1.0 / volume[a]
    inv_mass = inv_volume / props[RHO]
    dv2 = 0.0
    for i in range(d):
        if not fixed_mask[a, i]:
            dv = force[a, i] * inv_mass - (v[a, i] - v0[a, i]) * inv_dt
            dv2 += dv * dv
    for i in range(d):
        for J in range(d):
            change[i, J] = dF[a, i, J] * inv_volume - (F[a, i, J] - F0[a, i, J]) * inv_dt
            midway[i, J] = 0.5 * (F0[a, i, J] + F[a, i, J])
    return dv2


def relaxation_change(a, D, weight, node_edge_start, node_neighbour, dF, weighted):
    """The compatibility relaxation at node a (docs/theory.md, "Compatibility relaxation"):
    dF_a -= sum over a's edge neighbours b of w_ab (D_a - D_b), D = F - G(x) the mismatch of
    F with the gradient of the positions, w_ab = w_ba per slot of node_neighbour. A
    difference operator: a uniform D is not relaxed, the grid-scale modes at the full rate.
    ``weighted``: d x d scratch."""
    d = weighted.shape[0]
    # sum_b w_ab (D_a - D_b) = (sum_b w_ab) D_a - sum_b w_ab D_b: each neighbour read once
    for i in range(d):
        for J in range(d):
            weighted[i, J] = 0.0
    total = 0.0
    for k in range(node_edge_start[a], node_edge_start[a + 1]):
        b = node_neighbour[k]
        w = weight[k]
        total += w
        for i in range(d):
            for J in range(d):
                weighted[i, J] += w * D[b, i, J]
    for i in range(d):
        for J in range(d):
            dF[a, i, J] -= total * D[a, i, J] - weighted[i, J]


def slot(i, J, d, m):
    """Where component i, direction J of a node's gradient sums sits in its scratch: the
    field index innermost in 3D, so that the loops over the nine fields run on contiguous
    entries (packed into vector instructions on the CPU), the direction innermost in 2D,
    where that order is the faster one."""
    return J * m + i if d == 3 else i * d + J


def gradient_sums(a, U, x, dual, own, inverse_denominator, with_positions, scratch):
    """The unscaled Green-Gauss sums of node a's gradient: into g (at slot()) the sum over
    a's edges of (u_a + u_b)/2 C_ab plus over its dual boundary faces of the closure state
    times the face's area vector, for every field of U (n, m); into lo, hi the range of a
    and its neighbours; with ``with_positions`` into gx the same sums for the positions x.
    ``dual``: (node_edge_start, node_neighbour, node_C, node_half, bface_start,
    bface_others, bface_C, volume); ``scratch``: (g, lo, hi, ua, gx, temp, rise, fall)."""
    node_edge_start, node_neighbour, node_C, _, bface_start, bface_others, bface_C, _ = dual
    g, lo, hi, ua, gx, temp, _, _ = scratch
    m = ua.shape[0]
    d = gx.shape[0]
    for i in range(m):
        ua[i] = U[a, i]
        lo[i] = ua[i]
        hi[i] = ua[i]
    for s in range(m * d):
        g[s] = 0.0
    for i in range(d):
        for J in range(d):
            gx[i, J] = 0.0
    for k in range(node_edge_start[a], node_edge_start[a + 1]):
        b = node_neighbour[k]
        if d == 3:
            for J in range(d):
                c = node_C[k, J]
                for i in range(m):
                    g[slot(i, J, d, m)] += 0.5 * (ua[i] + U[b, i]) * c
        else:
            for i in range(m):
                mean = 0.5 * (ua[i] + U[b, i])
                for J in range(d):
                    g[slot(i, J, d, m)] += mean * node_C[k, J]
        if with_positions:
            for i in range(d):
                mean = 0.5 * (x[a, i] + x[b, i])
                for J in range(d):
                    gx[i, J] += mean * node_C[k, J]
        for i in range(m):
            lo[i] = min(lo[i], U[b, i])
            hi[i] = max(hi[i], U[b, i])
    for h in range(bface_start[a], bface_start[a + 1]):
        # the closure's mean as a product (1/8 is exact in 3D)
        if d == 3:
            for i in range(m):
                temp[i] = own * ua[i]
            for q in range(d - 1):
                o = bface_others[h, q]
                for i in range(m):
                    temp[i] += U[o, i]
            for i in range(m):
                temp[i] *= inverse_denominator
            for J in range(d):
                c = bface_C[h, J]
                for i in range(m):
                    g[slot(i, J, d, m)] += temp[i] * c
        else:
            for i in range(m):
                mean = own * ua[i]
                for q in range(d - 1):
                    mean += U[bface_others[h, q], i]
                mean *= inverse_denominator
                for J in range(d):
                    g[slot(i, J, d, m)] += mean * bface_C[h, J]
        if with_positions:
            for i in range(d):
                mean = own * x[a, i]
                for q in range(d - 1):
                    mean += x[bface_others[h, q], i]
                mean *= inverse_denominator
                for J in range(d):
                    gx[i, J] += mean * bface_C[h, J]


def limited_gradient_of_node(a, dual, kind, scratch, grad):
    """Node a's gradient from its sums (gradient_sums), limited (the TVD limiter of the seed
    paper's abstract; physics.limiters): each field's gradient is scaled by the smallest
    factor over the node's edges (midpoint offsets node_half = X_mid - X_a) that keeps the
    reconstructed midpoint values within the range of the node and its neighbours; the
    factor phi into grad[a, i, d]. Barth-Jespersen's factor falls as the change grows, so
    its smallest value over the edges is that of the largest rise and of the deepest fall:
    two evaluations per field instead of one per edge (the same result). Venkatakrishnan's
    factor is evaluated on every edge."""
    node_edge_start, _, _, node_half, _, _, _, volume = dual
    g, lo, hi, ua, gx, temp, rise, fall = scratch
    m = ua.shape[0]
    d = gx.shape[0]
    inv = 1.0 / volume[a]
    if kind == NONE:
        for i in range(m):
            for J in range(d):
                grad[a, i, J] = g[slot(i, J, d, m)] * inv
            grad[a, i, d] = 1.0
    elif kind == BARTH_JESPERSEN:
        # the largest rise and fall of the midpoint values over the node's edges, from the
        # unscaled sums (a factor Omega_a on every change; scaled once per field)
        for i in range(m):
            rise[i] = 0.0
            fall[i] = 0.0
        for k in range(node_edge_start[a], node_edge_start[a + 1]):
            if d == 3:
                # the fields innermost, on contiguous sums (vector instructions)
                for i in range(m):
                    temp[i] = 0.0
                for J in range(d):
                    offset = node_half[k, J]
                    for i in range(m):
                        temp[i] += g[slot(i, J, d, m)] * offset
                for i in range(m):
                    rise[i] = max(rise[i], temp[i])
                    fall[i] = min(fall[i], temp[i])
            else:
                for i in range(m):
                    change = 0.0
                    for J in range(d):
                        change += g[slot(i, J, d, m)] * node_half[k, J]
                    rise[i] = max(rise[i], change)
                    fall[i] = min(fall[i], change)
        for i in range(m):
            u = ua[i]
            # a change below 1e-10 of the local range needs no limiting; without this
            # tolerance a round-off sized change at an extremum would switch phi to 0
            tolerance = 1e-10 * (hi[i] - lo[i])
            phi = 1.0
            up = rise[i] * inv
            if up > tolerance:
                phi = min(phi, limiter_factor(kind, u, lo[i], hi[i], up))
            down = fall[i] * inv
            if down < -tolerance:
                phi = min(phi, limiter_factor(kind, u, lo[i], hi[i], down))
            scale = phi * inv
            for J in range(d):
                grad[a, i, J] = g[slot(i, J, d, m)] * scale
            grad[a, i, d] = phi
    else:
        for s in range(m * d):
            g[s] = g[s] * inv
        for i in range(m):
            u = ua[i]
            tolerance = 1e-10 * (hi[i] - lo[i])
            phi = 1.0
            for k in range(node_edge_start[a], node_edge_start[a + 1]):
                change = 0.0
                for J in range(d):
                    change += g[slot(i, J, d, m)] * node_half[k, J]
                if abs(change) > tolerance:
                    phi = min(phi, limiter_factor(kind, u, lo[i], hi[i], change))
            for J in range(d):
                grad[a, i, J] = g[slot(i, J, d, m)] * phi
            grad[a, i, d] = phi


def node_gradient(a, U, x, F, dual, own, inverse_denominator, kind, with_positions, scratch,
                  grad, mismatch):
    """The limited Green-Gauss gradient of every field of U at node a into grad[a] (the TVD
    limiter of the seed paper's abstract), exact for linear fields: (sum over edges ab of
    (u_a + u_b)/2 C_ab + sum over the dual boundary faces of the closure state times C) /
    Omega_a, limited by limited_gradient_of_node. With ``with_positions`` also the mismatch
    D_a = F_a - G_a(x) of the compatibility relaxation, G(x) the unlimited gradient of the
    positions by the same sums (each neighbour's area vector read once for both)."""
    gradient_sums(a, U, x, dual, own, inverse_denominator, with_positions, scratch)
    if with_positions:
        gx = scratch[4]
        d = gx.shape[0]
        inv = 1.0 / dual[7][a]
        for i in range(d):
            for J in range(d):
                mismatch[a, i, J] = F[a, i, J] - gx[i, J] * inv
    limited_gradient_of_node(a, dual, kind, scratch, grad)
