r"""Explicit total-Lagrangian finite-element baselines: T3 and mean-dilatation Q4.

Discretisation
--------------
* ``"fem-t3"``: linear triangles, one F per element, internal force
  ``f_I = A0 P(F) grad0 N_I`` (exact gradient of ``E = A0 W(F)``).
* ``"fem-q4md"``: bilinear quads, 2x2 Gauss, mean dilatation (F-bar with one volumetric
  J per element).  At Gauss point g, with J_g = det F_g and the element mean dilatation
  ``Jbar = a / A0`` (a = current area by the shoelace formula, A0 = reference area),

      Fbar_g = (Jbar / J_g)^(1/2) F_g,          det Fbar_g = Jbar (plane strain, 2x2 block),

  and the element energy is ``E_e = sum_g w_g j0_g W(Fbar_g)``.  The internal force is the
  exact gradient ``f_I = dE_e/dx_I`` (so the semi-discrete system is Hamiltonian and the
  central-difference scheme conserves energy up to O(dt^2) oscillations).  With
  ``s_g = (Jbar/J_g)^(1/2)``, ``Pbar_g = P(Fbar_g)``:

      dFbar = s [dF + 1/2 (dJbar/Jbar - dJ/J) F],   dJ/J = F^-T : dF,   dJbar = da / A0
      dW    = Pbar : dFbar = s [Pbar : dF - 1/2 (Pbar:F) F^-T : dF] + s/2 (Pbar:F) da/(Jbar A0)

  hence, with dF = dx_I (x) grad0 N_I and da/dx_I = 1/2 (y_{I+1} - y_{I-1}, x_{I-1} - x_{I+1}),

      f_I = sum_g w_g j0_g s_g [Pbar_g grad0 N_I - 1/2 (Pbar_g:F_g) F_g^-T grad0 N_I]
            + [sum_g w_g j0_g s_g (Pbar_g:F_g) / (2 Jbar)] (da/dx_I) / A0.

  The first bracket is the deviatoric ("isochoric") B-matrix part, the second the
  mean-dilatation (B-bar) volumetric part.  The neo-Hookean pressure kappa (Jbar - 1) is then
  constant per element.  The finite-difference check of this force is in tests/test_fem.py.
* Lumped row-sum mass (``m_I = rho int N_I dA``), velocity-Verlet central differences,
  ``dt = cfl * min_e(l_e / c_p,e)`` re-evaluated each step on the current geometry
  (l_e = 2a/longest side for T3, a/longest side for Q4; c_p = sqrt((lam + 2 mu)/rho)).
  Prescribed velocity components are set strongly every half step (their inverse mass is 0).

Contact (choice and parameters)
-------------------------------
Kinematic predictor-corrector contact (Abaqus/Explicit default), frictionless,
node-to-segment, symmetric two-pass (nodes of A against segments of B and vice versa):

1. predictor: v_{n+1/2} = v_n + dt/2 a_n, predicted x* = x_n + dt v_{n+1/2};
2. search on x*: uniform bins (cell list) of the master segments by midpoint, bin size
   >= 1.1 * longest master segment + 2 * depth; each slave node scans the 3x3 neighbouring
   bins (cost linear in the number of contact nodes).  A slave node is paired with the
   facing master segment (n_slave . n_master < -0.3, projection parameter in [-0.01, 1.01])
   of smallest |gap| with |gap| <= depth; depth = 0.5 * shortest contact segment (reference);
3. corrector: projected Gauss-Seidel sweeps (at most ``CONTACT_MAX_ITER`` = 50, stopping
   when the largest penetration < ``CONTACT_TOL`` = 1e-9 * depth) over the pairs, each
   removing the current predicted penetration g < 0 by an equal and opposite normal impulse
   (lambda n on the slave node, -(1-xi) lambda n and -xi lambda n on the segment nodes,
   lambda = -g / (dt sum_i c_i^2 n.M_i^-1 n)).  The impulses sum to zero, so linear momentum
   is conserved to round-off, and the predicted positions (= x_{n+1}) have no penetration
   (to the tolerance), whatever the impact speed or stiffness: no penalty parameter and no
   time-step reduction.
   The contact force reported is impulse/dt on body_a.  The corrections are inelastic (the
   relative normal velocity of the contacting nodes is removed): ``contact_energy`` is the
   energy absorbed by the contact, minus the accumulated change of the kinetic energy of the
   half-step velocities caused by the corrections (= minus the work of the contact impulses),
   so ``total_energy = kinetic + strain + contact`` stays constant up to the inelastic loss
   of the first impact of each node (about 1 % of E0 for a 40-element bar, O(h)).

Known limitation: on fine meshes (e.g. 160x16 Q4MD uniaxial bars) tangential velocities of
the frictionless contact-face nodes (a few m/s) develop during unloading and the accumulated
contact work then drifts (+11 % of E0 there) although kinetic + strain energy, momentum,
contact force and penetration remain correct.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..materials import N_PROPS, Material
from . import kernels as K

CONTACT_MAX_ITER = 50
CONTACT_TOL_REL = 1e-9
METHODS = ("fem-t3", "fem-q4md")


@dataclass
class FemBody:
    name: str
    points: np.ndarray          # (n,2) reference coordinates
    cells: np.ndarray           # (m,3) triangles or (m,4) quads, counter-clockwise
    material: Material
    velocity: np.ndarray | None = None       # (n,2) initial velocity (default 0)
    fixed_mask: np.ndarray | None = None     # (n,2) bool, prescribed velocity component
    fixed_value: np.ndarray | None = None    # (n,2) prescribed values where fixed_mask
    contact_edges: np.ndarray | None = None  # (k,2) body on the LEFT of a->b


@dataclass
class FemContact:
    body_a: int
    body_b: int


@dataclass
class FemResult:
    history: dict = field(default_factory=dict)
    bodies: dict = field(default_factory=dict)
    snapshots: list = field(default_factory=list)
    wall_time: float = 0.0
    steps: int = 0


# --------------------------------------------------------------------------- setup

_GP = 1.0 / np.sqrt(3.0)
_Q4_GAUSS = np.array([[-_GP, -_GP], [_GP, -_GP], [_GP, _GP], [-_GP, _GP]])
_Q4_NODES = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])


def reference_geometry(points, cells, density):
    """Reference gradients ``grads (m,ngp,k,2)``, ``wj (m,ngp)``, ``area0 (m,)`` and the
    lumped row-sum nodal mass ``(n,)`` of a T3 or Q4 mesh."""
    X = np.asarray(points, dtype=np.float64)
    c = np.asarray(cells, dtype=np.int64)
    m, k = c.shape
    mass = np.zeros(len(X))
    if k == 3:
        x1, x2, x3 = X[c[:, 0]], X[c[:, 1]], X[c[:, 2]]
        area = 0.5 * ((x2[:, 0] - x1[:, 0]) * (x3[:, 1] - x1[:, 1])
                      - (x3[:, 0] - x1[:, 0]) * (x2[:, 1] - x1[:, 1]))
        if np.any(area <= 0.0):
            raise ValueError("triangles must be counter-clockwise with positive area")
        grads = np.empty((m, 1, 3, 2))
        grads[:, 0, 0] = np.column_stack([x2[:, 1] - x3[:, 1], x3[:, 0] - x2[:, 0]])
        grads[:, 0, 1] = np.column_stack([x3[:, 1] - x1[:, 1], x1[:, 0] - x3[:, 0]])
        grads[:, 0, 2] = np.column_stack([x1[:, 1] - x2[:, 1], x2[:, 0] - x1[:, 0]])
        grads /= (2.0 * area)[:, None, None, None]
        wj = area[:, None].copy()
        np.add.at(mass, c.ravel(), np.repeat(density * area / 3.0, 3))
        return grads, wj, area, mass
    if k != 4:
        raise ValueError("cells must have 3 or 4 nodes")
    xe = X[c]  # (m,4,2)
    grads = np.empty((m, 4, 4, 2))
    wj = np.empty((m, 4))
    for g, (xi, eta) in enumerate(_Q4_GAUSS):
        dn = np.column_stack([0.25 * _Q4_NODES[:, 0] * (1 + _Q4_NODES[:, 1] * eta),
                              0.25 * _Q4_NODES[:, 1] * (1 + _Q4_NODES[:, 0] * xi)])  # (4,2)
        nval = 0.25 * (1 + _Q4_NODES[:, 0] * xi) * (1 + _Q4_NODES[:, 1] * eta)
        jac = np.einsum("eid,ij->edj", xe, dn)  # (m,2,2): dx_d/dxi_j
        det = jac[:, 0, 0] * jac[:, 1, 1] - jac[:, 0, 1] * jac[:, 1, 0]
        if np.any(det <= 0.0):
            raise ValueError("quads must be counter-clockwise and convex")
        inv = np.empty_like(jac)
        inv[:, 0, 0] = jac[:, 1, 1] / det
        inv[:, 1, 1] = jac[:, 0, 0] / det
        inv[:, 0, 1] = -jac[:, 0, 1] / det
        inv[:, 1, 0] = -jac[:, 1, 0] / det
        # grad_X N_I = J^-T dN/dxi
        grads[:, g] = np.einsum("ij,ejd->eid", dn, inv)
        wj[:, g] = det
        np.add.at(mass, c.ravel(), (density * det[:, None] * nval[None, :]).ravel())
    area = wj.sum(axis=1)
    return grads, wj, area, mass


def _check_method(method, cells):
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    k = np.asarray(cells).shape[1] if np.asarray(cells).ndim == 2 else -1
    if (method == "fem-t3" and k != 3) or (method == "fem-q4md" and k != 4):
        raise ValueError(f"method {method!r} needs {'3' if method == 'fem-t3' else '4'}-node "
                         f"cells, got cells of shape {np.asarray(cells).shape}")


# --------------------------------------------------------------------------- driver

def simulate_fem(bodies, contacts, end_time, method, cfl=0.5, snapshot_times=(),
                 progress=None) -> FemResult:
    """Run the explicit FE baseline; see the module docstring.  History row 0 is t = 0."""
    bodies = list(bodies)
    contacts = list(contacts)
    if not bodies:
        raise ValueError("no bodies")
    for b in bodies:
        _check_method(method, b.cells)

    # ---- global arrays
    node_off = np.cumsum([0] + [len(b.points) for b in bodies])
    cell_off = np.cumsum([0] + [len(b.cells) for b in bodies])
    nn = int(node_off[-1])
    X = np.concatenate([np.asarray(b.points, dtype=np.float64) for b in bodies])
    cells = np.concatenate([np.asarray(b.cells, dtype=np.int64) + node_off[i]
                            for i, b in enumerate(bodies)])
    mtab = np.array([b.material.table_row() for b in bodies], dtype=np.float64)
    assert mtab.shape[1] == N_PROPS
    emat = np.concatenate([np.full(len(b.cells), i, dtype=np.int64)
                           for i, b in enumerate(bodies)])
    grads, wj, area0, mass = [], [], [], np.zeros(nn)
    for i, b in enumerate(bodies):
        g, w, a, m = reference_geometry(b.points, b.cells, b.material.density)
        grads.append(g)
        wj.append(w)
        area0.append(a)
        mass[node_off[i]:node_off[i + 1]] = m
    grads = np.ascontiguousarray(np.concatenate(grads))
    wj = np.ascontiguousarray(np.concatenate(wj))
    area0 = np.concatenate(area0)
    if np.any(mass <= 0.0):
        raise ValueError("node without mass (not attached to any cell)")

    def per_node(arr, default, dtype):
        if arr is None:
            return np.full((len(default), 2), 0, dtype=dtype)
        a = np.asarray(arr, dtype=dtype)
        if a.shape != (len(default), 2):
            raise ValueError(f"per-node array has shape {a.shape}, expected {(len(default), 2)}")
        return a

    v = np.concatenate([per_node(b.velocity, b.points, np.float64) for b in bodies])
    fmask = np.concatenate([per_node(b.fixed_mask, b.points, np.bool_) for b in bodies])
    fval = np.concatenate([per_node(b.fixed_value, b.points, np.float64) for b in bodies])
    fval = np.where(fmask, fval, 0.0)
    v = np.where(fmask, fval, v)
    minv = np.where(fmask, 0.0, 1.0 / mass[:, None])
    x = X.copy()

    # ---- contact passes
    sl_ptr, sl_nodes, sg_ptr, sg, se_ptr, se, pc, pa, pdep = [0], [], [0], [], [0], [], [], [], []
    for k, c in enumerate(contacts):
        if not (0 <= c.body_a < len(bodies) and 0 <= c.body_b < len(bodies)):
            raise ValueError(f"contact {k} refers to a missing body")
        ea, eb = (np.asarray(bodies[i].contact_edges if bodies[i].contact_edges is not None
                             else np.empty((0, 2)), dtype=np.int64).reshape(-1, 2)
                  + node_off[i] for i in (c.body_a, c.body_b))
        lens = [np.linalg.norm(X[e[:, 1]] - X[e[:, 0]], axis=1) for e in (ea, eb) if len(e)]
        depth = 0.5 * min(float(l.min()) for l in lens) if lens else 0.0
        for slave, master, is_a in ((ea, eb, True), (eb, ea, False)):
            nodes = np.unique(slave.ravel())
            sl_nodes.append(nodes)
            sl_ptr.append(sl_ptr[-1] + len(nodes))
            sg.append(master)
            sg_ptr.append(sg_ptr[-1] + len(master))
            se.append(slave)
            se_ptr.append(se_ptr[-1] + len(slave))
            pc.append(k)
            pa.append(is_a)
            pdep.append(depth)
    ncontact = len(contacts)
    pslave_ptr = np.array(sl_ptr, dtype=np.int64)
    slave_nodes = np.concatenate(sl_nodes).astype(np.int64) if sl_nodes else np.zeros(0, np.int64)
    pseg_ptr = np.array(sg_ptr, dtype=np.int64)
    segs = np.concatenate(sg).astype(np.int64) if sg else np.zeros((0, 2), np.int64)
    psedge_ptr = np.array(se_ptr, dtype=np.int64)
    sedges = np.concatenate(se).astype(np.int64) if se else np.zeros((0, 2), np.int64)
    pcontact = np.array(pc, dtype=np.int64)
    pslave_is_a = np.array(pa, dtype=np.bool_)
    pdepth = np.array(pdep, dtype=np.float64)
    maxseg = max([len(s) for s in sg] + [1])
    normals = np.zeros((nn, 2))
    head = np.empty(4 * maxseg + 16, dtype=np.int64)
    nxt = np.empty(maxseg, dtype=np.int64)
    ncap = max(len(slave_nodes), 1)
    cons_n = np.empty((ncap, 3), dtype=np.int64)
    cons_xi = np.empty(ncap)
    cons_nrm = np.empty((ncap, 2))
    cons_p = np.empty(ncap, dtype=np.int64)
    cforce = np.zeros((max(ncontact, 1), 2))
    cgap = np.full(max(ncontact, 1), np.nan)
    tol = CONTACT_TOL_REL * (float(pdepth.min()) if len(pdepth) else 1.0)

    # ---- initial state
    f = np.zeros((nn, 2))
    acc = np.zeros((nn, 2))
    se0, dtlim, jmin = K.internal_forces(x, cells, grads, wj, area0, emat, mtab, f)
    acc[:] = -f * minv
    ke0, px0, py0 = K.kinetic_and_momentum(v, mass)
    keys = ["time", "dt", "kinetic_energy", "strain_energy", "contact_energy", "total_energy",
            "momentum_x", "momentum_y"]
    for k in range(ncontact):
        keys += [f"contact{k}_fx", f"contact{k}_fy", f"contact{k}_gap"]
    hist = {key: [] for key in keys}

    def record(t, dt, ke, se_, ce, px, py):
        hist["time"].append(t)
        hist["dt"].append(dt)
        hist["kinetic_energy"].append(ke)
        hist["strain_energy"].append(se_)
        hist["contact_energy"].append(ce)
        hist["total_energy"].append(ke + se_ + ce)
        hist["momentum_x"].append(px)
        hist["momentum_y"].append(py)
        for k in range(ncontact):
            hist[f"contact{k}_fx"].append(cforce[k, 0])
            hist[f"contact{k}_fy"].append(cforce[k, 1])
            hist[f"contact{k}_gap"].append(cgap[k])

    def state():
        pe = np.empty(len(cells))
        vme = np.empty(len(cells))
        K.element_pressure_von_mises(x, cells, grads, wj, area0, emat, mtab, pe, vme)
        out = {}
        for i, b in enumerate(bodies):
            n0, n1 = node_off[i], node_off[i + 1]
            c0, c1 = cell_off[i], cell_off[i + 1]
            lc = np.asarray(b.cells, dtype=np.int64)
            out[b.name] = {
                "reference_points": X[n0:n1].copy(),
                "points": x[n0:n1].copy(),
                "cells": lc.copy(),
                "velocity": v[n0:n1].copy(),
                "pressure": K.nodal_average(lc, area0[c0:c1], pe[c0:c1], n1 - n0),
                "von_mises": K.nodal_average(lc, area0[c0:c1], vme[c0:c1], n1 - n0),
            }
        return out

    record(0.0, 0.0, ke0, se0, 0.0, px0, py0)
    snaps_pending = sorted(float(s) for s in snapshot_times)
    snapshots = []
    t = 0.0
    while snaps_pending and snaps_pending[0] <= t:
        snapshots.append((t, state()))
        snaps_pending.pop(0)

    contact_energy = 0.0
    steps = 0
    next_report = 0.0
    wall0 = time.perf_counter()
    while t < end_time * (1.0 - 1e-12):
        if not np.isfinite(dtlim) or jmin <= 0.0:
            raise FloatingPointError(f"element inverted or degenerate at t={t:.6g} (min J={jmin})")
        dt = cfl * dtlim
        if t + dt > end_time:
            dt = end_time - t
        se_, ke, px, py, dke, dtlim, jmin, _ = K.step(
            x, v, acc, f, minv, mass, fmask, fval, dt, cells, grads, wj, area0, emat, mtab,
            pslave_ptr, slave_nodes, pseg_ptr, segs, psedge_ptr, sedges, pcontact, pslave_is_a,
            pdepth, normals, head, nxt, cons_n, cons_xi, cons_nrm, cons_p, cforce, cgap,
            CONTACT_MAX_ITER, tol)
        t += dt
        steps += 1
        contact_energy -= dke
        record(t, dt, ke, se_, contact_energy, px, py)
        while snaps_pending and snaps_pending[0] <= t:
            snapshots.append((t, state()))
            snaps_pending.pop(0)
        if progress is not None and t >= next_report:
            progress(min(t / end_time, 1.0))
            next_report = t + 0.01 * end_time
    wall = time.perf_counter() - wall0
    if progress is not None:
        progress(1.0)
    history = {k: np.asarray(vals, dtype=np.float64) for k, vals in hist.items()}
    return FemResult(history=history, bodies=state(), snapshots=snapshots, wall_time=wall,
                     steps=steps)
