"""Riemann step (compiled): the contact state of every piece and what it adds to the two
bodies' equations; then each contact node's state, contact velocity and motion.

Each side's state is its node's velocity and Cauchy stress closed to its face as the free
boundary flux does, (5 u_a + u_o) / 6 (3D: (6 u_a + u_b + u_c) / 8). The Riemann problem is
posed in
nominal tractions, as the seed's eq. 5: per unit reference area of its face each side carries
t = sigma n da/dA with impedance rho c; written per unit spatial area (where the two sides'
tractions must balance) that is sigma n with impedance rho c / (da/dA). A piece covering the
part l / l_face of its slave face, in contact for the fraction phi of the step (its node
touched during the step), gives weight phi t* A to the node's momentum equation and
-weight phi t* A to the partner node's, with A = (l / l_face) (da/dA) |C_face| that part's
area measured with F, as every other momentum flux (seed eq. 9a: nominal traction times
reference area): momentum passes between the bodies exactly. Its face carries the node's contact velocity in
the F equation, and the node moves with it (laws.kinematic_velocity). Both bodies are treated
alike by two passes, each with weight 1/2.
"""

import math
from collections import namedtuple

from numba import njit

from ..physics import materials as M
from ..compiled import load_vector, local_matrix, local_vector, point
from ..geometry.facets import dual_face_vector
from ..mesh.dual import CLOSURE
from ..physics import riemann as R
from ..physics.tensors import symmetric_index as _symmetric_index
from ..physics import contact_laws as CL
from .overlap import wall_faces

contact_state = point(CL.contact_state)
kinematic_velocity = point(CL.kinematic_velocity)
wall_state = point(CL.wall_state)
releases = point(CL.releases)
face_geometry = point(R.face_geometry)
face_traction = point(R.face_traction)
symmetric_index = point(_symmetric_index)

RHO, CP, CS = M.RHO, M.CP, M.CS
OPEN, STICK, SLIP = 0, 1, 2
OWN2, DENOMINATOR2 = CLOSURE[2]
OWN3, DENOMINATOR3 = CLOSURE[3]

#: the state of the stage the contact reads: positions, velocities, F and Cauchy stress
State = namedtuple("State", "x v F sigma")
#: one contact in this stage: per node the fraction of the step in contact (read) and the
#: contact mode OPEN, STICK or SLIP (written); the force on the first body (added to); the
#: Coulomb coefficient
Contact = namedtuple("Contact", "phi mode fsum friction")
#: per node, what the contact adds in this stage: the force, and the sums of contact length,
#: of length-weighted (contact velocity - velocity) and of length-weighted normal traction
#: that settle_nodes turns into its motion and output
NodeSums = namedtuple("NodeSums", "force length motion traction")


@njit(cache=True, inline="always", error_model="numpy")
def face_state(a, others, v, sigma, vf, sf, d):
    """Velocity and Cauchy stress of node a on its dual boundary face (the facet's other
    nodes ``others``): the boundary closure (5 u_a + u_o) / 6, in 3D (6 u_a + u_b + u_c) / 8,
    of the free-surface flux (docs/contact.md: reconstructed states made the contact work
    unbalanced and the energy rise)."""
    own = OWN2 if d == 2 else OWN3
    denominator = DENOMINATOR2 if d == 2 else DENOMINATOR3
    for i in range(d):
        u = own * v[a, i]
        for o in others:
            u += v[o, i]
        vf[i] = u / denominator
        for j in range(i, d):
            s = own * sigma[a, i, j]
            for o in others:
                s += sigma[o, i, j]
            s /= denominator
            sf[i, j] = s
            sf[j, i] = s


@njit(cache=True, inline="always", error_model="numpy")
def area_ratio(F, a, C, props, Fa, N, scratch):
    """da/dA of a face of node a with reference area vector C."""
    d = Fa.shape[0]
    for i in range(d):
        for J in range(d):
            Fa[i, J] = F[a, i, J]
    lc = 0.0
    for J in range(d):
        lc += C[J] * C[J]
    lc = math.sqrt(lc)
    for J in range(d):
        N[J] = C[J] / lc
    return face_geometry(Fa, N, props, scratch)


@njit(cache=True, inline="always", error_model="numpy")
def facet_position(facets, s, b):
    """Position (0 .. d-1) of node b in facet s."""
    for k in range(facets.shape[1]):
        if facets[s, k] == b:
            return k
    return -1


@njit(cache=True, inline="always", error_model="numpy")
def side_state(disc, state, a, face, n, vf, sf, tf, Fa, N, scratch, d):
    """One side of a contact on node a's face ``face``: the face's velocity and stress
    (face_state, into vf and sf) and its traction on the surface of normal n (into tf);
    returns the face's area ratio da/dA (its spatial normal left in scratch) and the side's
    normal and shear impedances per unit spatial area, rho c / (da/dA)."""
    face_state(a, disc.bface_others[face], state.v, state.sigma, vf, sf, d)
    face_traction(sf, n, 1.0, tf)
    props = disc.material_table[disc.node_material[a]]
    r = area_ratio(state.F, a, disc.bface_C[face], props, Fa, N, scratch)
    return r, props[RHO] * props[CP] / r, props[RHO] * props[CS] / r


@njit(cache=True, inline="always", error_model="numpy")
def piece_force(a, b, C, part, ra, weight, phi, ts, force, fsum, sign, d):
    """The force of a piece on node a, and minus it on node b: weight phi t* over the
    piece's part ``part`` (l / l_face) of a's face, that part's area measured with F (da/dA
    ``ra`` times the reference area |C|, seed eq. 9a) as every momentum flux is, not with
    the positions. Its total on the first body, times ``sign``, is added to fsum."""
    lc = 0.0
    for i in range(d):
        lc += C[i] * C[i]
    area = part * ra * math.sqrt(lc)
    for i in range(d):
        f = weight * phi * area * ts[i]
        force[a, i] += f
        force[b, i] -= f
        fsum[i] += sign * f


@njit(cache=True, error_model="numpy")
def piece_states(disc, state, segs, segment_faces, pieces, count, contact, weight, sign,
                 faces, sums, dim):
    """Contact states of the pieces (the parts of the contact faces, the nodes' dual
    boundary faces, that meet the partner; the first ``count`` of ``pieces``, on the master
    facets segs with their dual faces segment_faces), in order. A piece of pass weight w (1/2
    between two bodies: each body's nodes are checked against the other's surface) gives
    both sides w of the contact: the tractions +-w phi t* l (their total on the first body,
    times ``sign``, into contact.fsum); on each side's face the part w phi l / l_face of face
    and step in contact, with that side's contact velocity (faces.weight, and faces.velocity
    weighted by it); and per node the sums of w l, w phi l (v_kin - v) and w l t*_n for its
    motion and output (sums). Both sides of every piece get the same treatment, so that the
    work of the contact traction on the two bodies balances whichever body's pass found it."""
    d = len(dim)
    SA = local_matrix(d)
    SB = local_matrix(d)
    Fa = local_matrix(d)
    vA = local_vector(d)
    vB = local_vector(d)
    tA = local_vector(d)
    tB = local_vector(d)
    vtA = local_vector(d)
    ttA = local_vector(d)
    vtB = local_vector(d)
    ttB = local_vector(d)
    vsA = local_vector(d)
    vsB = local_vector(d)
    ts = local_vector(d)
    c = local_vector(d)
    mtB = local_vector(d)
    mts = local_vector(d)
    N = local_vector(d)
    scratch = local_vector(d)
    v = state.v
    for p in range(count):
        a = pieces.node[p]
        b = pieces.partner[p]
        face = pieces.face[p]
        sm = pieces.segment[p]
        face_b = segment_faces[sm, facet_position(segs, sm, b)]
        load_vector(pieces.normal, p, c)
        ra, zpA, zsA = side_state(disc, state, a, face, c, vA, SA, tA, Fa, N, scratch, d)
        rb, zpB, zsB = side_state(disc, state, b, face_b, c, vB, SB, tB, Fa, N, scratch, d)
        tn, slides = contact_state(vA, tA, vB, tB, c, zpA, zsA, zpB, zsB, contact.friction,
                                   vtA, ttA, vtB, ttB, vsA, vsB, ts)
        if releases(tn):
            continue
        for i in range(d):
            # B's view: tractions on surfaces of normal -c, out of B
            mtB[i] = -tB[i]
            mts[i] = -ts[i]
        ell = pieces.length[p]
        share = weight * contact.phi[a] * ell
        piece_force(a, b, disc.bface_C[face], ell / pieces.face_length[p], ra, weight,
                    contact.phi[a], ts, sums.force, contact.fsum, sign, d)
        # the partner's face: its share of the facet
        lb = dual_face_vector(state.x, disc.X, b, disc.bface_others[face_b],
                              disc.bface_C[face_b], scratch)
        wa = share / pieces.face_length[p]
        wb = share / lb
        faces.weight[face] += wa
        faces.weight[face_b] += wb
        for i in range(d):
            kA = kinematic_velocity(vA, tA, ts, c, zpA, i)
            kB = kinematic_velocity(vB, mtB, mts, c, zpB, i)
            faces.velocity[face, i] += wa * kA
            faces.velocity[face_b, i] += wb * kB
            sums.motion[a, i] += share * (kA - v[a, i])
            sums.motion[b, i] += share * (kB - v[b, i])
        mode = SLIP if slides else STICK
        contact.mode[a] = mode
        contact.mode[b] = mode
        sums.length[a] += weight * ell
        sums.length[b] += weight * ell
        sums.traction[a] += weight * tn * ell
        sums.traction[b] += weight * tn * ell


@njit(cache=True, error_model="numpy")
def wall_fractions(v, slave, gap, normal, wall_velocity, memory, dt, phi):
    """Fraction of this step each node spends against the wall (overlap.step_fraction...)."""
    d = v.shape[1]
    for i in range(slave.shape[0]):
        a = slave[i]
        gdot = 0.0
        for k in range(d):
            gdot += (wall_velocity[k] - v[a, k]) * normal[a, k]
        g = gap[a]
        if memory[a] > 0 or g <= 0.0:
            phi[a] = 1.0
        elif gdot < 0.0 and g + gdot * dt < 0.0:
            phi[a] = 1.0 + g / (gdot * dt)
        else:
            phi[a] = 0.0


@njit(cache=True, error_model="numpy")
def wall_pass(disc, state, slave, normal, wall_velocity, contact, facing, faces, sums, dim):
    """Nodes of one body against a rigid wall: each of a node's contact faces (its dual
    boundary faces) that faces the wall (overlap.wall_faces, listed in the buffer
    ``facing``) meets it with its own face state; the force acts on the face's projection
    on the wall, the face carries the contact velocity in the F equation for the part phi
    of the step, and the node moves with it (sums as in piece_states)."""
    d = len(dim)
    S = local_matrix(d)
    Fa = local_matrix(d)
    vA = local_vector(d)
    tA = local_vector(d)
    vt = local_vector(d)
    tt = local_vector(d)
    vs = local_vector(d)
    ts = local_vector(d)
    n = local_vector(d)
    N = local_vector(d)
    scratch = local_vector(d)
    vw = local_vector(d)
    for k in range(d):
        vw[k] = wall_velocity[k]
    x, v = state.x, state.v
    for i in range(slave.shape[0]):
        a = slave[i]
        if contact.phi[a] == 0.0:
            continue
        load_vector(normal, a, n)
        count, total = wall_faces(a, n, x, disc, faces, facing, 0)
        phi = contact.phi[a]
        for j in range(count):
            face = facing[j]
            r, zp, zs = side_state(disc, state, a, face, n, vA, S, tA, Fa, N, scratch, d)
            tn, slides = wall_state(vA, tA, n, zp, zs, vw, contact.friction, vt, tt, vs, ts)
            if releases(tn):
                continue
            # the force acts on the face's projection on the wall measured with F (da/dA
            # times the reference area, projected with the face's normal from F, left in
            # scratch by area_ratio); the projection of the positions weighs the motion
            reference = 0.0
            cosine = 0.0
            for k in range(d):
                reference += disc.bface_C[face, k] * disc.bface_C[face, k]
                cosine += scratch[k] * n[k]
            area = r * math.sqrt(reference) * abs(cosine)
            dual_face_vector(x, disc.X, a, disc.bface_others[face], disc.bface_C[face],
                             scratch)
            projected = 0.0
            for k in range(d):
                projected += scratch[k] * n[k]
            projected = abs(projected)
            share = phi * projected
            faces.weight[face] += phi
            for k in range(d):
                f = phi * area * ts[k]
                sums.force[a, k] += f
                contact.fsum[k] += f
                kv = kinematic_velocity(vA, tA, ts, n, zp, k)
                faces.velocity[face, k] += phi * kv
                sums.motion[a, k] += share * (kv - v[a, k])
            contact.mode[a] = SLIP if slides else STICK
            sums.length[a] += projected
            sums.traction[a] += tn * projected


@njit(cache=True, error_model="numpy")
def reset_surface(nodes, faces, state, force_acc, tstar_n, face_weight, face_velocity,
                  length_sum, motion_sum, traction_sum):
    d = force_acc.shape[1]
    for i in range(nodes.shape[0]):
        a = nodes[i]
        state[a] = OPEN
        tstar_n[a] = 0.0
        length_sum[a] = 0.0
        traction_sum[a] = 0.0
        for k in range(d):
            force_acc[a, k] = 0.0
            motion_sum[a, k] = 0.0
    for k in range(faces.shape[0]):
        face = faces[k]
        face_weight[face] = 0.0
        for j in range(d):
            face_velocity[face, j] = 0.0


@njit(cache=True, error_model="numpy")
def settle_nodes(nodes, faces, v, length_sum, motion_sum, traction_sum, face_weight,
                 face_velocity, xdot, tstar_n):
    """After all passes: each node in contact moves with
    its velocity plus the length- and step-weighted mean of (contact velocity - velocity)
    over its contact, and reports the mean normal contact traction. A face whose summed
    weight exceeds 1 (the two passes' overlaps of a corner counted twice) is scaled to 1."""
    d = v.shape[1]
    for i in range(nodes.shape[0]):
        a = nodes[i]
        total = length_sum[a]
        if total == 0.0:
            continue
        for k in range(d):
            xdot[a, k] = v[a, k] + motion_sum[a, k] / total
        tstar_n[a] = traction_sum[a] / total
    for j in range(faces.shape[0]):
        face = faces[j]
        w = face_weight[face]
        if w > 1.0:
            face_weight[face] = 1.0
            for k in range(d):
                face_velocity[face, k] /= w


@njit(cache=True, error_model="numpy")
def apply_contact(nodes, faces, bface_node, bface_C, face_weight, face_velocity, state, xdot,
                  force_acc, fixed_mask, fixed_value, force, dF):
    """Add the contact forces to the momentum equation, and the contact velocities of the
    contact faces (the nodes' dual boundary faces in contact) to the F equation (weighted by their part of the face and the step; the
    boundary flux keeps the rest). Velocity components prescribed by a boundary condition
    (e.g. a roller side meeting the contact face at a corner) win over the contact
    velocity."""
    d = force.shape[1]
    for i in range(nodes.shape[0]):
        a = nodes[i]
        for k in range(d):
            force[a, k] += force_acc[a, k]
        if state[a] != OPEN:
            for k in range(d):
                if fixed_mask[a, k]:
                    xdot[a, k] = fixed_value[a, k]
    for j in range(faces.shape[0]):
        face = faces[j]
        w = face_weight[face]
        if w == 0.0:
            continue
        a = bface_node[face]
        for i in range(d):
            u = face_velocity[face, i]
            if fixed_mask[a, i]:
                u = w * fixed_value[a, i]
            for J in range(d):
                dF[a, i, J] += u * bface_C[face, J]


@njit(cache=True, error_model="numpy")
def mark_followers(near, found, phi, segs, straightness, follower, follow_nodes, follow_w,
                   follow_normal, follow_phi):
    """Corners that follow the partner's surface: a slave node at a corner of its body
    (``straightness`` 0: a right or sharper corner) whose partner facet (``found``,
    search.Partners) is straight at both ends (both nodes' straightness above 0). Records
    the facet's nodes, the weights of the node's projection on it, the contact normal and
    the node's fraction of the step in contact (docs/contact.md, "Corners follow the face
    they press into")."""
    d = found.normal.shape[1]
    for i in range(near.shape[0]):
        a = near[i]
        s = found.facet[a]
        if s < 0 or straightness[a] > 0.0 or phi[a] == 0.0:
            continue
        flat = True
        for m in range(d):
            if straightness[segs[s, m]] == 0.0:
                flat = False
        if not flat:
            continue
        follower[a] = True
        follow_phi[a] = phi[a]
        for m in range(d):
            follow_nodes[a, m] = segs[s, m]
            follow_w[a, m] = found.weights[a, m]
            follow_normal[a, m] = found.normal[a, m]


@njit(cache=True, error_model="numpy")
def follow_partner_surfaces(nodes, follower, follow_nodes, follow_w, follow_normal,
                            follow_phi, state, v, xdot, face_start, face_list, face_weight,
                            face_velocity):
    """After settle_nodes: a follower corner in contact moves along the contact normal with
    the partner facet's point under it (the facet's nodes' motion, interpolated at the
    corner's projection) instead of its own Riemann velocity, for its fraction of the step;
    its contact faces carry the same change in the F equation, so that F keeps following
    the positions."""
    d = v.shape[1]
    for i in range(nodes.shape[0]):
        a = nodes[i]
        if not follower[a] or state[a] == OPEN:
            continue
        delta = 0.0
        for k in range(d):
            target = 0.0
            for m in range(d):
                b = follow_nodes[a, m]
                target += follow_w[a, m] * (xdot[b, k] if state[b] != OPEN else v[b, k])
            delta += follow_normal[a, k] * (target - xdot[a, k])
        delta *= follow_phi[a]
        for k in range(d):
            xdot[a, k] += delta * follow_normal[a, k]
        for j in range(face_start[a], face_start[a + 1]):
            f = face_list[j]
            w = face_weight[f]
            for k in range(d):
                face_velocity[f, k] += w * delta * follow_normal[a, k]
