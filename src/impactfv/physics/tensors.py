"""Small tensor point functions on d x d matrices and d-vectors (d = 2 or 3).

Backend-free: plain Python on small arrays, no allocation, so that the same source compiles
for a CPU loop (numba) or a GPU. The dimension is read from the array shapes; inlined into a
kernel whose dimension is a compile-time constant, the branches on it fold away.
"""

import math


def determinant(F):
    """det F."""
    if F.shape[0] == 2:
        return F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
    return (F[0, 0] * (F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1])
            - F[0, 1] * (F[1, 0] * F[2, 2] - F[1, 2] * F[2, 0])
            + F[0, 2] * (F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0]))


def cofactor_entry(F, i, J):
    """(cof F)_iJ = (det F) (F^-T)_iJ."""
    if F.shape[0] == 2:
        return (-1.0 if i != J else 1.0) * F[1 - i, 1 - J]
    i1 = (i + 1) % 3
    i2 = (i + 2) % 3
    J1 = (J + 1) % 3
    J2 = (J + 2) % 3
    return F[i1, J1] * F[i2, J2] - F[i1, J2] * F[i2, J1]


def stress_power(sigma, F, D):
    """P : D with the first Piola stress P = sigma cof F (sigma the Cauchy stress): the
    strain power of a deformation-gradient rate D (the energy balance, docs/theory.md)."""
    d = F.shape[0]
    power = 0.0
    for i in range(d):
        for J in range(d):
            P = 0.0
            for k in range(d):
                P += sigma[i, k] * cofactor_entry(F, k, J)
            power += P * D[i, J]
    return power


def cofactor_times(F, N, out):
    """out = cof(F) N: Nanson's formula, da n = cof(F) dA N."""
    if F.shape[0] == 2:
        out[0] = F[1, 1] * N[0] - F[1, 0] * N[1]
        out[1] = -F[0, 1] * N[0] + F[0, 0] * N[1]
        return
    for i in range(3):
        s = 0.0
        for J in range(3):
            s += cofactor_entry(F, i, J) * N[J]
        out[i] = s


def symmetric_index(i, j, d):
    """Position of the component (i, j), i <= j, among the d (d + 1) / 2 independent
    components of a symmetric d x d matrix, row by row."""
    return i * d - i * (i - 1) // 2 + (j - i)


def dot(u, w):
    s = 0.0
    for i in range(u.shape[0]):
        s += u[i] * w[i]
    return s


def normalise(u):
    """Scale u to unit length in place; returns its former length."""
    s = math.sqrt(dot(u, u))
    inverse = 1.0 / s       # one division instead of d (a quotient costs several products)
    for i in range(u.shape[0]):
        u[i] *= inverse
    return s


def solve(M, rhs, out):
    """out = M^-1 rhs for a 2x2 or 3x3 matrix (Cramer's rule with cofactors)."""
    det = determinant(M)
    d = M.shape[0]
    for i in range(d):
        s = 0.0
        for J in range(d):
            s += cofactor_entry(M, J, i) * rhs[J]
        out[i] = s / det


def _right_cauchy_green_3d(F):
    """The six entries of C = F^T F (3 x 3), the mean q of its eigenvalues and the sum p2 of
    their squared deviations from q (|C - q I|^2): (c00, c11, c22, c01, c02, c12, q, p2)."""
    c00 = F[0, 0] ** 2 + F[1, 0] ** 2 + F[2, 0] ** 2
    c11 = F[0, 1] ** 2 + F[1, 1] ** 2 + F[2, 1] ** 2
    c22 = F[0, 2] ** 2 + F[1, 2] ** 2 + F[2, 2] ** 2
    c01 = F[0, 0] * F[0, 1] + F[1, 0] * F[1, 1] + F[2, 0] * F[2, 1]
    c02 = F[0, 0] * F[0, 2] + F[1, 0] * F[1, 2] + F[2, 0] * F[2, 2]
    c12 = F[0, 1] * F[0, 2] + F[1, 1] * F[1, 2] + F[2, 1] * F[2, 2]
    q = (c00 + c11 + c22) / 3.0
    off = c01 * c01 + c02 * c02 + c12 * c12
    p2 = (c00 - q) ** 2 + (c11 - q) ** 2 + (c22 - q) ** 2 + 2.0 * off
    return c00, c11, c22, c01, c02, c12, q, p2


def smallest_stretch_squared_bounds(F):
    """(lo, hi) with lo <= smallest eigenvalue of C = F^T F <= hi, without the cubic's
    trigonometric solution (3 x 3): hi the smallest diagonal entry of C (a Rayleigh
    quotient), lo = q - 2 p with q the mean of the eigenvalues and 6 p^2 the sum of their
    squared deviations from it (an eigenvalue is furthest from the mean when the other two
    are equal, at 2 p). The same q and p as smallest_stretch_squared; returns (lo, hi, q)."""
    c00, c11, c22, _, _, _, q, p2 = _right_cauchy_green_3d(F)
    return q - 2.0 * math.sqrt(p2 / 6.0), min(c00, c11, c22), q


def smallest_stretch_squared(F):
    """Smallest eigenvalue of C = F^T F (principal stretch squared)."""
    d = F.shape[0]
    if d == 2:
        c11 = F[0, 0] * F[0, 0] + F[1, 0] * F[1, 0]
        c12 = F[0, 0] * F[0, 1] + F[1, 0] * F[1, 1]
        c22 = F[0, 1] * F[0, 1] + F[1, 1] * F[1, 1]
        half_tr = 0.5 * (c11 + c22)
        disc = math.sqrt(max(0.25 * (c11 - c22) ** 2 + c12 * c12, 0.0))
        return half_tr - disc
    # symmetric 3x3: trigonometric solution of the characteristic cubic
    c00, c11, c22, c01, c02, c12, q, p2 = _right_cauchy_green_3d(F)
    if p2 <= 1e-30 * q * q:
        return q
    p = math.sqrt(p2 / 6.0)
    b00 = (c00 - q) / p
    b11 = (c11 - q) / p
    b22 = (c22 - q) / p
    b01 = c01 / p
    b02 = c02 / p
    b12 = c12 / p
    r = 0.5 * (b00 * (b11 * b22 - b12 * b12) - b01 * (b01 * b22 - b12 * b02)
               + b02 * (b01 * b12 - b11 * b02))
    r = min(max(r, -1.0), 1.0)
    phi = math.acos(r) / 3.0
    return q + 2.0 * p * math.cos(phi + 2.0 * math.pi / 3.0)
