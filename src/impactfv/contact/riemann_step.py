"""Riemann step (compiled): the contact state of every piece and what it adds to the two
bodies' equations; then each contact node's state, contact velocity and motion.

A piece of length l in contact (not released) gives weight t* l to the node's momentum
equation and -weight t* l to the partner node's (equal and opposite: momentum is passed
between the bodies exactly); its face carries the node's contact velocity v* in the F
equation (seed eq. 9b). Both bodies are treated alike by two passes, each with weight 1/2.
"""


from numba import njit

from .. import materials as M
from ..backends.cpu import load_vector, local_vector, point
from . import laws as CL
from .overlap import facing_faces, is_candidate

contact_state = point(CL.contact_state)
wall_state = point(CL.wall_state)
releases = point(CL.releases)

RHO, CP, CS = M.RHO, M.CP, M.CS
OPEN, STICK, SLIP = 0, 1, 2


@njit(cache=True, inline="always")
def _traction(sig, a, n, t, d):
    """Cauchy traction sigma_a n."""
    for i in range(d):
        s = 0.0
        for J in range(d):
            s += sig[a, i, J] * n[J]
        t[i] = s


@njit(cache=True)
def piece_states(v, sig, node_material, table, count, piece_node, piece_face, piece_partner,
                 piece_length, piece_face_length, piece_normal, weight, sign, stick,
                 force_acc, fsum, face_velocity, cover, length_sum, velocity_sum,
                 traction_sum, dim):
    """Contact states of the pieces, in order; forces into force_acc (and their total on the
    first body, times ``sign``, into fsum), face velocities, and per-node sums of length,
    l v* and l t*_n."""
    d = len(dim)
    tA = local_vector(d)
    tB = local_vector(d)
    vtA = local_vector(d)
    ttA = local_vector(d)
    vtB = local_vector(d)
    ttB = local_vector(d)
    vsA = local_vector(d)
    vsB = local_vector(d)
    ts = local_vector(d)
    vA = local_vector(d)
    vB = local_vector(d)
    c = local_vector(d)
    for p in range(count):
        a = piece_node[p]
        b = piece_partner[p]
        load_vector(piece_normal, p, c)
        load_vector(v, a, vA)
        load_vector(v, b, vB)
        _traction(sig, a, c, tA, d)
        _traction(sig, b, c, tB, d)
        pa = table[node_material[a]]
        pb = table[node_material[b]]
        tn = contact_state(vA, tA, vB, tB, c, pa[RHO] * pa[CP], pa[RHO] * pa[CS],
                           pb[RHO] * pb[CP], pb[RHO] * pb[CS], stick, vtA, ttA, vtB, ttB,
                           vsA, vsB, ts)
        if releases(tn):
            continue
        ell = piece_length[p]
        for i in range(d):
            f = weight * ell * ts[i]
            force_acc[a, i] += f
            force_acc[b, i] -= f
            fsum[i] += sign * f
        face = piece_face[p]
        lh = piece_face_length[p]
        for i in range(d):
            face_velocity[face, i] += vsA[i] * ell / lh
        cover[face] += ell / lh
        length_sum[a] += ell
        for i in range(d):
            velocity_sum[a, i] += vsA[i] * ell
        traction_sum[a] += tn * ell


@njit(cache=True, inline="always")
def contact_motion(a, v, vstar, n, closing, xdot, d):
    """Velocity moving a contact node: its contact normal velocity plus the gap-closing rate
    along n, its own velocity across n (so that its tangential motion stays the one its F
    equation sees)."""
    un = closing
    for i in range(d):
        un += vstar[a, i] * n[i]
    for i in range(d):
        un -= v[a, i] * n[i]
    for i in range(d):
        xdot[a, i] = v[a, i] + un * n[i]


@njit(cache=True)
def settle_nodes(slave, v, dt, weight, stick, gap, normal, length_sum, velocity_sum,
                 traction_sum, state, vstar, xdot, tstar_n, dim):
    """Nodes with a piece in contact: their state, mean contact velocity v*, normal contact
    traction, and the velocity moving them (closing ``weight`` of the gap within the stage)."""
    d = len(dim)
    for i in range(slave.shape[0]):
        a = slave[i]
        total = length_sum[a]
        if total == 0.0:
            continue
        state[a] = STICK if stick else SLIP
        for k in range(d):
            vstar[a, k] = velocity_sum[a, k] / total
        contact_motion(a, v, vstar, normal[a], weight * gap[a] / dt, xdot, d)
        tstar_n[a] = traction_sum[a] / total


@njit(cache=True)
def wall_pass(v, F, sig, node_material, table, slave, face_start, face_list, bface_C,
              face_velocity, cover, node_length, gap, normal, wall_velocity, dt, stick,
              was_active, faces, state, vstar, xdot, tstar_n, force_acc, fsum, dim):
    """Nodes of one body against a rigid wall: candidate test, Riemann state of the node's own
    traction against the wall, its faces that face the wall, forces and motion."""
    d = len(dim)
    tA = local_vector(d)
    vt = local_vector(d)
    tt = local_vector(d)
    vs = local_vector(d)
    ts = local_vector(d)
    vA = local_vector(d)
    n = local_vector(d)
    vw = local_vector(d)
    for k in range(d):
        vw[k] = wall_velocity[k]
    for i in range(slave.shape[0]):
        a = slave[i]
        load_vector(normal, a, n)
        load_vector(v, a, vA)
        gdot = 0.0
        for k in range(d):
            gdot -= (v[a, k] - wall_velocity[k]) * n[k]
        if not is_candidate(gap[a], gdot, dt, was_active[a], node_length[a]):
            continue
        props = table[node_material[a]]
        _traction(sig, a, n, tA, d)
        tn = wall_state(vA, tA, n, props[RHO] * props[CP], props[RHO] * props[CS], vw, stick,
                        vt, tt, vs, ts)
        if releases(tn):
            continue
        count, length = facing_faces(a, n, F, face_start, face_list, bface_C, faces, 0)
        for k in range(count):
            for j in range(d):
                face_velocity[faces[k], j] = vs[j]
            cover[faces[k]] = 1.0
        if length == 0.0:
            continue
        state[a] = STICK if stick else SLIP
        for k in range(d):
            vstar[a, k] = vs[k]
        contact_motion(a, v, vstar, n, gap[a] / dt, xdot, d)
        tstar_n[a] = tn
        for k in range(d):
            f = length * ts[k]
            force_acc[a, k] += f
            fsum[k] += f


@njit(cache=True)
def reset_surface(nodes, faces, state, force_acc, tstar_n, face_velocity, cover,
                  length_sum, velocity_sum, traction_sum):
    d = force_acc.shape[1]
    for i in range(nodes.shape[0]):
        a = nodes[i]
        state[a] = OPEN
        tstar_n[a] = 0.0
        length_sum[a] = 0.0
        traction_sum[a] = 0.0
        for k in range(d):
            force_acc[a, k] = 0.0
            velocity_sum[a, k] = 0.0
    for k in range(faces.shape[0]):
        face = faces[k]
        cover[face] = 0.0
        for j in range(d):
            face_velocity[face, j] = 0.0


@njit(cache=True)
def mark_contact_faces(faces, cover, face_active):
    """Faces touched by a piece in contact leave the free-surface flux to the contact."""
    for k in range(faces.shape[0]):
        face_active[faces[k]] = cover[faces[k]] > 0.0


@njit(cache=True)
def apply_contact(nodes, faces, bface_node, bface_C, face_active, face_velocity, cover, state,
                  vstar, xdot, force_acc, fixed_mask, fixed_value, force, dF):
    """Add the contact forces to the momentum equation; faces in contact carry their mean
    contact velocity in the F equation in place of the free-surface flux. Velocity components
    prescribed by a boundary condition (e.g. a roller side meeting the contact face at a
    corner) win over the contact velocity."""
    d = force.shape[1]
    for i in range(nodes.shape[0]):
        a = nodes[i]
        for k in range(d):
            force[a, k] += force_acc[a, k]
        if state[a] != OPEN:
            for k in range(d):
                if fixed_mask[a, k]:
                    vstar[a, k] = fixed_value[a, k]
                    xdot[a, k] = fixed_value[a, k]
    for j in range(faces.shape[0]):
        face = faces[j]
        if not face_active[face]:
            continue
        a = bface_node[face]
        for i in range(d):
            w = face_velocity[face, i] / cover[face]
            if fixed_mask[a, i]:
                w = fixed_value[a, i]
            for J in range(d):
                dF[a, i, J] += w * bface_C[face, J]


