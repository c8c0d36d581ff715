"""Compiled loops of one Runge-Kutta stage of the p-F scheme (docs/theory.md).

Semi-discrete equations on the median dual, per node a (seed eq. 9)::

    Omega_a rho_a dv_a/dt = sum_b t_ab |C_ab| + sum_gamma t_gamma |C_gamma|
    Omega_a dF_a/dt      = sum_b v_ab (x) C_ab + sum_gamma v_gamma (x) C_gamma
    dx_a/dt              = v_a

The physics lives in point functions (scheme.riemann, scheme.limiters, scheme.time,
materials); these loops only gather their inputs and scatter their results. Every kernel
takes ``dim``, a tuple of d zeros (backends.cpu.dim_tag), so that the dimension is a
compile-time constant, and hands the point functions local copies (backends.cpu). Loops over nodes are parallel; the edge loops run by node block
(Discretisation.edge_offsets): blocks in parallel, the edges joining two blocks afterwards.
"""

import numpy as np
from numba import njit, prange

from .. import materials as M
from ..backends.cpu import (KERNEL_FASTMATH, load_matrix, load_vector, local_components,
                            local_matrix, local_rows, local_scratch, local_vector, point,
                            store_matrix)
from ..tensors import determinant as _determinant
from ..tensors import symmetric_index as _symmetric_index
from . import limiters as L
from . import riemann as R
from . import time as T

cauchy_stress = point(M.cauchy_stress)
# cold paths (on-demand monitors, output fields): called, not inlined (backends.cpu.point)
strain_energy_density = point(M.strain_energy_density, inline=False)
cauchy_stress_and_energy = point(M.cauchy_stress_and_energy)
pressure_and_von_mises = point(M.pressure_and_von_mises, inline=False)
min_stretch = point(M.min_stretch)
min_stretch_bounds = point(M.min_stretch_bounds)
determinant = point(_determinant)
strain_power = point(M.strain_power)
symmetric_index = point(_symmetric_index)
face_geometry = point(R.face_geometry)
face_traction = point(R.face_traction)
face_area_normal = point(R.face_area_normal)
upwind_traction_area = point(R.upwind_traction_area)
central_velocity = point(R.central_velocity)
upwind_velocity = point(R.upwind_velocity)
boundary_state = point(R.boundary_state)
geometric_boundary_velocity = point(R.geometric_boundary_velocity)
limiter_factor = point(L.limiter_factor)
blend_weight = point(L.blend_weight)
switch_scales = point(L.switch_scales)
rk_stage = point(T.rk_stage)
heun_energy_excess = point(T.heun_energy_excess)

RHO, CP, CS = M.RHO, M.CP, M.CS


@njit(cache=True, parallel=True, fastmath=KERNEL_FASTMATH)
def compute_stress(F, node_material, table, sigma, dim):
    """Cauchy stress sigma_a = sigma(F_a) at every node (the material law)."""
    d = len(dim)
    for a in prange(F.shape[0]):
        Fa = local_matrix(d)
        sa = local_matrix(d)
        load_matrix(F, a, Fa)
        cauchy_stress(Fa, table[node_material[a]], sa)
        store_matrix(sa, sigma, a)


@njit(cache=True, parallel=True, fastmath=KERNEL_FASTMATH)
def stress_and_fields(F, v, node_material, table, sigma, U, dim):
    """:func:`compute_stress` and :func:`pack_velocity_and_stress` in one pass: sigma_a,
    and U[a] = (v_a, the independent components of sigma_a) while sigma_a is in registers."""
    d = len(dim)
    for a in prange(F.shape[0]):
        Fa = local_matrix(d)
        sa = local_matrix(d)
        load_matrix(F, a, Fa)
        cauchy_stress(Fa, table[node_material[a]], sa)
        store_matrix(sa, sigma, a)
        for i in range(d):
            U[a, i] = v[a, i]
            for j in range(i, d):
                U[a, d + symmetric_index(i, j, d)] = sa[i, j]


@njit(cache=True, parallel=True, fastmath=KERNEL_FASTMATH)
def pack_velocity_and_stress(v, sigma, U, dim):
    """U[a] = (v_a, the independent components of sigma_a): the fields reconstructed to the
    faces."""
    d = len(dim)
    for a in prange(v.shape[0]):
        for i in range(d):
            U[a, i] = v[a, i]
            for j in range(i, d):
                U[a, d + symmetric_index(i, j, d)] = sigma[a, i, j]


@njit(inline="always")
def slot(i, J, d, m):
    """Where component i, direction J of a node's gradient sums sits in its scratch: the
    field index innermost in 3D, so that the loops over the nine fields run on contiguous
    entries (packed into vector instructions; 2.3 times faster, docs/performance.md), the
    direction innermost in 2D, where that order is the faster one."""
    return J * m + i if d == 3 else i * d + J


@njit(cache=True, parallel=True, fastmath=KERNEL_FASTMATH)
def limited_gradient(v, node_edge_start, node_neighbour, node_C, node_half, bface_start,
                     bface_others, bface_C, closure, volume, kind, grad, dim, components,
                     x, F, mismatch, with_positions):
    """Limited Green-Gauss nodal gradient grad[a, i, J] of every component i of the nodal
    field v (n, m). ``components`` is a tuple of m zeros (a compile-time m, like ``dim``).
    With ``with_positions`` the same pass also gives the mismatch D = F - G(x) (n, d, d) of
    the compatibility relaxation (relax_towards_positions), G(x) the unlimited Green-Gauss
    gradient of the positions x (n, d): each neighbour's area vector is read once for both
    (the same sums as the gradient of v = x without limiter), and the relaxation then reads
    one 3 x 3 block per neighbour instead of F's and G's.

    Gradient (exact for linear fields): grad_a = (sum over edges ab of (v_a + v_b)/2 C_ab +
    sum over the node's dual boundary faces of the closure state times S/d) / Omega_a, with
    node_C the area vector seen from a (node_edge_start / node_neighbour list a's edges,
    bface_start its boundary faces). Limiter (``kind``, scheme.limiters): each component's
    gradient is scaled by the smallest factor over the node's edges (midpoint offsets
    node_half = X_mid - X_a) that keeps the reconstructed midpoint values within the range of
    the node and its neighbours. A gather over nodes: each node reads its neighbours once and
    writes only its own rows (no race, no edge blocks); gradient and range stay on the stack.

    Barth-Jespersen's factor min(1, dmax / change) falls as the change grows, so its
    smallest value over the edges is that of the largest positive and of the most negative
    change: two evaluations per component instead of one per edge (the same result).
    Venkatakrishnan's factor is evaluated on every edge."""
    d = len(dim)
    m = len(components)
    own, denominator = closure
    # the closure's mean as a product (1/8 is exact in 3D; one division per call, not per face)
    inverse_denominator = 1.0 / denominator
    for a in prange(v.shape[0]):
        g = local_scratch(m * d)      # the unscaled gradient sums, component (i, J) at slot()
        lo = local_components(m)
        hi = local_components(m)
        ua = local_components(m)
        for i in range(m):
            ua[i] = v[a, i]
            lo[i] = ua[i]
            hi[i] = ua[i]
        for s in range(m * d):
            g[s] = 0.0
        gx = local_matrix(d)          # the positions' gradient sums (with_positions)
        xa = local_components(d)
        for i in range(d):
            xa[i] = x[a, i]
            for J in range(d):
                gx[i, J] = 0.0
        for k in range(node_edge_start[a], node_edge_start[a + 1]):
            b = node_neighbour[k]
            if d == 3:
                for J in range(d):
                    c = node_C[k, J]
                    for i in range(m):
                        g[slot(i, J, d, m)] += 0.5 * (ua[i] + v[b, i]) * c
            else:
                for i in range(m):
                    mean = 0.5 * (ua[i] + v[b, i])
                    for J in range(d):
                        g[slot(i, J, d, m)] += mean * node_C[k, J]
            if with_positions:
                for i in range(d):
                    mean = 0.5 * (xa[i] + x[b, i])
                    for J in range(d):
                        gx[i, J] += mean * node_C[k, J]
            for i in range(m):
                lo[i] = min(lo[i], v[b, i])
                hi[i] = max(hi[i], v[b, i])
        for h in range(bface_start[a], bface_start[a + 1]):
            if d == 3:
                face = local_components(m)
                for i in range(m):
                    face[i] = own * ua[i]
                for q in range(d - 1):
                    o = bface_others[h, q]
                    for i in range(m):
                        face[i] += v[o, i]
                for i in range(m):
                    face[i] *= inverse_denominator
                for J in range(d):
                    c = bface_C[h, J]
                    for i in range(m):
                        g[slot(i, J, d, m)] += face[i] * c
            else:
                for i in range(m):
                    mean = own * ua[i]
                    for q in range(d - 1):
                        mean += v[bface_others[h, q], i]
                    mean *= inverse_denominator
                    for J in range(d):
                        g[slot(i, J, d, m)] += mean * bface_C[h, J]
            if with_positions:
                for i in range(d):
                    mean = own * xa[i]
                    for q in range(d - 1):
                        mean += x[bface_others[h, q], i]
                    mean *= inverse_denominator
                    for J in range(d):
                        gx[i, J] += mean * bface_C[h, J]
        inv = 1.0 / volume[a]
        if with_positions:
            for i in range(d):
                for J in range(d):
                    mismatch[a, i, J] = F[a, i, J] - gx[i, J] * inv
        if kind == L.NONE:
            for i in range(m):
                for J in range(d):
                    grad[a, i, J] = g[slot(i, J, d, m)] * inv
                grad[a, i, d] = 1.0
        elif kind == L.BARTH_JESPERSEN:
            # the largest rise and fall of the midpoint values over the node's edges, from the
            # unscaled sums (a factor Omega_a on every change; scaled once per component)
            rise = local_components(m)
            fall = local_components(m)
            for i in range(m):
                rise[i] = 0.0
                fall[i] = 0.0
            for k in range(node_edge_start[a], node_edge_start[a + 1]):
                if d == 3:
                    changes = local_components(m)
                    for i in range(m):
                        changes[i] = 0.0
                    for J in range(d):
                        offset = node_half[k, J]
                        for i in range(m):
                            changes[i] += g[slot(i, J, d, m)] * offset
                    for i in range(m):
                        rise[i] = max(rise[i], changes[i])
                        fall[i] = min(fall[i], changes[i])
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


@njit(cache=True, inline="always", fastmath=KERNEL_FASTMATH)
def _reconstruct_stresses(sigma, grad, a, b, e, half, stress_reconstructed, bias, Sa, Sb, d):
    """Sa = sigma_a and Sb = sigma_b, reconstructed to the midpoint of edge e = ab when the
    stress is reconstructed:
    sigma_a + (1 - c) r_a + c phi_a (sigma_b - sigma_a) / 2 and
    sigma_b - (1 - c) r_b - c phi_b (sigma_b - sigma_a) / 2,
    r = grad sigma . (X_mid - X_a) (limited), phi the limiter factor (grad[., row, d]) and c
    the U-MUSCL weight of the edge (limiters.blend_weight of bias), one for both sides."""
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
                if bias == 0.0:
                    sa += ra
                    sb -= rb
                else:
                    change = sb - sa
                    c = blend_weight(bias, change, ra, rb)
                    sa += (1.0 - c) * ra + 0.5 * c * grad[a, row, d] * change
                    sb -= (1.0 - c) * rb + 0.5 * c * grad[b, row, d] * change
            Sa[i, j] = sa
            Sa[j, i] = sa
            Sb[i, j] = sb
            Sb[j, i] = sb


@njit(cache=True, inline="always", fastmath=KERNEL_FASTMATH)
def _flux_edge(e, v, F, sigma, grad, node_material, table, edges, C, C_len, half,
               use_reconstruction, stress_reconstructed, upwind_geometric, bias, switch,
               contact_state, force_a, dF_a, force, dF, d, Fe, Sa, Sb, work):
    """Upwind traction (seed eq. 9a) and geometric velocity (9b) of interior edge e:
    added to its first node's running sums force_a, dF_a (held by the caller while it
    walks that node's edges) and subtracted from its second node's rows of force, dF.

    Both sides' forces are sigma m, with m = da n = cof(F) C_ab the face's own spatial area
    vector (from the mean F of the edge), so a rigid rotation of a stressed state makes no
    traction jump; the face is handled through its area vectors throughout (impedances
    rho c |C_ab|), which needs neither its unit normal nor a division by its area. With
    ``use_reconstruction`` the velocities are reconstructed linearly to the edge
    midpoint from each side (grad rows 0..d-1); with ``stress_reconstructed`` the stresses as
    well (grad rows d..: the independent components of sigma). ``switch``: the smoothness
    switch's chi (limiters.switch_scales; 0: off), not applied on the edges of nodes in
    contact (contact_state != 0), which keep the whole upwind dissipation.
    """
    A, m, va, vb, w, fa, fb = work[0], work[1], work[2], work[3], work[4], work[5], work[6]
    fbar, fjump, f, u = work[7], work[8], work[9], work[10]
    a = edges[e, 0]
    b = edges[e, 1]
    props = table[node_material[a]]
    area = C_len[e]
    zp = props[RHO] * props[CP] * area
    zs = props[RHO] * props[CS] * area
    for i in range(d):
        A[i] = C[e, i]
        for J in range(d):
            Fe[i, J] = 0.5 * (F[a, i, J] + F[b, i, J])
    inverse_m2 = face_area_normal(Fe, A, props, m)
    load_vector(v, a, va)
    load_vector(v, b, vb)
    if not upwind_geometric:
        # central (seed eq. 9b as written): keeps F the gradient of x at interior nodes
        central_velocity(va, vb, u)
    if use_reconstruction:
        for i in range(d):
            ra = 0.0
            rb = 0.0
            for J in range(d):
                ra += grad[a, i, J] * half[e, J]
                rb += grad[b, i, J] * half[e, J]
            if bias == 0.0:
                va[i] += ra
                vb[i] -= rb
            else:
                change = v[b, i] - v[a, i]
                c = blend_weight(bias, change, ra, rb)
                va[i] += (1.0 - c) * ra + 0.5 * c * grad[a, i, d] * change
                vb[i] -= (1.0 - c) * rb + 0.5 * c * grad[b, i, d] * change
    _reconstruct_stresses(sigma, grad, a, b, e, half, stress_reconstructed, bias, Sa, Sb, d)
    face_traction(Sa, m, 1.0, fa)
    face_traction(Sb, m, 1.0, fb)
    for i in range(d):
        w[i] = vb[i] - va[i]
        fbar[i] = 0.5 * (fa[i] + fb[i])
        fjump[i] = fb[i] - fa[i]
    if switch != 0.0 and contact_state[a] == 0 and contact_state[b] == 0:
        # the smoothness switch (docs/theory.md) scales the momentum flux's upwind term
        # through its impedances and the geometric flux's through the force jump
        scale_v, scale_t = switch_scales(switch, v, sigma, a, b, w, Sa, Sb, upwind_geometric)
        zp_v = zp * scale_v
        zs_v = zs * scale_v
        for i in range(d):
            fjump[i] *= scale_t
    else:
        zp_v = zp
        zs_v = zs
    upwind_traction_area(fbar, w, zp_v, zs_v, m, inverse_m2, f)
    for i in range(d):
        force_a[i] += f[i]
        force[b, i] -= f[i]
    if upwind_geometric:
        # [[f]] / (2 rho c_p |C|) = [[t]] / (2 rho c_p)
        upwind_velocity(va, vb, fjump, zp, u)
    for i in range(d):
        for J in range(d):
            dF_a[i, J] += u[i] * C[e, J]
            dF[b, i, J] -= u[i] * C[e, J]


@njit(cache=True, inline="always", fastmath=KERNEL_FASTMATH)
def _interior_fluxes(k, v, F, sigma, grad, node_material, table, edges, C, C_len, half,
                     edge_offsets, use_reconstruction, stress_reconstructed, upwind_geometric,
                     bias, switch, contact_state, force, dF, d):
    Fe = local_matrix(d)
    Sa = local_matrix(d)
    Sb = local_matrix(d)
    work = local_rows(11, d)
    # a group's edges come grouped by their first node (Discretisation.partition_edges;
    # the local parts of MPI keep the grouping), so each node's own sums stay in registers
    # while its edges are walked: loaded once and stored once, in the same order of
    # additions as one edge at a time (and correct for any order: a run of one first node
    # never writes that node's rows, and each run reloads them)
    force_a = local_vector(d)
    dF_a = local_matrix(d)
    current = -1
    for e in range(edge_offsets[k], edge_offsets[k + 1]):
        a = edges[e, 0]
        if a != current:
            if current >= 0:
                _store_node_sums(force_a, dF_a, force, dF, current, d)
            for i in range(d):
                force_a[i] = force[a, i]
                for J in range(d):
                    dF_a[i, J] = dF[a, i, J]
            current = a
        _flux_edge(e, v, F, sigma, grad, node_material, table, edges, C, C_len, half,
                   use_reconstruction, stress_reconstructed, upwind_geometric, bias, switch,
                   contact_state, force_a, dF_a, force, dF, d, Fe, Sa, Sb, work)
    if current >= 0:
        _store_node_sums(force_a, dF_a, force, dF, current, d)


@njit(cache=True, inline="always")
def _store_node_sums(force_a, dF_a, force, dF, a, d):
    for i in range(d):
        force[a, i] = force_a[i]
        for J in range(d):
            dF[a, i, J] = dF_a[i, J]


@njit(cache=True, parallel=True, fastmath=KERNEL_FASTMATH)
def assemble_rates(v, F, sigma, grad, node_material, table, edges, C, C_len, half,
                   edge_offsets, bface_node, bface_others, bface_C, bface_bc, closure, bc_fixed,
                   prescribed_velocity, prescribed_traction, use_reconstruction,
                   stress_reconstructed, upwind_geometric, bias, switch, contact_state,
                   tangential_correction,
                   bface_contact_weight, force, dF, power, bc_force, dim):
    """Accumulate the momentum flux (force on each dual cell) and Omega dF/dt; into
    power[0] the power of the boundary tractions, sum over the dual boundary faces of
    t^C . v^C |C| (the Riemann states of the faces: zero on free faces, the work of a clamp or
    of a prescribed traction elsewhere); and into bc_force (nbc, d) the force of each
    boundary condition's faces on the body.

    A dual boundary face takes its boundary flux for the part of the face and of the step it
    is not in contact (1 - bface_contact_weight); the contact module adds the rest. It
    prescribes the components its
    boundary condition bc_fixed[bface_bc] prescribes (velocity) or not (traction).
    prescribed_velocity and prescribed_traction (h, d) hold their values.
    """
    d = len(dim)
    own, denominator = closure
    inverse_denominator = 1.0 / denominator
    for a in prange(force.shape[0]):
        for i in range(d):
            force[a, i] = 0.0
            for J in range(d):
                dF[a, i, J] = 0.0
    nb = edge_offsets.shape[0] - 2
    for k in prange(nb):
        _interior_fluxes(k, v, F, sigma, grad, node_material, table, edges, C, C_len, half,
                         edge_offsets, use_reconstruction, stress_reconstructed,
                         upwind_geometric, bias, switch, contact_state, force, dF, d)
    _interior_fluxes(nb, v, F, sigma, grad, node_material, table, edges, C, C_len, half,
                     edge_offsets, use_reconstruction, stress_reconstructed, upwind_geometric,
                     bias, switch, contact_state, force, dF, d)
    Fi = local_matrix(d)
    Si = local_matrix(d)
    Z = local_matrix(d)
    N = local_vector(d)
    n = local_vector(d)
    vi = local_vector(d)
    ti = local_vector(d)
    rhs = local_vector(d)
    vC = local_vector(d)
    tC = local_vector(d)
    fix = local_vector(d)
    given = local_vector(d)
    u = local_vector(d)
    boundary_power = 0.0
    for k in range(bc_force.shape[0]):
        for i in range(d):
            bc_force[k, i] = 0.0
    for h in range(bface_node.shape[0]):
        free = 1.0 - bface_contact_weight[h]
        if free == 0.0:
            continue
        bc = bface_bc[h]
        a = bface_node[h]
        props = table[node_material[a]]
        zp = props[RHO] * props[CP]
        zs = props[RHO] * props[CS]
        ln = 0.0
        for J in range(d):
            ln += bface_C[h, J] * bface_C[h, J]
        ln = np.sqrt(ln)
        for J in range(d):
            N[J] = bface_C[h, J] / ln
        # interior state on the face: (own u_a + sum of the other facet nodes) / denominator
        # (the facet's other nodes by index: a view bface_others[h] would cost a reference
        # count in this serial loop, twice the time of the face)
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
        # a component the node's velocity is held at (e.g. by the clamp of a neighbouring
        # region at a corner) is held on all its faces
        for i in range(d):
            fix[i] = 1.0 if bc_fixed[bc, i] else 0.0
            given[i] = prescribed_velocity[h, i]
        boundary_state(vi, ti, zp, zs, n, fix, given, prescribed_traction[h], Z, rhs, vC, tC)
        # the F equation's velocity: the prescribed one, or the interior one corrected along
        # the normal only or in every direction (riemann.geometric_boundary_velocity)
        geometric_boundary_velocity(vi, ti, tC, vC, fix, zp, n, tangential_correction, u)
        for i in range(d):
            force[a, i] += free * tC[i] * ln
            bc_force[bc, i] += free * tC[i] * ln
            for J in range(d):
                dF[a, i, J] += free * u[i] * bface_C[h, J]
            boundary_power += free * tC[i] * vC[i] * ln
    power[0] = boundary_power


@njit(cache=True, parallel=True, fastmath=KERNEL_FASTMATH)
def relax_towards_positions(D, weight, owned, node_edge_start, node_neighbour, dF, dim):
    """dF_a -= sum over a's edge neighbours b of w_ab (D_a - D_b) at the nodes a < owned,
    with D = F - G (n, d, d) the mismatch of F and the gradient G of the positions (written
    by limited_gradient) and w_ab = w_ba the weight of the edge (per slot of node_neighbour;
    docs/theory.md, "Compatibility relaxation"). A difference operator, so only the
    grid-scale part of D is relaxed: a uniform D not at all, a smooth one through its
    O(h |grad D|) differences, while the incompatible modes, which change sign from node to
    node, are relaxed at the full rate. Symmetric, so its power sum_a P_a : dF_a = -sum over
    edges w_ab (P_a - P_b) : (D_a - D_b) vanishes for a uniform stress."""
    d = len(dim)
    for a in prange(owned):
        # sum_b w_ab (D_a - D_b) = (sum_b w_ab) D_a - sum_b w_ab D_b: one pass over the
        # neighbours, each read once
        weighted = local_matrix(d)
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


@njit(cache=True, inline="always", fastmath=KERNEL_FASTMATH)
def _node_energy_rate(a, v, force, F, sigma, dF, fixed_mask, props, d):
    """The rate of the kinetic and strain energy of node a as its rates give it: v . f over
    the velocity components that are not held, plus P : Omega dF/dt with the first Piola
    stress P = sigma cof F, or P = sigma for the small-strain law (materials.strain_power;
    docs/theory.md, "Energy balance"). Read before the node's state
    is updated, so that the Runge-Kutta update gives it in the same pass."""
    rate = 0.0
    for i in range(d):
        if not fixed_mask[a, i]:
            rate += v[a, i] * force[a, i]
    Fa = local_matrix(d)
    Sa = local_matrix(d)
    Da = local_matrix(d)
    load_matrix(F, a, Fa)
    load_matrix(sigma, a, Sa)
    load_matrix(dF, a, Da)
    return rate + strain_power(Sa, Fa, Da, props)


@njit(cache=True, parallel=True, fastmath=KERNEL_FASTMATH)
def rk_update(alpha, dt, v0, F0, x0, v, F, x, force, dF, sigma, contact_state,
              contact_xdot, node_material, table, volume, fixed_mask, fixed_value, save_start,
              dim):
    """One Runge-Kutta stage for v, F and x at every node (scheme.time.rk_stage). With
    ``save_start`` (the first stage) the state it starts from is first copied into v0, F0,
    x0, in the same pass.

    Positions move with the nodal velocity, or at contact nodes with their contact velocity;
    prescribed velocity components are imposed strongly. Returns the rate of the nodes'
    kinetic and strain energy in the stage's state (sigma: its Cauchy stress), summed while
    the node is read for its update.
    """
    d = len(dim)
    total = 0.0
    for a in prange(v.shape[0]):
        total += _node_energy_rate(a, v, force, F, sigma, dF, fixed_mask,
                                   table[node_material[a]], d)
        inv_volume = 1.0 / volume[a]
        inv_mass = inv_volume / table[node_material[a], RHO]
        in_contact = contact_state[a] != 0
        if save_start:
            for i in range(d):
                x0[a, i] = x[a, i]
                v0[a, i] = v[a, i]
                for J in range(d):
                    F0[a, i, J] = F[a, i, J]
        for i in range(d):
            xdot = contact_xdot[a, i] if in_contact else v[a, i]
            x[a, i] = rk_stage(alpha, x0[a, i], x[a, i], dt, xdot)
            vn = rk_stage(alpha, v0[a, i], v[a, i], dt, force[a, i] * inv_mass)
            if fixed_mask[a, i]:
                vn = fixed_value[a, i]
            v[a, i] = vn
        for i in range(d):
            for J in range(d):
                F[a, i, J] = rk_stage(alpha, F0[a, i, J], F[a, i, J], dt,
                                      dF[a, i, J] * inv_volume)
    return total


@njit(cache=True, parallel=True, fastmath=KERNEL_FASTMATH)
def rk_update_last(alpha, dt, v0, F0, x0, v, F, x, force, dF, sigma, contact_state,
                   contact_xdot, node_material, table, volume, fixed_mask, fixed_value,
                   node_length, body_start, with_monitors, out, pack, U, bound, dim):
    """The last Runge-Kutta stage (as :func:`rk_update`) fused with what the time loop needs
    of the new state, computed while it is still in registers: the stable time step of the
    next step (as :func:`stable_time_step`), the first node with a non-finite state or
    J <= 0 (as :func:`state_is_bad`), with ``with_monitors`` the energies and momentum
    of each body into ``out`` (as :func:`monitors`, summed in the same order), and the
    Cauchy stress of the new state into sigma (as :func:`compute_stress`, for the next
    step's first stage), with ``pack`` also the packed fields U as :func:`stress_and_fields`
    writes them. The stress and the strain energy share one power of J
    (materials.cauchy_stress_and_energy). sigma is read (the stage's stress, for the energy
    rate) before the node's new stress is written.

    In 3D the smallest principal stretch (the trigonometric solution of a cubic) is not
    evaluated here: the first value returned is then the smallest of upper bounds of
    h_a lambda_min,a / c_p,a, and ``bound`` receives each node's lower bound;
    :func:`smallest_time_step_of_candidates` completes the time step from the few nodes
    whose lower bound does not exceed that (materials.min_stretch_bounds).

    Returns (min over nodes of h_a lambda_min,a / c_p,a, index of the first bad node or -1,
    the energy rate of the stage's state as :func:`rk_update` returns it, the energy the
    two-stage step adds, scheme.time.heun_energy_excess summed).
    """
    d = len(dim)
    n = v.shape[0]
    smallest = np.inf
    first_bad = n
    total = 0.0
    integration = 0.0
    inv_dt = 1.0 / dt
    for k in range(body_start.shape[0] - 1):
        kinetic = 0.0
        strain = 0.0
        p0 = 0.0
        p1 = 0.0
        p2 = 0.0
        for a in prange(body_start[k], body_start[k + 1]):
            props = table[node_material[a]]
            total += _node_energy_rate(a, v, force, F, sigma, dF, fixed_mask, props, d)
            inv_volume = 1.0 / volume[a]
            inv_mass = inv_volume / props[RHO]
            in_contact = contact_state[a] != 0
            finite = True
            Fa = local_matrix(d)
            va = local_vector(d)
            # the change of the rates between the stages, L1 - (u* - u0) / dt, for the energy
            # the step adds (scheme.time.heun_energy_excess)
            change = local_matrix(d)
            dv2 = 0.0
            for i in range(d):
                xdot = contact_xdot[a, i] if in_contact else v[a, i]
                x[a, i] = rk_stage(alpha, x0[a, i], x[a, i], dt, xdot)
                acceleration = force[a, i] * inv_mass
                vn = rk_stage(alpha, v0[a, i], v[a, i], dt, acceleration)
                if fixed_mask[a, i]:
                    vn = fixed_value[a, i]
                else:
                    dv = acceleration - (v[a, i] - v0[a, i]) * inv_dt
                    dv2 += dv * dv
                v[a, i] = vn
                va[i] = vn
                finite = finite and np.isfinite(vn)
            # the state midway between u0 and u*, where the elasticity of the energy the step
            # adds is taken
            midway = local_matrix(d)
            for i in range(d):
                for J in range(d):
                    rate = dF[a, i, J] * inv_volume
                    change[i, J] = rate - (F[a, i, J] - F0[a, i, J]) * inv_dt
                    midway[i, J] = 0.5 * (F0[a, i, J] + F[a, i, J])
                    f = rk_stage(alpha, F0[a, i, J], F[a, i, J], dt, rate)
                    F[a, i, J] = f
                    Fa[i, J] = f
            integration += heun_energy_excess(dt, props, volume[a], dv2, change, midway)
            jac = determinant(Fa)
            if not (finite and np.isfinite(jac) and jac > 0.0):
                first_bad = min(first_bad, a)
            if d == 3:
                lower, upper = min_stretch_bounds(Fa)
                bound[a] = node_length[a] * lower / props[CP]
                smallest = min(smallest, node_length[a] * upper / props[CP])
            else:
                smallest = min(smallest, node_length[a] * min_stretch(Fa) / props[CP])
            sa = local_matrix(d)
            energy = cauchy_stress_and_energy(Fa, props, sa)
            store_matrix(sa, sigma, a)
            if pack:
                for i in range(d):
                    U[a, i] = va[i]
                    for j in range(i, d):
                        U[a, d + symmetric_index(i, j, d)] = sa[i, j]
            if with_monitors:
                mass = props[RHO] * volume[a]
                v2 = 0.0
                for i in range(d):
                    v2 += va[i] * va[i]
                kinetic += 0.5 * mass * v2
                strain += volume[a] * energy
                p0 += mass * va[0]
                p1 += mass * va[1]
                if d == 3:
                    p2 += mass * va[d - 1]
        if with_monitors:
            out[k, 0] = kinetic
            out[k, 1] = strain
            out[k, 2] = p0
            out[k, 3] = p1
            if d == 3:
                out[k, 4] = p2
    return smallest, (first_bad if first_bad < n else -1), total, integration


@njit(cache=True, parallel=True, fastmath=KERNEL_FASTMATH)
def smallest_time_step_of_candidates(F, node_material, table, node_length, bound, upper, dim):
    """min over nodes of h_a lambda_min,a / c_p,a (as :func:`stable_time_step`), given a
    lower bound of each node's value (``bound``) and an upper bound of the minimum
    (``upper``, the smallest of the nodes' upper bounds; :func:`rk_update_last`): only the
    nodes whose lower bound does not exceed it can give the minimum, and only they are
    evaluated. The same minimum, to the last bit, as evaluating every node."""
    d = len(dim)
    smallest = np.inf
    for a in prange(F.shape[0]):
        if bound[a] <= upper:
            Fa = local_matrix(d)
            load_matrix(F, a, Fa)
            smallest = min(smallest, node_length[a] * min_stretch(Fa)
                           / table[node_material[a], CP])
    return smallest


@njit(cache=True, parallel=True, fastmath=KERNEL_FASTMATH)
def stable_time_step(F, node_material, table, node_length, dim):
    """min over nodes of h_a lambda_min,a / c_p,a; multiply by the CFL number."""
    d = len(dim)
    n = F.shape[0]
    local = np.empty(n)
    for a in prange(n):
        Fa = local_matrix(d)
        load_matrix(F, a, Fa)
        local[a] = node_length[a] * min_stretch(Fa) / table[node_material[a], CP]
    return local.min()


@njit(cache=True, parallel=True, fastmath=KERNEL_FASTMATH)
def monitors(v, F, node_material, table, volume, body_start, out, dim):
    """Per body k (nodes body_start[k]:body_start[k+1]), into row k of ``out``: kinetic
    energy, strain energy and the d components of linear momentum."""
    d = len(dim)
    for k in range(body_start.shape[0] - 1):
        kinetic = 0.0
        strain = 0.0
        p0 = 0.0
        p1 = 0.0
        p2 = 0.0
        for a in prange(body_start[k], body_start[k + 1]):
            props = table[node_material[a]]
            mass = props[RHO] * volume[a]
            v2 = 0.0
            for i in range(d):
                v2 += v[a, i] * v[a, i]
            kinetic += 0.5 * mass * v2
            Fa = local_matrix(d)
            load_matrix(F, a, Fa)
            strain += volume[a] * strain_energy_density(Fa, props)
            p0 += mass * v[a, 0]
            p1 += mass * v[a, 1]
            if d == 3:
                p2 += mass * v[a, d - 1]
        out[k, 0] = kinetic
        out[k, 1] = strain
        out[k, 2] = p0
        out[k, 3] = p1
        if d == 3:
            out[k, 4] = p2


@njit(cache=True, parallel=True, fastmath=KERNEL_FASTMATH)
def state_is_bad(v, F, dim):
    """Index of the first node with a non-finite state or J <= 0, or -1."""
    d = len(dim)
    n = v.shape[0]
    bad = np.full(n, False)
    for a in prange(n):
        Fa = local_matrix(d)
        load_matrix(F, a, Fa)
        J = determinant(Fa)
        ok = np.isfinite(J) and J > 0.0
        for i in range(d):
            ok = ok and np.isfinite(v[a, i])
        bad[a] = not ok
    for a in range(n):
        if bad[a]:
            return a
    return -1


@njit(cache=True, parallel=True, fastmath=KERNEL_FASTMATH)
def point_fields(F, node_material, table, pressure, von_mises, jac, dim):
    """Pressure (compression positive), von Mises stress and J at every node."""
    d = len(dim)
    for a in prange(F.shape[0]):
        Fa = local_matrix(d)
        sigma = local_matrix(d)
        load_matrix(F, a, Fa)
        p, vm = pressure_and_von_mises(Fa, table[node_material[a]], sigma)
        pressure[a] = p
        von_mises[a] = vm
        jac[a] = determinant(Fa)

