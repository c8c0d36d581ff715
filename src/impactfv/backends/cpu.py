"""Compiled loops of one Runge-Kutta stage of the p-F scheme (docs/theory.md).

Semi-discrete equations on the median dual, per node a (seed eq. 9)::

    Omega_a rho_a dv_a/dt = sum_b t_ab |C_ab| + sum_gamma t_gamma |C_gamma|
    Omega_a dF_a/dt      = sum_b v_ab (x) C_ab + sum_gamma v_gamma (x) C_gamma
    dx_a/dt              = v_a

The loop bodies (scheme.bodies) and the physics they call (impactfv.physics) are point
functions compiled by compiled.point; these loops only iterate over them and scatter their
results. Every kernel takes ``dim``, a tuple of d zeros (compiled.dim_tag), so that the
dimension is a compile-time constant, and hands the bodies scratch arrays on the stack
(compiled.local_matrix, ...). Loops over nodes are parallel; the edge loops run by node
block (Discretisation.edge_offsets): blocks in parallel, the edges joining two blocks
afterwards, each node's sums held while its run of edges is walked.
"""

import numpy as np
from numba import njit, prange

from ..compiled import (KERNEL_FASTMATH, load_matrix, local_components, local_matrix,
                        local_rows, local_scratch, local_vector, point, store_matrix)
from ..physics import materials as M
from ..physics import runge_kutta as T
from ..physics.tensors import determinant as _determinant
from ..physics.tensors import symmetric_index as _symmetric_index
from ..scheme import bodies as B

cauchy_stress = point(M.cauchy_stress)
# cold paths (on-demand monitors, output fields): called, not inlined (compiled.point)
strain_energy_density = point(M.strain_energy_density, inline=False)
cauchy_stress_and_energy = point(M.cauchy_stress_and_energy)
pressure_and_von_mises = point(M.pressure_and_von_mises, inline=False)
min_stretch = point(M.min_stretch)
min_stretch_bounds = point(M.min_stretch_bounds)
determinant = point(_determinant)
strain_power = point(M.strain_power)
symmetric_index = point(_symmetric_index)
heun_energy_excess = point(T.heun_energy_excess)
edge_flux = point(B.edge_flux)
boundary_face_flux = point(B.boundary_face_flux)
node_gradient = point(B.node_gradient)
node_update = point(B.node_update)
relaxation_change = point(B.relaxation_change)
node_energy_rate = point(B.node_energy_rate)
node_monitors = point(B.node_monitors)
stage_change = point(B.stage_change)

CP = M.CP


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


@njit(cache=True, parallel=True, fastmath=KERNEL_FASTMATH)
def limited_gradient(U, dual, closure, kind, grad, components, x, F, mismatch,
                     with_positions, dim):
    """The limited Green-Gauss gradient grad[a, i, J] of every field i of U (n, m) at every
    node (scheme.bodies.node_gradient), with ``with_positions`` also the mismatch
    D = F - G(x) of the compatibility relaxation. ``components`` is a tuple of m zeros (a
    compile-time m, like ``dim``); ``dual`` the tuple (node_edge_start, node_neighbour,
    node_C, node_half, bface_start, bface_others, bface_C, volume) of
    Discretisation.gradient_dual. A gather over nodes: each node reads its neighbours once
    and writes only its own rows (no race, no edge blocks); its sums stay on the stack."""
    d = len(dim)
    m = len(components)
    own, denominator = closure
    # one division per call, not per face (1/8 is exact in 3D)
    inverse_denominator = 1.0 / denominator
    for a in prange(U.shape[0]):
        scratch = (local_scratch(m * d), local_components(m), local_components(m),
                   local_components(m), local_matrix(d), local_components(m),
                   local_components(m), local_components(m))
        node_gradient(a, U, x, F, dual, own, inverse_denominator, kind, with_positions,
                      scratch, grad, mismatch)


@njit(cache=True, inline="always", fastmath=KERNEL_FASTMATH)
def _interior_fluxes(k, v, F, sigma, grad, node_material, table, edges, C, C_len, half,
                     edge_offsets, options, contact_state, force, dF, d):
    """The edges of block k (scheme.bodies.edge_flux), each scattered to its two nodes."""
    Fe = local_matrix(d)
    Sa = local_matrix(d)
    Sb = local_matrix(d)
    work = local_rows(B.EDGE_WORK_ROWS, d)
    f = work[B.EDGE_FORCE]
    u = work[B.EDGE_VELOCITY]
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
        b = edges[e, 1]
        if a != current:
            if current >= 0:
                _store_node_sums(force_a, dF_a, force, dF, current, d)
            for i in range(d):
                force_a[i] = force[a, i]
                for J in range(d):
                    dF_a[i, J] = dF[a, i, J]
            current = a
        edge_flux(e, a, b, v, F, sigma, grad, table[node_material[a]], C, C_len, half,
                  options, contact_state, Fe, Sa, Sb, work)
        for i in range(d):
            force_a[i] += f[i]
            force[b, i] -= f[i]
        for i in range(d):
            for J in range(d):
                dF_a[i, J] += u[i] * C[e, J]
                dF[b, i, J] -= u[i] * C[e, J]
    if current >= 0:
        _store_node_sums(force_a, dF_a, force, dF, current, d)


@njit(cache=True, inline="always")
def _store_node_sums(force_a, dF_a, force, dF, a, d):
    for i in range(d):
        force[a, i] = force_a[i]
        for J in range(d):
            dF[a, i, J] = dF_a[i, J]


@njit(cache=True, parallel=True, fastmath=KERNEL_FASTMATH)
def assemble_rates(v, F, sigma, grad, node_material, table, edge_mesh, face_mesh, boundary,
                   options, contact_state, bface_contact_weight, out, dim):
    """Accumulate the momentum flux (force on each dual cell) and Omega dF/dt of every
    interior edge (scheme.bodies.edge_flux) and dual boundary face
    (scheme.bodies.boundary_face_flux) into ``out`` = (force, dF, power, bc_force): into
    power[0] the power of the boundary tractions, sum over the dual boundary faces of
    t^C . v^C |C| (zero on free faces, the work of a clamp or of a prescribed traction
    elsewhere); into bc_force (nbc, d) the force of each boundary condition's faces on the
    body.

    edge_mesh: (edges, C, C_len, half, edge_offsets); face_mesh: (bface_node, bface_others,
    bface_C, bface_bc, closure); boundary: (bc_fixed, prescribed_velocity,
    prescribed_traction, tangential_correction); options: the edge flux's
    (scheme.bodies). A dual boundary face takes its boundary flux for the part of the face
    and of the step it is not in contact (1 - bface_contact_weight); the contact stage adds
    the rest."""
    d = len(dim)
    edges, C, C_len, half, edge_offsets = edge_mesh
    force, dF, power, bc_force = out
    for a in prange(force.shape[0]):
        for i in range(d):
            force[a, i] = 0.0
            for J in range(d):
                dF[a, i, J] = 0.0
    # the variants (compiled.variant tags: one specialisation per option set) as constants
    # that the parallel loop takes as it takes d
    reconstruct, stress_reconstructed, upwind_geometric = (
        len(options[0]), len(options[1]), len(options[2]))
    bias, switch = options[3], options[4]
    nb = edge_offsets.shape[0] - 2
    for k in prange(nb):
        _interior_fluxes(k, v, F, sigma, grad, node_material, table, edges, C, C_len, half,
                         edge_offsets, (reconstruct, stress_reconstructed, upwind_geometric,
                                        bias, switch), contact_state, force, dF, d)
    _interior_fluxes(nb, v, F, sigma, grad, node_material, table, edges, C, C_len, half,
                     edge_offsets, (reconstruct, stress_reconstructed, upwind_geometric, bias,
                                    switch), contact_state, force, dF, d)
    power[0] = _boundary_fluxes(v, F, sigma, node_material, table, face_mesh, boundary,
                                bface_contact_weight, force, dF, bc_force, d)


@njit(cache=True, inline="always", fastmath=KERNEL_FASTMATH)
def _boundary_fluxes(v, F, sigma, node_material, table, face_mesh, boundary,
                     bface_contact_weight, force, dF, bc_force, d):
    """The dual boundary faces, in order (serial: few faces, each node's faces scattered to
    it); returns their power."""
    bface_node, bface_others, bface_C, bface_bc, closure = face_mesh
    bc_fixed, prescribed_velocity, prescribed_traction, tangential_correction = boundary
    own, denominator = closure
    inverse_denominator = 1.0 / denominator
    Fi = local_matrix(d)
    Si = local_matrix(d)
    Z = local_matrix(d)
    work = local_rows(B.FACE_WORK_ROWS, d)
    tC = work[B.FACE_TRACTION]
    vC = work[B.FACE_STATE_VELOCITY]
    u = work[B.FACE_VELOCITY]
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
        ln = boundary_face_flux(h, a, v, F, sigma, table[node_material[a]], bface_others,
                                bface_C, own, inverse_denominator, bc_fixed, bc,
                                prescribed_velocity, prescribed_traction,
                                tangential_correction, Fi, Si, Z, work)
        for i in range(d):
            force[a, i] += free * tC[i] * ln
            bc_force[bc, i] += free * tC[i] * ln
            for J in range(d):
                dF[a, i, J] += free * u[i] * bface_C[h, J]
            boundary_power += free * tC[i] * vC[i] * ln
    return boundary_power


@njit(cache=True, parallel=True, fastmath=KERNEL_FASTMATH)
def relax_towards_positions(D, weight, owned, node_edge_start, node_neighbour, dF, dim):
    """The compatibility relaxation (scheme.bodies.relaxation_change) at the nodes
    a < owned, D = F - G (n, d, d) written by limited_gradient."""
    d = len(dim)
    for a in prange(owned):
        relaxation_change(a, D, weight, node_edge_start, node_neighbour, dF, local_matrix(d))


@njit(cache=True, inline="always", fastmath=KERNEL_FASTMATH)
def _node_energy_rate(a, v, force, F, sigma, dF, fixed_mask, props, d):
    return node_energy_rate(a, v, force, F, sigma, dF, fixed_mask, props, local_matrix(d),
                            local_matrix(d), local_matrix(d))


@njit(cache=True, parallel=True, fastmath=KERNEL_FASTMATH)
def rk_update(alpha, dt, start, state, rates, contact_state, contact_xdot, node_material,
              table, held, save_start, dim):
    """One Runge-Kutta stage of every node (scheme.bodies.node_update). With ``save_start``
    (the first stage) the state it starts from is first copied into ``start`` = (v0, F0, x0),
    in the same pass. ``state``: (v, F, x); ``rates``: (force, dF, sigma), sigma the Cauchy
    stress of the stage's state; ``held``: (volume, fixed_mask, fixed_value). Returns the
    rate of the nodes' kinetic and strain energy in the stage's state
    (scheme.bodies.node_energy_rate), summed while the node is read for its update."""
    d = len(dim)
    v0, F0, x0 = start
    v, F, x = state
    force, dF, sigma = rates
    volume, fixed_mask, fixed_value = held
    total = 0.0
    for a in prange(v.shape[0]):
        props = table[node_material[a]]
        total += _node_energy_rate(a, v, force, F, sigma, dF, fixed_mask, props, d)
        if save_start:
            for i in range(d):
                x0[a, i] = x[a, i]
                v0[a, i] = v[a, i]
                for J in range(d):
                    F0[a, i, J] = F[a, i, J]
        node_update(a, alpha, dt, v0, F0, x0, v, F, x, force, dF, contact_state[a] != 0,
                    contact_xdot, props, volume, fixed_mask, fixed_value, local_matrix(d))
    return total


@njit(cache=True, parallel=True, fastmath=KERNEL_FASTMATH)
def rk_update_last(alpha, dt, start, state, rates, contact_state, contact_xdot, node_material,
                   table, held, node_length, body_start, with_monitors, out, pack, U, bound,
                   dim):
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
    two-stage step adds, physics.runge_kutta.heun_energy_excess summed).
    """
    d = len(dim)
    v0, F0, x0 = start
    v, F, x = state
    force, dF, sigma = rates
    volume, fixed_mask, fixed_value = held
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
            change = local_matrix(d)
            midway = local_matrix(d)
            dv2 = stage_change(a, inv_dt, v0, F0, v, F, force, dF, props, volume, fixed_mask,
                               change, midway)
            integration += heun_energy_excess(dt, props, volume[a], dv2, change, midway)
            Fa = local_matrix(d)
            finite = node_update(a, alpha, dt, v0, F0, x0, v, F, x, force, dF,
                                 contact_state[a] != 0, contact_xdot, props, volume,
                                 fixed_mask, fixed_value, Fa)
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
                    U[a, i] = v[a, i]
                    for j in range(i, d):
                        U[a, d + symmetric_index(i, j, d)] = sa[i, j]
            if with_monitors:
                node_kinetic, node_strain, m0, m1, m2 = node_monitors(a, v, props, volume,
                                                                      energy)
                kinetic += node_kinetic
                strain += node_strain
                p0 += m0
                p1 += m1
                p2 += m2
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
            Fa = local_matrix(d)
            load_matrix(F, a, Fa)
            node_kinetic, node_strain, m0, m1, m2 = node_monitors(
                a, v, props, volume, strain_energy_density(Fa, props))
            kinetic += node_kinetic
            strain += node_strain
            p0 += m0
            p1 += m1
            p2 += m2
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
def point_fields(F, node_material, table, pressure, von_mises, jac, stress, dim):
    """The output frames' point fields of every node: pressure (compression positive), von
    Mises stress, J, and the 3 x 3 Cauchy stress (n, 3, 3), in plane strain with its
    out-of-plane normal stress sigma_zz."""
    d = len(dim)
    for a in prange(F.shape[0]):
        Fa = local_matrix(d)
        sigma = local_matrix(d)
        load_matrix(F, a, Fa)
        p, vm, szz = pressure_and_von_mises(Fa, table[node_material[a]], sigma)
        pressure[a] = p
        von_mises[a] = vm
        jac[a] = determinant(Fa)
        for i in range(3):
            for j in range(3):
                stress[a, i, j] = 0.0
        for i in range(d):
            for j in range(d):
                stress[a, i, j] = sigma[i, j]
        if d == 2:
            stress[a, 2, 2] = szz


@njit(cache=True, fastmath=KERNEL_FASTMATH)
def projection_positions(last, dt, x0, x, v, contact_state, contact_xdot, owned, y):
    """The positions the angular momentum projection (scheme.angular_momentum) takes at a
    stage: the state's at the first stage, at the last the positions the step ends at,
    x0 / 2 + (x + dt xdot) / 2 (scheme.bodies.node_update: xdot the contact velocity of a
    node in contact, its velocity otherwise)."""
    d = y.shape[1]
    for a in range(owned):
        for i in range(d):
            if not last:
                y[a, i] = x[a, i]
            else:
                xdot = contact_xdot[a, i] if contact_state[a] != 0 else v[a, i]
                y[a, i] = 0.5 * x0[a, i] + 0.5 * (x[a, i] + dt * xdot)


@njit(cache=True, fastmath=KERNEL_FASTMATH)
def body_moments(y, mass, force, body, owned, origin, out):
    """The angular momentum projection's sums (scheme.angular_momentum). Per body k
    (body[a] of node a < owned), about its point origin[k], r = y - origin:
    out[k] = (sum m, sum m r (d), sum m r (x) r (d x d, row by row), sum r x f (3: only the
    third in 2D)). Serial: a handful of bodies' sums, in one pass."""
    d = y.shape[1]
    out[:] = 0.0
    r = np.empty(d)
    for a in range(owned):
        k = body[a]
        m = mass[a]
        for i in range(d):
            r[i] = y[a, i] - origin[k, i]
        out[k, 0] += m
        for i in range(d):
            out[k, 1 + i] += m * r[i]
            for j in range(d):
                out[k, 1 + d + d * i + j] += m * r[i] * r[j]
        t = 1 + d + d * d
        if d == 3:
            out[k, t] += r[1] * force[a, 2] - r[2] * force[a, 1]
            out[k, t + 1] += r[2] * force[a, 0] - r[0] * force[a, 2]
        out[k, t + 2] += r[0] * force[a, 1] - r[1] * force[a, 0]


@njit(cache=True, fastmath=KERNEL_FASTMATH)
def add_rigid_spin(y, mass, body, owned, centre, spin, force):
    """The angular momentum projection's correction (scheme.angular_momentum):
    force_a += m_a spin_k x (y_a - centre_k) at the nodes a < owned of body k: the force
    of a rigid angular acceleration spin_k (3: only the third in 2D) about the body's
    centre of mass; it adds no force to the body, and spin_k = 0 leaves it as it is."""
    d = y.shape[1]
    for a in range(owned):
        k = body[a]
        w0, w1, w2 = spin[k, 0], spin[k, 1], spin[k, 2]
        if w0 == 0.0 and w1 == 0.0 and w2 == 0.0:
            continue
        m = mass[a]
        r0 = y[a, 0] - centre[k, 0]
        r1 = y[a, 1] - centre[k, 1]
        if d == 3:
            r2 = y[a, 2] - centre[k, 2]
            force[a, 0] += m * (w1 * r2 - w2 * r1)
            force[a, 1] += m * (w2 * r0 - w0 * r2)
            force[a, 2] += m * (w0 * r1 - w1 * r0)
        else:
            force[a, 0] -= m * w2 * r1
            force[a, 1] += m * w2 * r0
