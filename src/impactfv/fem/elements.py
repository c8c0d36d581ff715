"""Element kernels of the explicit FE baselines: internal forces (T3, mean-dilatation Q4),
element stresses and their nodal averages.

All kernels work on global (all-bodies concatenated) arrays:

* ``x (N,2)`` current positions, ``v (N,2)`` velocities, ``minv (N,2)`` inverse lumped mass
  per component (0 where the component is prescribed), ``mass (N,)`` lumped mass;
* ``cells (M,k)`` element connectivity, k=3 (T3) or 4 (Q4), ``grads (M,ngp,k,2)`` reference
  shape-function gradients at the integration points, ``wj (M,ngp)`` weight * reference
  Jacobian, ``area0 (M,)`` reference element area, ``emat (M,)`` material row, ``mtab`` the
  material table of :mod:`impactfv.physics.materials`.

The compiled step takes the element arrays as one bundle, :class:`Elements`.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from ..physics import materials as M
from ..compiled import local_matrix, point

_first_piola = point(M.first_piola)
_energy = point(M.strain_energy_density)
_pressure_and_von_mises = point(M.pressure_and_von_mises)
_cauchy_stress = point(M.cauchy_stress)
CP = M.CP

#: the element arrays of the mesh (see above), bundled for the compiled step
Elements = namedtuple("Elements", ["cells", "grads", "wj", "area0", "emat", "mtab"])


# the per-element helpers are inlined: a call per element cost 10-20 % of the element loops
@njit(cache=True, inline="always")
def _shoelace(x, cells, e):
    k = cells.shape[1]
    a = 0.0
    for i in range(k):
        p = cells[e, i]
        q = cells[e, (i + 1) % k]
        a += x[p, 0] * x[q, 1] - x[q, 0] * x[p, 1]
    return 0.5 * a


@njit(cache=True, inline="always")
def _deformation_gradient(x, cells, grads, e, g):
    f11 = 0.0
    f12 = 0.0
    f21 = 0.0
    f22 = 0.0
    for i in range(cells.shape[1]):
        n = cells[e, i]
        g1 = grads[e, g, i, 0]
        g2 = grads[e, g, i, 1]
        f11 += x[n, 0] * g1
        f12 += x[n, 0] * g2
        f21 += x[n, 1] * g1
        f22 += x[n, 1] * g2
    return f11, f12, f21, f22


@njit(cache=True, inline="always")
def _stress(f11, f12, f21, f22, props, Fm, P):
    """P(F) of the material law, F given by components (copied into Fm)."""
    Fm[0, 0] = f11
    Fm[0, 1] = f12
    Fm[1, 0] = f21
    Fm[1, 1] = f22
    _first_piola(Fm, props, P)
    return P[0, 0], P[0, 1], P[1, 0], P[1, 1]


@njit(cache=True, inline="always")
def _longest_side(x, cells, e, k):
    """The longest side of element e (k nodes; a literal k unrolls the loop)."""
    lmax = 0.0
    for i in range(k):
        p = cells[e, i]
        q = cells[e, (i + 1) % k]
        d = math.sqrt((x[q, 0] - x[p, 0]) ** 2 + (x[q, 1] - x[p, 1]) ** 2)
        if d > lmax:
            lmax = d
    return lmax


@njit(cache=True)
def _t3_forces(x, cells, grads, wj, area0, emat, mtab, f):
    """:func:`internal_forces` of a T3 mesh: f_I += A0 P(F) grad0 N_I, l_e = 2a/longest
    side."""
    energy = 0.0
    dtlim = np.inf
    jmin = np.inf
    Fm = local_matrix(2)
    P = local_matrix(2)
    for e in range(cells.shape[0]):
        m = emat[e]
        props = mtab[m]
        a = _shoelace(x, cells, e)
        jbar = a / area0[e]
        if jbar < jmin:
            jmin = jbar
        r = (2.0 * a / _longest_side(x, cells, e, 3)) / mtab[m, CP]
        if r < dtlim:
            dtlim = r
        f11, f12, f21, f22 = _deformation_gradient(x, cells, grads, e, 0)
        p11, p12, p21, p22 = _stress(f11, f12, f21, f22, props, Fm, P)
        w = wj[e, 0]
        energy += w * _energy(Fm, props)
        for i in range(3):
            n = cells[e, i]
            g1 = grads[e, 0, i, 0]
            g2 = grads[e, 0, i, 1]
            f[n, 0] += w * (p11 * g1 + p12 * g2)
            f[n, 1] += w * (p21 * g1 + p22 * g2)
    return energy, dtlim, jmin


@njit(cache=True)
def _q4md_forces(x, cells, grads, wj, area0, emat, mtab, f):
    """:func:`internal_forces` of a mean-dilatation Q4 mesh (see impactfv.fem.stepper for
    the derivation): per Gauss point the isochoric part
    w j0 s [Pbar grad0 N_I - 1/2 (Pbar:F) F^-T grad0 N_I], then per element the volumetric
    part coef da/dx_I; l_e = a/longest side."""
    ngp = grads.shape[1]
    energy = 0.0
    dtlim = np.inf
    jmin = np.inf
    Fm = local_matrix(2)
    P = local_matrix(2)
    for e in range(cells.shape[0]):
        m = emat[e]
        props = mtab[m]
        a = _shoelace(x, cells, e)
        jbar = a / area0[e]
        if jbar < jmin:
            jmin = jbar
        r = (a / _longest_side(x, cells, e, 4)) / mtab[m, CP]
        if r < dtlim:
            dtlim = r
        coef = 0.0
        for g in range(ngp):
            f11, f12, f21, f22 = _deformation_gradient(x, cells, grads, e, g)
            J = f11 * f22 - f12 * f21
            if J < jmin:
                jmin = J
            s = math.sqrt(jbar / J)  # Fbar = s F
            p11, p12, p21, p22 = _stress(s * f11, s * f12, s * f21, s * f22, props, Fm, P)
            w = wj[e, g]
            energy += w * _energy(Fm, props)
            pf = p11 * f11 + p12 * f12 + p21 * f21 + p22 * f22  # Pbar : F
            ws = w * s
            h = 0.5 * pf / J
            # F^-T = cof F / J, cof F = [[F22, -F21], [-F12, F11]]
            c11 = f22
            c12 = -f21
            c21 = -f12
            c22 = f11
            for i in range(4):
                n = cells[e, i]
                g1 = grads[e, g, i, 0]
                g2 = grads[e, g, i, 1]
                f[n, 0] += ws * (p11 * g1 + p12 * g2 - h * (c11 * g1 + c12 * g2))
                f[n, 1] += ws * (p21 * g1 + p22 * g2 - h * (c21 * g1 + c22 * g2))
            coef += ws * 0.5 * pf / jbar
        coef /= area0[e]
        # da/dx_I = 1/2 (y_{I+1} - y_{I-1}, x_{I-1} - x_{I+1})
        for i in range(4):
            n = cells[e, i]
            nn = cells[e, (i + 1) % 4]
            np_ = cells[e, (i + 3) % 4]
            f[n, 0] += coef * 0.5 * (x[nn, 1] - x[np_, 1])
            f[n, 1] += coef * 0.5 * (x[np_, 0] - x[nn, 0])
    return energy, dtlim, jmin


@njit(cache=True)
def internal_forces(x, cells, grads, wj, area0, emat, mtab, f):
    """Assemble internal nodal forces ``f`` (= dE/dx, overwritten) of the whole mesh.

    Returns ``(strain_energy, min_e(l_e / c_e), min J)`` where l_e is the current
    characteristic length (2a/longest side for T3, a/longest side for Q4) and c_e the
    reference p-wave speed of the element's material.
    """
    f[:, :] = 0.0
    if cells.shape[1] == 3:
        return _t3_forces(x, cells, grads, wj, area0, emat, mtab, f)
    return _q4md_forces(x, cells, grads, wj, area0, emat, mtab, f)


@njit(cache=True)
def element_pressure_von_mises(x, cells, grads, wj, area0, emat, mtab, pe, vme):
    """Element-average pressure (-tr sigma / 3, sigma_zz included) and von Mises stress.

    Q4 uses the mean-dilatation F_bar at each Gauss point (so its pressure is the element one).
    """
    k = cells.shape[1]
    ngp = grads.shape[1]
    Fm = local_matrix(2)
    sigma = local_matrix(2)
    for e in range(cells.shape[0]):
        props = mtab[emat[e]]
        jbar = _shoelace(x, cells, e) / area0[e]
        ps = 0.0
        vs = 0.0
        ws = 0.0
        for g in range(ngp):
            f11, f12, f21, f22 = _deformation_gradient(x, cells, grads, e, g)
            if k == 4:
                s = math.sqrt(jbar / (f11 * f22 - f12 * f21))
                f11 *= s
                f12 *= s
                f21 *= s
                f22 *= s
            Fm[0, 0] = f11
            Fm[0, 1] = f12
            Fm[1, 0] = f21
            Fm[1, 1] = f22
            p, vm, _ = _pressure_and_von_mises(Fm, props, sigma)
            w = wj[e, g]
            ps += w * p
            vs += w * vm
            ws += w
        pe[e] = ps / ws
        vme[e] = vs / ws


@njit(cache=True)
def element_stress_and_J(x, cells, grads, wj, area0, emat, mtab, se, je):
    """Element-average Cauchy stress ``se (M, 4)`` = (xx, yy, xy, zz) and J ``je (M,)``
    (Q4: with the mean-dilatation F_bar, so J is the element's Jbar)."""
    k = cells.shape[1]
    ngp = grads.shape[1]
    Fm = local_matrix(2)
    sigma = local_matrix(2)
    for e in range(cells.shape[0]):
        props = mtab[emat[e]]
        jbar = _shoelace(x, cells, e) / area0[e]
        acc = np.zeros(5)
        ws = 0.0
        for g in range(ngp):
            f11, f12, f21, f22 = _deformation_gradient(x, cells, grads, e, g)
            if k == 4:
                s = math.sqrt(jbar / (f11 * f22 - f12 * f21))
                f11 *= s
                f12 *= s
                f21 *= s
                f22 *= s
            Fm[0, 0] = f11
            Fm[0, 1] = f12
            Fm[1, 0] = f21
            Fm[1, 1] = f22
            szz = _cauchy_stress(Fm, props, sigma)
            w = wj[e, g]
            acc[0] += w * sigma[0, 0]
            acc[1] += w * sigma[1, 1]
            acc[2] += w * sigma[0, 1]
            acc[3] += w * szz
            acc[4] += w * (f11 * f22 - f12 * f21)
            ws += w
        for c in range(4):
            se[e, c] = acc[c] / ws
        je[e] = acc[4] / ws


@njit(cache=True)
def nodal_average(cells, area0, ve, nnodes):
    """Reference-area-weighted nodal average of an element field."""
    acc = np.zeros(nnodes)
    wsum = np.zeros(nnodes)
    for e in range(cells.shape[0]):
        for i in range(cells.shape[1]):
            n = cells[e, i]
            acc[n] += area0[e] * ve[e]
            wsum[n] += area0[e]
    for n in range(nnodes):
        if wsum[n] > 0.0:
            acc[n] /= wsum[n]
    return acc
