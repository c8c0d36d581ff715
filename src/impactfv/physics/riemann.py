"""Acoustic Riemann states of the p-F scheme as small point functions (docs/theory.md).

Waves along a spatial unit normal n: pressure waves at +-c_p and shear waves at +-c_s, each
carrying a jump [[t]] = -+ Z [[v]] with the impedance tensor
Z = rho c_p n (x) n + rho c_s (I - n (x) n) (seed paper, eqs. 3-4). Vectors are small arrays
of length d = 2 or 3; the functions write their results into arrays the caller provides and
never allocate, so the same source compiles for any backend.
"""

from .materials import small_strain
from .tensors import cofactor_times, dot, normalise, solve


def spatial_normal(F, N, n):
    """Unit spatial normal n = F^-T N / |F^-T N| of a dual face (seed eq. 9a), written into
    n; returns the area ratio da/dA = |cof(F) N| (Nanson: da n = cof(F) dA N)."""
    cofactor_times(F, N, n)
    return normalise(n)


def face_geometry(F, N, props, n):
    """Normal n and area ratio da/dA of a face of reference normal N and deformation F: the
    spatial normal (Nanson) for finite-strain laws, the reference normal and 1 for
    small-strain laws (for which sigma N is the nominal traction)."""
    if small_strain(props):
        for i in range(N.shape[0]):
            n[i] = N[i]
        return 1.0
    return spatial_normal(F, N, n)


def face_area_normal(F, A, props, m):
    """Spatial area vector m = da n (seed eq. 9a) of a face of reference area vector
    A = dA N and deformation F, written into m: cof(F) A (Nanson: da n = cof(F) dA N) for finite-strain
    laws, A itself for small-strain laws. Returns 1 / |m|^2, with which the projections on
    the unit normal need no square root: (n . w) n = (m . w) m / |m|^2. The force of a
    Cauchy stress on the face is sigma m (face_traction with area 1); with A of unit length
    m is (da/dA) n, and sigma m the nominal traction P N."""
    if small_strain(props):
        for i in range(A.shape[0]):
            m[i] = A[i]
    else:
        cofactor_times(F, A, m)
    return 1.0 / dot(m, m)


def face_traction(sigma, n, area, t):
    """Nominal traction (force per unit reference area) of a face with spatial normal n and
    area ratio da/dA: t = sigma n da/dA, which is P N when sigma, n and da/dA come from the
    same F (Nanson). Evaluated for both sides of a face with the face's own n and da/dA, the
    traction jump sees no rigid rotation of a stressed state."""
    d = n.shape[0]
    for i in range(d):
        s = 0.0
        for k in range(d):
            s += sigma[i, k] * n[k]
        t[i] = s * area


def impedance_times(zp, zs, n, w, out):
    """out = Z w with the impedance tensor Z = zp n (x) n + zs (I - n (x) n): the ratio of
    the traction jump to the velocity jump across an acoustic wave (seed eqs. 3-4)."""
    wn = dot(n, w)
    for i in range(n.shape[0]):
        out[i] = zs * w[i] + (zp - zs) * wn * n[i]


def upwind_traction(tbar, dv, zp, zs, n, t):
    """Interior momentum flux (seed eq. 9a): the traction t = tbar + Z [[v]] / 2 between two
    states of one material, with tbar the mean of their face tractions and [[v]] = v_b - v_a
    the jump of their velocities across the dual face (N from a to b). Written into t."""
    impedance_times(zp, zs, n, dv, t)
    for i in range(n.shape[0]):
        t[i] = tbar[i] + 0.5 * t[i]


def upwind_traction_area(fbar, dv, zp, zs, m, inverse_m2, f):
    """upwind_traction (seed eq. 9a) on a face given by its area vector m (face_area_normal)
    and 1 / |m|^2:
    f = fbar + Z [[v]] / 2 with Z [[v]] = zs [[v]] + (zp - zs) (n . [[v]]) n and
    (n . [[v]]) n = (m . [[v]]) m / |m|^2. With fbar the mean force of the two sides' stresses
    on a face of reference area |A| and impedances rho c |A| this is the face's whole upwind
    force, |A| times the traction of upwind_traction, without the square root and the
    divisions of a unit normal."""
    wn = dot(m, dv) * inverse_m2
    for i in range(m.shape[0]):
        f[i] = fbar[i] + 0.5 * (zs * dv[i] + (zp - zs) * wn * m[i])


def central_velocity(va, vb, v):
    """Geometric flux of seed eq. 9b as written: the velocity v = (v_a + v_b) / 2 on the dual
    face in the deformation-gradient equation."""
    for i in range(va.shape[0]):
        v[i] = 0.5 * (va[i] + vb[i])


def upwind_velocity(va, vb, dt, zp, v):
    """Upwind geometric flux (the velocity on a dual face in seed eq. 9b):
    v = (v_a + v_b) / 2 + [[t]] / (2 rho c_p), with [[t]] = t_b - t_a the jump of the face
    tractions.

    The acoustic Riemann velocity would divide the part of [[t]] across n by rho c_s instead.
    At a p-wave front, a face oblique to the front sees a traction jump across its normal
    that a Riemann solver along the normal takes for a shear wave; divided by rho c_s
    (c_p / c_s = 10 at nu = 0.495) it became a tangential face velocity of order 100 m/s and
    left spurious shear in F along the boundaries (docs/theory.md). With the p-wave impedance
    in every direction the flux stays consistent and dissipative, and shear waves are still
    captured by the momentum flux (docs/validation.md).
    """
    scale = 0.5 / zp
    for i in range(va.shape[0]):
        v[i] = 0.5 * (va[i] + vb[i]) + scale * dt[i]


def boundary_state(v, t, zp, zs, n, fixed, v_given, t_given, Z, rhs, vC, tC):
    """Riemann state on a boundary face, the boundary terms of seed eqs. 9a-9b, from the
    outgoing characteristic t^C - t = Z (v^C - v) (docs/theory.md, "Boundaries").

    (v, t) is the interior state (t = P N, outward). Each Cartesian component i is either a
    prescribed velocity (fixed[i], value v_given[i]) or a prescribed traction (t_given[i]; zero
    on a free surface). Writes v^C into vC and t^C into tC; Z and rhs are d x d and d scratch.
    """
    d = n.shape[0]
    held = False
    for i in range(d):
        held = held or fixed[i]
    if not held:
        # every component a prescribed traction (a free or loaded face): t^C = t_given and
        # v^C = v + Z^-1 (t_given - t), Z^-1 = n (x) n / zp + (I - n (x) n) / zs
        jn = 0.0
        for i in range(d):
            jn += (t_given[i] - t[i]) * n[i]
        compliance_s = 1.0 / zs
        compliance_difference = 1.0 / zp - compliance_s
        for i in range(d):
            jump = t_given[i] - t[i]
            vC[i] = v[i] + jump * compliance_s + compliance_difference * jn * n[i]
            tC[i] = t_given[i]
        return
    # unknown dv = v^C - v with dt = Z dv; per component one of (dv_i, dt_i) is known
    for i in range(d):
        if fixed[i]:
            for j in range(d):
                Z[i, j] = 1.0 if i == j else 0.0
            rhs[i] = v_given[i] - v[i]
        else:
            for j in range(d):
                Z[i, j] = _impedance_entry(zp, zs, n, i, j)
            rhs[i] = t_given[i] - t[i]
    solve(Z, rhs, vC)
    for i in range(d):
        if fixed[i]:
            vC[i] = v_given[i] - v[i]
    for i in range(d):
        s = 0.0
        for j in range(d):
            s += _impedance_entry(zp, zs, n, i, j) * vC[j]
        tC[i] = t[i] + s
    for i in range(d):
        vC[i] += v[i]


def geometric_boundary_velocity(w, t, tC, vC, fixed, zp, n, tangential, u):
    """Velocity on a boundary face in the deformation-gradient equation (the boundary term of
    seed eq. 9b), written into u: a prescribed component takes its value vC; the others take
    the interior velocity w plus the characteristic correction with the p-wave impedance,
    along the spatial normal n only (``tangential`` 0) or in every direction (1),

        u = w + n (n . (t^C - t)) / (rho c_p)                  (normal)
        u = w + (t^C - t) / (rho c_p)                          (full, as riemann.upwind_velocity)

    The normal part adds u (x) N = (n (x) N) x (a number) to the rate of F, and n (x) N F^-1
    is a multiple of n (x) n (Nanson: F^-T N is parallel to n), a pure stretch rate. The
    tangential part adds tau (x) n, half of it a spin: F turns against the positions with
    nothing to turn it back (a rotation costs no strain energy), and on a compressed free
    surface in 2D the rotated stresses fold the boundary cells; but it is also what damps the
    free faces' tangential modes, without which the 3D scheme has growing modes on
    unstructured tetrahedra (docs/theory.md, "Boundaries"). The traction-free condition on
    the tangential traction is imposed by the momentum flux (``boundary_state``'s t^C)."""
    d = n.shape[0]
    jn = 0.0
    for i in range(d):
        jn += (tC[i] - t[i]) * n[i]
    compliance = 1.0 / zp
    for i in range(d):
        normal_part = jn * n[i]
        u[i] = vC[i] if fixed[i] else \
            w[i] + (normal_part + tangential * (tC[i] - t[i] - normal_part)) * compliance


def _impedance_entry(zp, zs, n, i, j):
    """Z_ij = zs delta_ij + (zp - zs) n_j n_i."""
    return zs * (1.0 if i == j else 0.0) + (zp - zs) * n[j] * n[i]

