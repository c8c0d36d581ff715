"""The CUDA backend: the loops of one finite-volume step on an NVIDIA GPU (numba-cuda).

The physics is the CPU's: the same point functions (materials, tensors, scheme.riemann,
scheme.limiters, scheme.time) compiled as CUDA device functions by :func:`device`, which
clones each with a globals table in which the point functions it calls are their device
copies (as backends.cpu.point does for numba on the CPU). Only the loops differ: one GPU
thread per node (stress, gradient and limiter, Runge-Kutta stage) or per dual face (fluxes,
scattered with atomic additions), and small arrays in ``cuda.local.array`` instead of the
CPU's stack buffers. Kernels are compiled per dimension d and number of reconstructed fields
m, which are compile-time constants of the closures :func:`kernels` makes.

The state (v, F, x), the work arrays and the discretisation live on the device for the
whole run; per stage only a few numbers come back (the boundary power, the force of each
boundary condition, and at the last stage the next stable time step, the first bad node
and the monitors), plus the forces of the held nodes when the case has reactions, and the
prescribed values go up when the loads change in time. The state is copied back only for
outputs (:meth:`DeviceState.to_host`).

Body forces are added on the device. Contact is not: its search and Riemann states are the
CPU's kernels, run on the host on the contact surfaces' rows of the state (:class:`HostContact`),
whose results go back to the device each stage. Without a GPU, the tests run these kernels
under numba-cuda's simulator (NUMBA_ENABLE_CUDASIM=1), which executes the same Python
sources thread by thread.
"""

from __future__ import annotations

import importlib.util
import math
import os
import types

import numpy as np

from ..compiled import device
from ..physics.limiters import NONE as NO_LIMITER
from ..physics.runge_kutta import STAGES

#: threads per block of every kernel (a power of two: the block sums halve it); the simulator
#: runs every thread of a block as a Python thread, so it gets small blocks
THREADS = 16 if os.environ.get("NUMBA_ENABLE_CUDASIM") == "1" else 128

def problem(case) -> str | None:
    """Why ``case`` cannot run with backend "cuda" here (one line), or None."""
    if importlib.util.find_spec("numba_cuda") is None:
        return ('run.backend = "cuda" needs numba-cuda, which is not installed '
                '(pip install "impactfv[cuda]")')
    from numba import cuda as _cuda
    if not _cuda.is_available():
        return ('run.backend = "cuda": no usable CUDA GPU here (numba-cuda finds no device '
                'or driver); use backend = "cpu"')
    if case.run.method != "fv":
        return f'run.backend = "cuda" runs the FV method only, not {case.run.method!r}'
    return None


_kernels = {}


def kernels(d: int, m: int, kind: int):
    """The kernels for dimension d, m reconstructed fields and limiter ``kind`` (all
    compile-time constants), compiled once per combination."""
    key = (d, m, kind)
    if key not in _kernels:
        _kernels[key] = _make_kernels(d, m, kind)
    return _kernels[key]


#: numba.cuda, imported when the first kernels are made (a module global, so that the
#: simulator can swap it for its own in the kernels' globals)
cuda = None


def _make_kernels(d, m, kind):
    global cuda
    from numba import cuda as _cuda
    from numba import float64
    cuda = _cuda

    from ..physics import materials as M
    from ..physics import limiters as L
    from ..physics import riemann as R
    from ..physics import runge_kutta as T
    from ..physics.tensors import determinant as _determinant
    from ..physics.tensors import symmetric_index as _symmetric_index

    cauchy_stress = device(M.cauchy_stress)
    strain_energy_density = device(M.strain_energy_density)
    min_stretch = device(M.min_stretch)
    determinant = device(_determinant)
    strain_power = device(M.strain_power)
    symmetric_index = device(_symmetric_index)
    face_geometry = device(R.face_geometry)
    face_traction = device(R.face_traction)
    face_area_normal = device(R.face_area_normal)
    upwind_traction_area = device(R.upwind_traction_area)
    central_velocity = device(R.central_velocity)
    upwind_velocity = device(R.upwind_velocity)
    boundary_state = device(R.boundary_state)
    geometric_boundary_velocity = device(R.geometric_boundary_velocity)
    limiter_factor = device(L.limiter_factor)
    blend_weight = device(L.blend_weight)
    switch_scales = device(L.switch_scales)
    rk_stage = device(T.rk_stage)
    heun_energy_excess = device(T.heun_energy_excess)
    RHO, CP, CS = M.RHO, M.CP, M.CS
    BJ, NONE = L.BARTH_JESPERSEN, L.NONE
    D2 = d * d
    NMON = 2 + d

    @cuda.jit
    def stress_and_fields(F, v, node_material, table, sigma, U, pack):
        a = cuda.grid(1)
        if a >= F.shape[0]:
            return
        Fa = cuda.local.array((d, d), float64)
        sa = cuda.local.array((d, d), float64)
        for i in range(d):
            for J in range(d):
                Fa[i, J] = F[a, i, J]
        cauchy_stress(Fa, table[node_material[a]], sa)
        for i in range(d):
            for J in range(d):
                sigma[a, i, J] = sa[i, J]
        if pack:
            for i in range(d):
                U[a, i] = v[a, i]
                for j in range(i, d):
                    U[a, d + symmetric_index(i, j, d)] = sa[i, j]

    @cuda.jit
    def limited_gradient(v, node_edge_start, node_neighbour, node_C, node_half, bface_start,
                         bface_others, bface_C, own, denominator, volume, grad):
        # the CPU's kernels.limited_gradient, one thread per node
        a = cuda.grid(1)
        if a >= v.shape[0]:
            return
        g = cuda.local.array((m, d), float64)
        lo = cuda.local.array(m, float64)
        hi = cuda.local.array(m, float64)
        rise = cuda.local.array(m, float64)
        fall = cuda.local.array(m, float64)
        for i in range(m):
            lo[i] = v[a, i]
            hi[i] = v[a, i]
            for J in range(d):
                g[i, J] = 0.0
        for k in range(node_edge_start[a], node_edge_start[a + 1]):
            b = node_neighbour[k]
            for i in range(m):
                ub = v[b, i]
                mean = 0.5 * (v[a, i] + ub)
                for J in range(d):
                    g[i, J] += mean * node_C[k, J]
                lo[i] = min(lo[i], ub)
                hi[i] = max(hi[i], ub)
        for h in range(bface_start[a], bface_start[a + 1]):
            for i in range(m):
                face = own * v[a, i]
                for o in range(bface_others.shape[1]):
                    face += v[bface_others[h, o], i]
                face *= 1.0 / denominator    # as the CPU: 1/8 exact in 3D
                for J in range(d):
                    g[i, J] += face * bface_C[h, J]
        inv = 1.0 / volume[a]
        for i in range(m):
            for J in range(d):
                g[i, J] = g[i, J] * inv
        if kind == BJ:
            for i in range(m):
                rise[i] = 0.0
                fall[i] = 0.0
            for k in range(node_edge_start[a], node_edge_start[a + 1]):
                for i in range(m):
                    change = 0.0
                    for J in range(d):
                        change += g[i, J] * node_half[k, J]
                    rise[i] = max(rise[i], change)
                    fall[i] = min(fall[i], change)
        for i in range(m):
            phi = 1.0
            if kind != NONE:
                u = v[a, i]
                tolerance = 1e-10 * (hi[i] - lo[i])
                if kind == BJ:
                    if rise[i] > tolerance:
                        phi = min(phi, limiter_factor(kind, u, lo[i], hi[i], rise[i]))
                    if fall[i] < -tolerance:
                        phi = min(phi, limiter_factor(kind, u, lo[i], hi[i], fall[i]))
                else:
                    for k in range(node_edge_start[a], node_edge_start[a + 1]):
                        change = 0.0
                        for J in range(d):
                            change += g[i, J] * node_half[k, J]
                        if abs(change) > tolerance:
                            phi = min(phi, limiter_factor(kind, u, lo[i], hi[i], change))
            for J in range(d):
                grad[a, i, J] = g[i, J] * phi
            grad[a, i, d] = phi

    @cuda.jit
    def relax_towards_positions(F, G, weight, owned, node_edge_start, node_neighbour, dF):
        # the CPU's kernels.relax_towards_positions, one thread per node
        a = cuda.grid(1)
        if a >= owned:
            return
        start, stop = node_edge_start[a], node_edge_start[a + 1]
        for i in range(d):
            for J in range(d):
                Da = F[a, i, J] - G[a, i, J]
                change = 0.0
                for k in range(start, stop):
                    b = node_neighbour[k]
                    change += weight[k] * (Da - F[b, i, J] + G[b, i, J])
                dF[a, i, J] -= change

    @cuda.jit
    def zero_rates(force, dF):
        a = cuda.grid(1)
        if a >= force.shape[0]:
            return
        for i in range(d):
            force[a, i] = 0.0
            for J in range(d):
                dF[a, i, J] = 0.0

    @cuda.jit
    def interior_fluxes(v, F, sigma, grad, node_material, table, edges, C, C_len, half,
                        use_reconstruction, stress_reconstructed, upwind_geometric, bias,
                        switch, contact_state, force, dF):
        # the CPU's kernels._flux_edge, one thread per interior edge, scattered atomically
        e = cuda.grid(1)
        if e >= edges.shape[0]:
            return
        Fe = cuda.local.array((d, d), float64)
        Sa = cuda.local.array((d, d), float64)
        Sb = cuda.local.array((d, d), float64)
        A = cuda.local.array(d, float64)
        n = cuda.local.array(d, float64)
        va = cuda.local.array(d, float64)
        vb = cuda.local.array(d, float64)
        w = cuda.local.array(d, float64)
        ta = cuda.local.array(d, float64)
        tb = cuda.local.array(d, float64)
        tbar = cuda.local.array(d, float64)
        tjump = cuda.local.array(d, float64)
        t = cuda.local.array(d, float64)
        u = cuda.local.array(d, float64)
        a = edges[e, 0]
        b = edges[e, 1]
        props = table[node_material[a]]
        # the face through its area vectors, as the CPU's kernels._flux_edge: n holds
        # m = cof(F) C, and ta, tb, t are the face's forces (not per unit area)
        area = C_len[e]
        zp = props[RHO] * props[CP] * area
        zs = props[RHO] * props[CS] * area
        for i in range(d):
            A[i] = C[e, i]
            for J in range(d):
                Fe[i, J] = 0.5 * (F[a, i, J] + F[b, i, J])
        inverse_m2 = face_area_normal(Fe, A, props, n)
        for i in range(d):
            va[i] = v[a, i]
            vb[i] = v[b, i]
        if not upwind_geometric:
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
        # the CPU's kernels._reconstruct_stresses
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
        face_traction(Sa, n, 1.0, ta)
        face_traction(Sb, n, 1.0, tb)
        for i in range(d):
            w[i] = vb[i] - va[i]
            tbar[i] = 0.5 * (ta[i] + tb[i])
            tjump[i] = tb[i] - ta[i]
        zp_v = zp
        zs_v = zs
        if switch != 0.0 and contact_state[a] == 0 and contact_state[b] == 0:
            # the CPU's smoothness switch (kernels._flux_edge)
            scale_v, scale_t = switch_scales(switch, v, sigma, a, b, w, Sa, Sb,
                                             upwind_geometric)
            zp_v = zp * scale_v
            zs_v = zs * scale_v
            for i in range(d):
                tjump[i] *= scale_t
        upwind_traction_area(tbar, w, zp_v, zs_v, n, inverse_m2, t)
        for i in range(d):
            cuda.atomic.add(force, (a, i), t[i])
            cuda.atomic.add(force, (b, i), -t[i])
        if upwind_geometric:
            upwind_velocity(va, vb, tjump, zp, u)
        for i in range(d):
            for J in range(d):
                cuda.atomic.add(dF, (a, i, J), u[i] * C[e, J])
                cuda.atomic.add(dF, (b, i, J), -(u[i] * C[e, J]))

    @cuda.jit
    def boundary_fluxes(v, F, sigma, node_material, table, bface_node, bface_others, bface_C,
                        bface_bc, own, denominator, bc_fixed, prescribed_velocity,
                        prescribed_traction, tangential_correction, face_contact_weight,
                        force, dF, power, bc_force):
        # the boundary part of the CPU's kernels.assemble_rates, one thread per face; a face
        # takes its boundary flux for the part of it and of the step not in contact
        h = cuda.grid(1)
        if h >= bface_node.shape[0]:
            return
        free = 1.0 - face_contact_weight[h]
        if free == 0.0:
            return
        Fi = cuda.local.array((d, d), float64)
        Si = cuda.local.array((d, d), float64)
        Z = cuda.local.array((d, d), float64)
        N = cuda.local.array(d, float64)
        n = cuda.local.array(d, float64)
        vi = cuda.local.array(d, float64)
        ti = cuda.local.array(d, float64)
        rhs = cuda.local.array(d, float64)
        vC = cuda.local.array(d, float64)
        tC = cuda.local.array(d, float64)
        fix = cuda.local.array(d, float64)
        given = cuda.local.array(d, float64)
        tgiven = cuda.local.array(d, float64)
        u = cuda.local.array(d, float64)
        bc = bface_bc[h]
        a = bface_node[h]
        props = table[node_material[a]]
        zp = props[RHO] * props[CP]
        zs = props[RHO] * props[CS]
        inverse_denominator = 1.0 / denominator
        ln = 0.0
        for J in range(d):
            ln += bface_C[h, J] * bface_C[h, J]
        ln = math.sqrt(ln)
        for J in range(d):
            N[J] = bface_C[h, J] / ln
        for i in range(d):
            vi[i] = own * v[a, i]
            for o in range(bface_others.shape[1]):
                vi[i] += v[bface_others[h, o], i]
            vi[i] *= inverse_denominator
            for J in range(d):
                Fi[i, J] = own * F[a, i, J]
                Si[i, J] = own * sigma[a, i, J]
                for o in range(bface_others.shape[1]):
                    Fi[i, J] += F[bface_others[h, o], i, J]
                    Si[i, J] += sigma[bface_others[h, o], i, J]
                Fi[i, J] *= inverse_denominator
                Si[i, J] *= inverse_denominator
        area = face_geometry(Fi, N, props, n)
        face_traction(Si, n, area, ti)
        for i in range(d):
            fix[i] = 1.0 if bc_fixed[bc, i] else 0.0
            given[i] = prescribed_velocity[h, i]
            tgiven[i] = prescribed_traction[h, i]
        boundary_state(vi, ti, zp, zs, n, fix, given, tgiven, Z, rhs, vC, tC)
        geometric_boundary_velocity(vi, ti, tC, vC, fix, zp, n, tangential_correction, u)
        face_power = 0.0
        for i in range(d):
            cuda.atomic.add(force, (a, i), free * tC[i] * ln)
            cuda.atomic.add(bc_force, (bc, i), free * tC[i] * ln)
            for J in range(d):
                cuda.atomic.add(dF, (a, i, J), free * u[i] * bface_C[h, J])
            face_power += free * tC[i] * vC[i] * ln
        cuda.atomic.add(power, 0, face_power)

    @cuda.jit
    def rk_update(alpha, dt, v0, F0, x0, v, F, x, force, dF, contact_state, contact_xdot,
                  node_material, table, volume, fixed_mask, fixed_value, start, stop,
                  node_length, with_checks, with_monitors, smallest, first_bad, out, body):
        # the CPU's kernels.rk_update / rk_update_last for nodes start..stop-1 (one body
        # when with_checks): block sums in shared memory, one atomic per block
        a = start + cuda.grid(1)
        tid = cuda.threadIdx.x
        part = cuda.shared.array((THREADS, NMON), float64)
        low = cuda.shared.array(THREADS, float64)
        for j in range(NMON):
            part[tid, j] = 0.0
        low[tid] = math.inf
        if a < stop:
            props = table[node_material[a]]
            inv_volume = 1.0 / volume[a]
            inv_mass = inv_volume / props[RHO]
            finite = True
            Fa = cuda.local.array((d, d), float64)
            in_contact = contact_state[a] != 0
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
            if with_checks:
                jac = determinant(Fa)
                if not (finite and math.isfinite(jac) and jac > 0.0):
                    cuda.atomic.min(first_bad, 0, a)
                low[tid] = node_length[a] * min_stretch(Fa) / props[CP]
                if with_monitors:
                    mass = props[RHO] * volume[a]
                    v2 = 0.0
                    for i in range(d):
                        v2 += v[a, i] * v[a, i]
                    part[tid, 0] = 0.5 * mass * v2
                    part[tid, 1] = volume[a] * strain_energy_density(Fa, props)
                    for i in range(d):
                        part[tid, 2 + i] = mass * v[a, i]
        if not with_checks:
            return
        cuda.syncthreads()
        step = THREADS // 2
        while step > 0:
            if tid < step:
                low[tid] = min(low[tid], low[tid + step])
                for j in range(NMON):
                    part[tid, j] += part[tid + step, j]
            cuda.syncthreads()
            step //= 2
        if tid == 0:
            cuda.atomic.min(smallest, 0, low[0])
            if with_monitors:
                for j in range(NMON):
                    cuda.atomic.add(out, (body, j), part[0, j])

    @cuda.jit
    def energy_rate(v, F, sigma, force, dF, fixed_mask, v0, F0, volume, node_material, table,
                    dt, with_integration, out):
        # the energy rate the CPU's kernels.rk_update sums (kernels._node_energy_rate) into
        # out[0], into out[1] the power v . f of the held velocity components and, at the
        # last stage, into out[2] the energy the step adds (scheme.time.heun_energy_excess,
        # as the CPU's kernels.rk_update_last): block sums in shared memory, one atomic per
        # block
        a = cuda.grid(1)
        tid = cuda.threadIdx.x
        part = cuda.shared.array((THREADS, 3), float64)
        part[tid, 0] = 0.0
        part[tid, 1] = 0.0
        part[tid, 2] = 0.0
        if a < v.shape[0]:
            if with_integration:
                props = table[node_material[a]]
                inv_volume = 1.0 / volume[a]
                inv_mass = inv_volume / props[RHO]
                change = cuda.local.array((d, d), float64)
                midway = cuda.local.array((d, d), float64)
                dv2 = 0.0
                for i in range(d):
                    if not fixed_mask[a, i]:
                        dv = force[a, i] * inv_mass - (v[a, i] - v0[a, i]) / dt
                        dv2 += dv * dv
                    for J in range(d):
                        change[i, J] = dF[a, i, J] * inv_volume - (F[a, i, J] - F0[a, i, J]) / dt
                        midway[i, J] = 0.5 * (F0[a, i, J] + F[a, i, J])
                part[tid, 2] = heun_energy_excess(dt, props, volume[a], dv2, change, midway)
            Fa = cuda.local.array((d, d), float64)
            Sa = cuda.local.array((d, d), float64)
            Da = cuda.local.array((d, d), float64)
            for i in range(d):
                for J in range(d):
                    Fa[i, J] = F[a, i, J]
                    Sa[i, J] = sigma[a, i, J]
                    Da[i, J] = dF[a, i, J]
            rate = 0.0
            held = 0.0
            for i in range(d):
                if fixed_mask[a, i]:
                    held += v[a, i] * force[a, i]
                else:
                    rate += v[a, i] * force[a, i]
            part[tid, 0] = rate + strain_power(Sa, Fa, Da, table[node_material[a]])
            part[tid, 1] = held
        cuda.syncthreads()
        step = THREADS // 2
        while step > 0:
            if tid < step:
                for j in range(3):
                    part[tid, j] += part[tid + step, j]
            cuda.syncthreads()
            step //= 2
        if tid == 0:
            for j in range(3):
                cuda.atomic.add(out, j, part[0, j])

    @cuda.jit
    def body_force(force, mass, acceleration, v, out):
        # the CPU's force += mass a, and into out[0] the power sum mass a . v: block sums
        a = cuda.grid(1)
        tid = cuda.threadIdx.x
        part = cuda.shared.array(THREADS, float64)
        part[tid] = 0.0
        if a < force.shape[0]:
            p = 0.0
            for i in range(d):
                f = mass[a] * acceleration[a, i]
                force[a, i] += f
                p += f * v[a, i]
            part[tid] = p
        cuda.syncthreads()
        step = THREADS // 2
        while step > 0:
            if tid < step:
                part[tid] += part[tid + step]
            cuda.syncthreads()
            step //= 2
        if tid == 0:
            cuda.atomic.add(out, 0, part[0])

    @cuda.jit
    def pack_rows(source, rows, out, column):
        # out[k, column:column + w] = source[rows[k]] (source viewed as (n, w)): the rows of
        # the state that the contact stage on the host reads, the forces of the held nodes
        k = cuda.grid(1)
        if k >= rows.shape[0]:
            return
        r = rows[k]
        for j in range(source.shape[1]):
            out[k, column + j] = source[r, j]

    @cuda.jit
    def unpack_rows(packed, column, rows, target):
        # target[rows[k]] = packed[k, column:column + w] (target viewed as (n, w))
        k = cuda.grid(1)
        if k >= rows.shape[0]:
            return
        r = rows[k]
        for j in range(target.shape[1]):
            target[r, j] = packed[k, column + j]

    return types.SimpleNamespace(
        stress_and_fields=stress_and_fields, limited_gradient=limited_gradient,
        relax_towards_positions=relax_towards_positions,
        zero_rates=zero_rates, interior_fluxes=interior_fluxes,
        boundary_fluxes=boundary_fluxes, rk_update=rk_update,
        energy_rate=energy_rate, body_force=body_force, pack_rows=pack_rows,
        unpack_rows=unpack_rows)


def _blocks(count):
    return max(1, (count + THREADS - 1) // THREADS)


class DeviceState:
    """The state, work arrays and discretisation of an FVStepper on the GPU, and its step."""

    def __init__(self, stepper):
        from numba import cuda as _cuda

        self.cuda = cuda = _cuda
        s, m = stepper, stepper.disc
        self.s = s
        d = m.dim
        self.k = kernels(d, len(s.components), int(s.limiter))
        up = cuda.to_device
        # a view of v when only v is reconstructed: U has its own array on the device
        self.pack = s.stress_reconstructed
        self.arrays = {name: up(np.ascontiguousarray(getattr(m, name))) for name in (
            "node_material", "material_table", "edges", "C", "C_len", "half",
            "node_edge_start", "node_neighbour", "node_C", "node_half", "bface_start",
            "bface_others", "bface_C", "bface_node", "bface_bc", "bc_fixed", "volume",
            "fixed_mask", "node_length")}
        for name in ("v", "F", "x", "sigma", "grad", "force", "dF"):
            self.arrays[name] = up(np.ascontiguousarray(getattr(s, name)))
        for name in ("v", "F", "x"):
            self.arrays[name + "0"] = cuda.device_array_like(self.arrays[name])
        self.arrays["U"] = up(s.U) if self.pack else self.arrays["v"]
        self.mass = up(np.ascontiguousarray(s.mass))
        n, h = m.n_nodes, len(m.bface_node)
        # contact: what the host's contact stage decides, on the device (the state and
        # contact velocity of the nodes, the part of each face in contact)
        self.arrays["contact_state"] = up(np.zeros(n))
        self.arrays["contact_xdot"] = up(np.zeros((n, d)))
        self.arrays["face_contact_weight"] = up(np.zeros(h))
        self.contact = None if s.contact is None else HostContact(self)
        self.loads_up()
        self.power = cuda.device_array(1)
        self.energy = cuda.device_array(3)
        self.bc_force = cuda.device_array(s.bc_force.shape)
        self.smallest = cuda.device_array(1)
        self.first_bad = cuda.device_array(1, np.int64)
        self.monitors = cuda.device_array(s.monitor_buf.shape)
        self.body_start = [int(b) for b in m.body_start]
        if s.reaction_rows:
            held = np.unique(s.reaction_sum.indices)
            self.held = up(held.astype(np.int64))
            self.held_sum = s.reaction_sum[:, held]
            self.held_force = cuda.device_array((len(held), d))

    def loads_up(self):
        """Copy the prescribed values of the loads' current time to the device."""
        up = self.cuda.to_device
        loads = self.s.loads
        self.arrays["face_velocity"] = up(loads.face_velocity)
        self.arrays["face_traction"] = up(loads.face_traction)
        self.arrays["fixed_value"] = up(loads.fixed_value)
        if loads.has_body_force:
            self.arrays["acceleration"] = up(loads.acceleration)

    def to_host(self):
        """Copy the state (v, F, x) back into the stepper's host arrays."""
        s, A = self.s, self.arrays
        A["v"].copy_to_host(s.v)
        A["F"].copy_to_host(s.F)
        A["x"].copy_to_host(s.x)

    def from_host(self):
        s, A = self.s, self.arrays
        for name in ("v", "F", "x"):
            A[name].copy_to_device(getattr(s, name))

    def rates(self, stage=0, stage_time=0.0):
        """force and dF of the device state; returns (boundary power, bc forces, the forces
        of the held nodes or None)."""
        s, m, A, k = self.s, self.s.disc, self.arrays, self.k
        n = m.n_nodes
        own, denominator = m.closure
        k.stress_and_fields[_blocks(n), THREADS](A["F"], A["v"], A["node_material"],
                                                 A["material_table"], A["sigma"], A["U"],
                                                 self.pack)
        if s.order == 2:
            k.limited_gradient[_blocks(n), THREADS](
                A["U"], A["node_edge_start"], A["node_neighbour"], A["node_C"],
                A["node_half"], A["bface_start"], A["bface_others"], A["bface_C"],
                float(own), float(denominator), A["volume"], A["grad"])
        if self.contact is not None:
            self.contact.stage(stage, stage_time)
        k.zero_rates[_blocks(n), THREADS](A["force"], A["dF"])
        self.power.copy_to_device(np.zeros(1))
        self.bc_force.copy_to_device(np.zeros(s.bc_force.shape))
        if m.n_edges:
            k.interior_fluxes[_blocks(m.n_edges), THREADS](
                A["v"], A["F"], A["sigma"], A["grad"], A["node_material"],
                A["material_table"], A["edges"], A["C"], A["C_len"], A["half"],
                s.order == 2, s.stress_reconstructed, s.upwind_geometric, s.bias, s.switch,
                A["contact_state"], A["force"], A["dF"])
        h = len(m.bface_node)
        if h:
            k.boundary_fluxes[_blocks(h), THREADS](
                A["v"], A["F"], A["sigma"], A["node_material"], A["material_table"],
                A["bface_node"], A["bface_others"], A["bface_C"], A["bface_bc"], float(own),
                float(denominator), A["bc_fixed"], A["face_velocity"], A["face_traction"],
                s.tangential_correction, A["face_contact_weight"], A["force"], A["dF"],
                self.power, self.bc_force)
        if self.contact is not None:
            self.contact.apply()
        if s.relaxation_weight is not None:
            # F relaxed towards the gradient of the positions (scheme.stepper)
            if "G" not in A:
                A["G"] = self.cuda.device_array((n, m.dim, m.dim + 1))
                A["relaxation_weight"] = self.cuda.to_device(s.relaxation_weight)
            kernels(m.dim, m.dim, NO_LIMITER).limited_gradient[_blocks(n), THREADS](
                A["x"], A["node_edge_start"], A["node_neighbour"], A["node_C"],
                A["node_half"], A["bface_start"], A["bface_others"], A["bface_C"],
                float(own), float(denominator), A["volume"], A["G"])
            k.relax_towards_positions[_blocks(n), THREADS](
                A["F"], A["G"], A["relaxation_weight"], n, A["node_edge_start"],
                A["node_neighbour"], A["dF"])
        if s.loads.has_body_force:
            # the power of the body force is summed with the boundary power
            k.body_force[_blocks(n), THREADS](A["force"], self.mass, A["acceleration"],
                                              A["v"], self.power)
        power = float(self.power.copy_to_host()[0])
        # the rate of the energy the rates give, and the power of the forces that the
        # supports cancel on held components (scheme.stepper: the energy balance)
        self.energy.copy_to_device(np.zeros(3))
        last = stage == len(STAGES) - 1
        k.energy_rate[_blocks(n), THREADS](A["v"], A["F"], A["sigma"], A["force"], A["dF"],
                                           A["fixed_mask"], A["v0"], A["F0"], A["volume"],
                                           A["node_material"], A["material_table"],
                                           float(s.dt), bool(last), self.energy)
        rate, held_power, integration = self.energy.copy_to_host()
        self.rate = float(rate)
        self.integration = float(integration)
        power -= float(held_power)
        bc_force = self.bc_force.copy_to_host()
        held = None
        if s.reaction_rows:
            k.pack_rows[_blocks(self.held.shape[0]), THREADS](A["force"], self.held,
                                                              self.held_force, 0)
            held = self.held_sum @ self.held_force.copy_to_host()
        return power, bc_force, held

    def update(self, alpha, dt, last, with_monitors):
        """One Runge-Kutta stage of every node; at the last stage also (smallest
        h lambda_min / c_p, first bad node or -1), and the monitors when asked."""
        s, A, k = self.s, self.arrays, self.k
        n = s.disc.n_nodes
        if last:
            self.smallest.copy_to_device(np.array([np.inf]))
            self.first_bad.copy_to_device(np.array([n], np.int64))
            self.monitors.copy_to_device(np.zeros(s.monitor_buf.shape))
            ranges = [(self.body_start[b], self.body_start[b + 1], b)
                      for b in range(len(self.body_start) - 1)]
        else:
            ranges = [(0, n, 0)]
        for start, stop, body in ranges:
            if stop <= start:
                continue
            k.rk_update[_blocks(stop - start), THREADS](
                float(alpha), float(dt), A["v0"], A["F0"], A["x0"], A["v"], A["F"], A["x"],
                A["force"], A["dF"], A["contact_state"], A["contact_xdot"],
                A["node_material"], A["material_table"], A["volume"],
                A["fixed_mask"], A["fixed_value"], start, stop, A["node_length"], bool(last),
                bool(with_monitors), self.smallest, self.first_bad, self.monitors, body)
        if not last:
            return None
        if with_monitors:
            self.monitors.copy_to_host(s.monitor_buf)
        bad = int(self.first_bad.copy_to_host()[0])
        return float(self.smallest.copy_to_host()[0]), (bad if bad < n else -1)

    def save_start(self):
        A = self.arrays
        for name in ("v", "F", "x"):
            A[name + "0"].copy_to_device(A[name])


class HostContact:
    """The contact stage of a device run, on the host: per stage the rows of the contact
    surfaces' nodes (positions, velocity, F, stress, gradients) come from the device, the
    CPU's contact.driver.ContactSystem runs on them in the stepper's host arrays (it reads
    and writes only those rows), and what it decides goes back: the part of each contact
    face in contact, the gradients it drops, and after the flux assembly the contact forces
    and F-equation terms (added on the host to the device's sums of the surface rows) and
    each node's contact state and velocity. The transfers grow with the contact surfaces,
    not with the mesh; the search and the contact Riemann states are the CPU's code."""

    def __init__(self, device):
        cuda, A, s = device.cuda, device.arrays, device.s
        self.device, self.s, self.system = device, s, s.contact
        n, d = s.disc.n_nodes, s.disc.dim
        self.nodes = s.contact.surface_nodes.astype(np.int64)
        self.faces = s.contact.faces.astype(np.int64)
        self.nodes_dev = cuda.to_device(self.nodes)
        self.faces_dev = cuda.to_device(self.faces)

        def view(name, host, rows=n):
            # (name, the device array viewed as (rows, w), the host array viewed likewise)
            w = int(np.prod(host.shape[1:])) if host.ndim > 1 else 1
            flat = host.reshape(rows, w)
            assert np.shares_memory(flat, host), name      # a view, written through
            return name, A[name].reshape(rows, w), flat
        self.state_in = [view("x", s.x), view("v", s.v), view("F", s.F),
                         view("sigma", s.sigma)]
        self.grad = view("grad", s.grad) if s.order == 2 else None
        self.rates_io = [view("force", s.force), view("dF", s.dF)]
        self.weights = view("face_contact_weight", s.face_contact_weight,
                            len(s.disc.bface_node))
        self.contact_out = [("contact_state", A["contact_state"].reshape(n, 1),
                             s.contact_state.reshape(n, 1)),
                            ("contact_xdot", A["contact_xdot"], s.contact_xdot)]
        self.buffers = {}

    def _buffer(self, rows, width):
        key = (rows, width)
        if key not in self.buffers:
            self.buffers[key] = self.device.cuda.device_array(key)
        return self.buffers[key]

    def _down(self, views, rows, rows_dev):
        """Copy the rows ``rows`` of the device arrays ``views`` into the host arrays."""
        k = self.device.k
        width = sum(dev.shape[1] for _, dev, _ in views)
        packed = self._buffer(len(rows), width)
        column = 0
        for _, dev, _ in views:
            k.pack_rows[_blocks(len(rows)), THREADS](dev, rows_dev, packed, column)
            column += dev.shape[1]
        host = packed.copy_to_host()
        column = 0
        for _, dev, target in views:
            target[rows] = host[:, column:column + dev.shape[1]]
            column += dev.shape[1]

    def _up(self, views, rows, rows_dev):
        """Copy the rows ``rows`` of the host arrays ``views`` into the device arrays."""
        k = self.device.k
        width = sum(dev.shape[1] for _, dev, _ in views)
        host = np.empty((len(rows), width))
        column = 0
        for _, dev, source in views:
            host[:, column:column + dev.shape[1]] = source[rows]
            column += dev.shape[1]
        packed = self._buffer(len(rows), width)
        packed.copy_to_device(host)
        column = 0
        for _, dev, _ in views:
            k.unpack_rows[_blocks(len(rows)), THREADS](packed, column, rows_dev, dev)
            column += dev.shape[1]

    def stage(self, stage, stage_time):
        s = self.s
        views = self.state_in + ([self.grad] if self.grad else [])
        self._down(views, self.nodes, self.nodes_dev)
        self.system.stage(s.x, s.v, s.F, s.sigma, s.grad, s.order == 2, s.dt, stage,
                          stage_time)
        self._up([self.weights], self.faces, self.faces_dev)
        # the stage's contact states (the smoothness switch leaves the contact zone's edges)
        self._up(self.contact_out[:1], self.nodes, self.nodes_dev)
        if self.grad:
            self._up([self.grad], self.nodes, self.nodes_dev)

    def apply(self):
        s = self.s
        self._down(self.rates_io, self.nodes, self.nodes_dev)
        self.system.apply(s.force, s.dF, s.loads.fixed_value)
        self._up(self.rates_io + self.contact_out, self.nodes, self.nodes_dev)

    def end_step(self, time):
        s = self.s
        self._down(self.state_in[:3], self.nodes, self.nodes_dev)
        self.system.end_step(s.x, s.v, s.F, time)
