"""Compiled loops of one Runge-Kutta stage of the p-F scheme (numerics.md B.2-B.5, C, D).

Semi-discrete equations on the median dual, per node a::

    Omega_a rho_a dv_a/dt = sum_b t_ab |C_ab| + sum_gamma t_gamma |C_gamma|
    Omega_a dF_a/dt      = sum_b v_ab (x) C_ab + sum_gamma v_gamma (x) C_gamma
    dx_a/dt              = v_a

Interior: t_ab = (P_a + P_b) N / 2 + Z (v_b^+ - v_a^-) / 2 (acoustic upwinding, v reconstructed
linearly to the edge midpoint and limited), v_ab = (v_a + v_b) / 2 (central; see
docs/theory.md for why). Boundary: Riemann-consistent states from boundary_state with the
interior state weighted (5 u_a + u_b)/6. F is stored flat as (F11, F12, F21, F22).
Loops over nodes are parallel; the edge loops scatter serially (sorted edges keep it local).
"""

import numpy as np
from numba import njit, prange

from .. import materials as _m
from . import riemann as _r
from .compile import compile_module_functions

_mat = compile_module_functions(_m, ["first_piola", "strain_energy_density", "cauchy_stress",
                                     "pressure_and_von_mises", "min_stretch"])
first_piola = _mat["first_piola"]
strain_energy_density = _mat["strain_energy_density"]
pressure_and_von_mises = _mat["pressure_and_von_mises"]
min_stretch = _mat["min_stretch"]
_rie = compile_module_functions(_r, ["spatial_normal", "impedance_times", "interior_traction",
                                     "boundary_state"])
spatial_normal = _rie["spatial_normal"]
impedance_times = _rie["impedance_times"]
interior_traction = _rie["interior_traction"]
boundary_state = _rie["boundary_state"]

RHO, MU, LAMBDA, KAPPA, CP, CS, MODEL = (_m.RHO, _m.MU, _m.LAMBDA, _m.KAPPA, _m.CP, _m.CS,
                                         _m.MODEL)
LIMITER_NONE = 0
LIMITER_BARTH_JESPERSEN = 1
LIMITER_VENKATAKRISHNAN = 2


@njit(cache=True, parallel=True)
def compute_stress(F, node_mat, mat, P):
    for a in prange(F.shape[0]):
        k = node_mat[a]
        p11, p12, p21, p22 = first_piola(F[a, 0], F[a, 1], F[a, 2], F[a, 3], mat[k, MU],
                                         mat[k, LAMBDA], mat[k, KAPPA], int(mat[k, MODEL]))
        P[a, 0] = p11
        P[a, 1] = p12
        P[a, 2] = p21
        P[a, 3] = p22


@njit(cache=True, inline="always")
def _gradient_edge(e, v, edges, C, grad, vmin, vmax):
    a = edges[e, 0]
    b = edges[e, 1]
    for i in range(2):
        u = 0.5 * (v[a, i] + v[b, i])
        for J in range(2):
            grad[a, i, J] += u * C[e, J]
            grad[b, i, J] -= u * C[e, J]
        # neighbour range for the limiter, in the same sweep
        if v[b, i] < vmin[a, i]:
            vmin[a, i] = v[b, i]
        if v[b, i] > vmax[a, i]:
            vmax[a, i] = v[b, i]
        if v[a, i] < vmin[b, i]:
            vmin[b, i] = v[a, i]
        if v[a, i] > vmax[b, i]:
            vmax[b, i] = v[a, i]


@njit(cache=True, parallel=True)
def velocity_gradient(v, edges, C, edge_offsets, hb_node, hb_other, hb_C, omega, grad, vmin,
                      vmax):
    """Green-Gauss nodal gradient grad[a, i, J] = d v_i / d X_J (exact for linear fields), and
    the range [vmin, vmax] of each component over the node and its neighbours.

    Edges come grouped by node block (edge_offsets): the blocks run in parallel without
    races, the edges joining two blocks afterwards.
    """
    n = v.shape[0]
    for a in prange(n):
        for i in range(2):
            vmin[a, i] = v[a, i]
            vmax[a, i] = v[a, i]
            for J in range(2):
                grad[a, i, J] = 0.0
    nb = edge_offsets.shape[0] - 2
    for k in prange(nb):
        for e in range(edge_offsets[k], edge_offsets[k + 1]):
            _gradient_edge(e, v, edges, C, grad, vmin, vmax)
    for e in range(edge_offsets[nb], edge_offsets[nb + 1]):
        _gradient_edge(e, v, edges, C, grad, vmin, vmax)
    for h in range(hb_node.shape[0]):
        a = hb_node[h]
        o = hb_other[h]
        for i in range(2):
            u = (5.0 * v[a, i] + v[o, i]) / 6.0
            for J in range(2):
                grad[a, i, J] += u * hb_C[h, J]
    for a in prange(n):
        inv = 1.0 / omega[a]
        for i in range(2):
            for J in range(2):
                grad[a, i, J] *= inv


@njit(cache=True)
def _venkatakrishnan(dmax, d, eps2):
    num = (dmax * dmax + eps2) * d + 2.0 * d * d * dmax
    den = dmax * dmax + 2.0 * d * d + d * dmax + eps2
    return num / (den * d)


@njit(cache=True, inline="always")
def _limit_edge(e, v, edges, half, kind, vmin, vmax, phi, grad):
    for side in range(2):
        a = edges[e, side]
        sgn = 1.0 if side == 0 else -1.0
        for i in range(2):
            d = sgn * (grad[a, i, 0] * half[e, 0] + grad[a, i, 1] * half[e, 1])
            # a change below 1e-10 of the local range needs no limiting; without this
            # tolerance a round-off sized d at an extremum would switch phi from 1 to 0
            if abs(d) <= 1e-10 * (vmax[a, i] - vmin[a, i]):
                continue
            dmax = vmax[a, i] - v[a, i] if d > 0.0 else vmin[a, i] - v[a, i]
            if kind == LIMITER_BARTH_JESPERSEN:
                f = min(1.0, dmax / d)
            else:
                rng = vmax[a, i] - vmin[a, i]
                f = _venkatakrishnan(dmax, d, 0.027 * rng * rng)
            if f < phi[a, i]:
                phi[a, i] = f


@njit(cache=True, parallel=True)
def limit_gradient(v, edges, half, edge_offsets, kind, vmin, vmax, phi, grad):
    """Scale each component's gradient so the midpoint values stay within the neighbours' range
    [vmin, vmax] (from velocity_gradient): Barth-Jespersen (kind 1) or Venkatakrishnan
    (kind 2, with eps^2 = 0.027 (vmax - vmin)^2, i.e. K = 0.3 relative to the local range).
    """
    n = v.shape[0]
    for a in prange(n):
        phi[a, 0] = 1.0
        phi[a, 1] = 1.0
    nb = edge_offsets.shape[0] - 2
    for k in prange(nb):
        for e in range(edge_offsets[k], edge_offsets[k + 1]):
            _limit_edge(e, v, edges, half, kind, vmin, vmax, phi, grad)
    for e in range(edge_offsets[nb], edge_offsets[nb + 1]):
        _limit_edge(e, v, edges, half, kind, vmin, vmax, phi, grad)
    for a in prange(n):
        for i in range(2):
            grad[a, i, 0] *= phi[a, i]
            grad[a, i, 1] *= phi[a, i]


@njit(cache=True, inline="always")
def _flux_edge(e, v, F, P, grad, node_mat, mat, edges, C, C_len, half, use_reconstruction,
               upwind_geometric, force, dF):
    """Upwind traction and central (or upwind) geometric flux of interior edge e."""
    a = edges[e, 0]
    b = edges[e, 1]
    k = node_mat[a]
    rho = mat[k, RHO]
    zp = rho * mat[k, CP]
    zs = rho * mat[k, CS]
    c1 = C[e, 0]
    c2 = C[e, 1]
    ln = C_len[e]
    N1 = c1 / ln
    N2 = c2 / ln
    n1, n2 = spatial_normal(0.5 * (F[a, 0] + F[b, 0]), 0.5 * (F[a, 1] + F[b, 1]),
                            0.5 * (F[a, 2] + F[b, 2]), 0.5 * (F[a, 3] + F[b, 3]), N1, N2)
    va1 = v[a, 0]
    va2 = v[a, 1]
    vb1 = v[b, 0]
    vb2 = v[b, 1]
    if use_reconstruction:
        h1 = half[e, 0]
        h2 = half[e, 1]
        va1 += grad[a, 0, 0] * h1 + grad[a, 0, 1] * h2
        va2 += grad[a, 1, 0] * h1 + grad[a, 1, 1] * h2
        vb1 -= grad[b, 0, 0] * h1 + grad[b, 0, 1] * h2
        vb2 -= grad[b, 1, 0] * h1 + grad[b, 1, 1] * h2
    tbar1 = 0.5 * ((P[a, 0] + P[b, 0]) * N1 + (P[a, 1] + P[b, 1]) * N2)
    tbar2 = 0.5 * ((P[a, 2] + P[b, 2]) * N1 + (P[a, 3] + P[b, 3]) * N2)
    t1, t2 = interior_traction(tbar1, tbar2, vb1 - va1, vb2 - va2, zp, zs, n1, n2)
    f1 = t1 * ln
    f2 = t2 * ln
    force[a, 0] += f1
    force[a, 1] += f2
    force[b, 0] -= f1
    force[b, 1] -= f2
    # central geometric flux keeps F the gradient of x (compatibility)
    u1 = 0.5 * (v[a, 0] + v[b, 0])
    u2 = 0.5 * (v[a, 1] + v[b, 1])
    if upwind_geometric:
        # v = avg(v) + Z^-1 [[t]] / 2 with nodal (unreconstructed) tractions
        dt1 = (P[b, 0] - P[a, 0]) * N1 + (P[b, 1] - P[a, 1]) * N2
        dt2 = (P[b, 2] - P[a, 2]) * N1 + (P[b, 3] - P[a, 3]) * N2
        w1, w2 = impedance_times(1.0 / zp, 1.0 / zs, n1, n2, dt1, dt2)
        u1 = 0.5 * (va1 + vb1) + 0.5 * w1
        u2 = 0.5 * (va2 + vb2) + 0.5 * w2
    dF[a, 0] += u1 * c1
    dF[a, 1] += u1 * c2
    dF[a, 2] += u2 * c1
    dF[a, 3] += u2 * c2
    dF[b, 0] -= u1 * c1
    dF[b, 1] -= u1 * c2
    dF[b, 2] -= u2 * c1
    dF[b, 3] -= u2 * c2


@njit(cache=True, parallel=True)
def assemble_rates(v, F, P, grad, node_mat, mat, edges, C, C_len, half, edge_offsets, hb_node,
                   hb_other, hb_C, hb_bc, bc_fix, bc_v, bc_t, use_reconstruction,
                   upwind_geometric, hb_in_contact, force, dF):
    """Accumulate the momentum flux (force on each dual cell) and Omega dF/dt.

    Half-edges on a contact surface whose node is in contact are left to the contact module.
    Interior edges run by node block in parallel (see velocity_gradient).
    """
    for a in prange(force.shape[0]):
        force[a, 0] = 0.0
        force[a, 1] = 0.0
        for j in range(4):
            dF[a, j] = 0.0
    nb = edge_offsets.shape[0] - 2
    for k in prange(nb):
        for e in range(edge_offsets[k], edge_offsets[k + 1]):
            _flux_edge(e, v, F, P, grad, node_mat, mat, edges, C, C_len, half,
                       use_reconstruction, upwind_geometric, force, dF)
    for e in range(edge_offsets[nb], edge_offsets[nb + 1]):
        _flux_edge(e, v, F, P, grad, node_mat, mat, edges, C, C_len, half, use_reconstruction,
                   upwind_geometric, force, dF)
    for h in range(hb_node.shape[0]):
        bc = hb_bc[h]
        a = hb_node[h]
        if hb_in_contact[h]:
            continue
        o = hb_other[h]
        k = node_mat[a]
        rho = mat[k, RHO]
        zp = rho * mat[k, CP]
        zs = rho * mat[k, CS]
        c1 = hb_C[h, 0]
        c2 = hb_C[h, 1]
        ln = np.sqrt(c1 * c1 + c2 * c2)
        N1 = c1 / ln
        N2 = c2 / ln
        Fi0 = (5.0 * F[a, 0] + F[o, 0]) / 6.0
        Fi1 = (5.0 * F[a, 1] + F[o, 1]) / 6.0
        Fi2 = (5.0 * F[a, 2] + F[o, 2]) / 6.0
        Fi3 = (5.0 * F[a, 3] + F[o, 3]) / 6.0
        n1, n2 = spatial_normal(Fi0, Fi1, Fi2, Fi3, N1, N2)
        vi1 = (5.0 * v[a, 0] + v[o, 0]) / 6.0
        vi2 = (5.0 * v[a, 1] + v[o, 1]) / 6.0
        ti1 = ((5.0 * P[a, 0] + P[o, 0]) * N1 + (5.0 * P[a, 1] + P[o, 1]) * N2) / 6.0
        ti2 = ((5.0 * P[a, 2] + P[o, 2]) * N1 + (5.0 * P[a, 3] + P[o, 3]) * N2) / 6.0
        vc1, vc2, tc1, tc2 = boundary_state(vi1, vi2, ti1, ti2, zp, zs, n1, n2,
                                            bc_fix[bc, 0], bc_fix[bc, 1], bc_v[bc, 0],
                                            bc_v[bc, 1], bc_t[bc, 0], bc_t[bc, 1])
        force[a, 0] += tc1 * ln
        force[a, 1] += tc2 * ln
        dF[a, 0] += vc1 * c1
        dF[a, 1] += vc1 * c2
        dF[a, 2] += vc2 * c1
        dF[a, 3] += vc2 * c2


@njit(cache=True, parallel=True)
def rk_update(alpha, dt, v0, F0, x0, v, F, x, force, dF, contact_state, contact_xdot, node_mat,
              mat, omega, fixed_mask, fixed_value):
    """U <- alpha U0 + (1 - alpha) (U + dt R): alpha = 0 for stage 1 and 1/2 for stage 2.

    Positions move with the nodal velocity, or at contact nodes with their contact velocity.
    """
    beta = 1.0 - alpha
    for a in prange(v.shape[0]):
        inv_omega = 1.0 / omega[a]
        inv_m = inv_omega / mat[node_mat[a], RHO]
        in_contact = contact_state[a] != 0
        for i in range(2):
            xdot = contact_xdot[a, i] if in_contact else v[a, i]
            x[a, i] = alpha * x0[a, i] + beta * (x[a, i] + dt * xdot)
            vn = alpha * v0[a, i] + beta * (v[a, i] + dt * force[a, i] * inv_m)
            if fixed_mask[a, i]:
                vn = fixed_value[a, i]
            v[a, i] = vn
        for j in range(4):
            F[a, j] = alpha * F0[a, j] + beta * (F[a, j] + dt * dF[a, j] * inv_omega)


@njit(cache=True, parallel=True)
def stable_time_step(F, node_mat, mat, node_length):
    """min over nodes of h_a lambda_min,a / c_p,a (numerics.md D); multiply by the CFL number."""
    n = F.shape[0]
    local = np.empty(n)
    for a in prange(n):
        lam = min_stretch(F[a, 0], F[a, 1], F[a, 2], F[a, 3])
        local[a] = node_length[a] * lam / mat[node_mat[a], CP]
    return local.min()


@njit(cache=True, parallel=True)
def monitors(v, F, node_mat, mat, omega, body_start, out):
    """Per body (nodes body_start[k]:body_start[k+1]): kinetic energy, strain energy,
    momentum x, momentum y (rows of ``out``)."""
    for k in range(body_start.shape[0] - 1):
        ke = 0.0
        se = 0.0
        px = 0.0
        py = 0.0
        for a in prange(body_start[k], body_start[k + 1]):
            j = node_mat[a]
            m = mat[j, RHO] * omega[a]
            w = strain_energy_density(F[a, 0], F[a, 1], F[a, 2], F[a, 3], mat[j, MU],
                                      mat[j, LAMBDA], mat[j, KAPPA], int(mat[j, MODEL]))
            ke += 0.5 * m * (v[a, 0] * v[a, 0] + v[a, 1] * v[a, 1])
            se += omega[a] * w
            px += m * v[a, 0]
            py += m * v[a, 1]
        out[k, 0] = ke
        out[k, 1] = se
        out[k, 2] = px
        out[k, 3] = py


@njit(cache=True, parallel=True)
def state_is_bad(v, F):
    """Index of the first node with a non-finite state or J <= 0, or -1."""
    n = v.shape[0]
    bad = np.full(n, False)
    for a in prange(n):
        J = F[a, 0] * F[a, 3] - F[a, 1] * F[a, 2]
        ok = np.isfinite(v[a, 0]) and np.isfinite(v[a, 1]) and np.isfinite(J) and J > 0.0
        bad[a] = not ok
    for a in range(n):
        if bad[a]:
            return a
    return -1


@njit(cache=True, parallel=True)
def point_fields(F, node_mat, mat, pressure, von_mises, jac):
    for a in prange(F.shape[0]):
        k = node_mat[a]
        p, vm = pressure_and_von_mises(F[a, 0], F[a, 1], F[a, 2], F[a, 3], mat[k, MU],
                                       mat[k, LAMBDA], mat[k, KAPPA], int(mat[k, MODEL]))
        pressure[a] = p
        von_mises[a] = vm
        jac[a] = F[a, 0] * F[a, 3] - F[a, 1] * F[a, 2]
