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
   energy the contact absorbed, the sum over impulses of minus their change of the
   end-of-step energy.  An impulse dv on a half-step velocity changes KE(v_{n+1}) +
   SE(x_{n+1}) by m (v_n + dv/2) . dv (v_n = v_{n+1/2} - dt/2 a_n; to O(dt^2)), so
   ``total_energy = kinetic + strain + contact`` stays at its initial value up to the
   O(dt^2) ripple of the central-difference step, and ``kinetic + strain`` falls by what the
   contact absorbed (about 0.3 % of E0 for a 160x16 Q4MD uniaxial bar impact, 0.4 % for an
   oblique steel-on-aluminium impact; the inelastic loss of the first impact of each node,
   O(h)).  (Counting the work with the velocities after each impulse, m v_new . dv, as an
   earlier version did, drifted by 5-7 % of E0 on the oblique impact of tests/test_fem.py,
   21-26 % on a finer oblique case and 11 % on the fine bars, while kinetic + strain energy
   was right.)

From a case (:meth:`FEStepper.from_case`)
-----------------------------------------
* ``fem-t3`` uses each body's triangle mesh as it is (the same nodes and triangles the FV
  scheme builds its median dual on);
* ``fem-q4md`` needs quadrilaterals: a body meshed with ``generator = "rectangle"`` gets the
  bilinear quads of the same grid (same nodes, same boundary regions), a body read from a
  mesh file of quadrilaterals gets them as they are (the FV scheme and fem-t3 run on their
  triangles, impactfv.mesh.quads); a disc or a file of triangles is refused;
* a ``[[body.boundary]]`` velocity component is prescribed strongly on every node of its
  region;
* a ``[[contact]]`` between two bodies becomes a frictionless kinematic contact whose
  surfaces are the bodies' boundary facets (or those of the contact's ``regions``). The FE
  contact is frictionless only, so ``model = "stick"`` is refused; traction boundaries and
  rigid walls are not implemented here and are refused with an InputError.

"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError, SimulationError
from ..geometry.surfaces import surface_facets
from ..physics.materials import N_PROPS, Material
from ..mesh.core import Mesh
from ..mesh.edges import boundary_facets, unique_edges
from ..mesh.generators import quads_to_triangles, rectangle_quads
from .contact import ContactPasses, ContactWork
from .elements import (Elements, element_pressure_von_mises, element_stress_and_J,
                       internal_forces, nodal_average)
from .verlet import NodeData, State
from .verlet import step as verlet_step

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



# --------------------------------------------------------------------------- from a case

def case_mesh(body, method):
    """The FE mesh of a case body: its triangles (fem-t3), or its quadrilaterals (fem-q4md:
    those of a rectangle generator's grid, or those of a mesh file of quads), with the same
    nodes and boundary regions."""
    mesh = body.mesh
    if method != "fem-q4md":
        return mesh
    spec = body.spec.mesh
    if mesh.quads is not None:
        return Mesh(mesh.points, mesh.quads, mesh.regions)
    quads = rectangle_quads(spec.origin, spec.size, spec.divisions)
    return Mesh(quads.points * spec.scale, quads.cells, quads.regions)


def _contact_surface(case, mesh, k, name):
    spec = case.contacts[k]
    return surface_facets(boundary_facets(mesh.cells), mesh.regions, spec.regions,
                          f"{case.source}: contact[{k}].regions", name)


def unsupported(case, method) -> str | None:
    """Why ``method`` (an FE method) cannot run ``case``, as an input-error line naming the
    case file and the key, or None. Checks the case only; builds nothing."""
    src = case.source
    if method not in METHODS:
        return f"{src}: run.method: {method!r} is not a FE method ({', '.join(METHODS)})"
    for ib, body in enumerate(case.bodies):
        spec = body.spec.mesh
        if method == "fem-q4md" and body.mesh.quads is None and spec.generator != "rectangle":
            what = f"reads {spec.file!r}, which has triangles" if spec.file else \
                f"is a {spec.generator} of triangles"
            return (f"{src}: body[{ib}].mesh: method fem-q4md needs quadrilaterals (a "
                    "rectangle generator, or a mesh file of quadrilaterals only); body "
                    f"{body.name!r} {what}")
        if method == "fem-q4md" and body.mesh.quads is not None:
            q = body.mesh.points[body.mesh.quads]
            e1 = q - np.roll(q, 1, axis=1)
            e2 = np.roll(q, -1, axis=1) - q
            turn = e1[..., 0] * e2[..., 1] - e1[..., 1] * e2[..., 0]
            bad = np.flatnonzero((turn <= 0).any(axis=1))
            if len(bad):
                return (f"{src}: body[{ib}].mesh: method fem-q4md needs convex "
                        f"quadrilaterals; {len(bad)} of {body.spec.mesh.file!r} are not, "
                        f"first is quad {bad[0]}")
        if body.spec.body_force is not None:
            return (f"{src}: body[{ib}].body_force: body forces are not supported by "
                    f"method {method!r} (use method = \"fv\")")
        for j, bc in enumerate(body.boundary):
            if bc.traction is not None:
                return (f"{src}: body[{ib}].boundary[{j}]: traction boundaries are not "
                        f"supported by method {method!r} (use method = \"fv\")")
            if bc.amplitude is not None or any(isinstance(c, str)
                                               for c in bc.velocity.components(2)):
                return (f"{src}: body[{ib}].boundary[{j}].velocity: velocities that change "
                        f"in time or space are not supported by method {method!r} (use "
                        "method = \"fv\")")
    names = [b.name for b in case.bodies]
    used = {}
    for k, spec in enumerate(case.contacts):
        if spec.wall is not None:
            return (f"{src}: contact[{k}].wall: rigid-wall contact is not supported by "
                    f"method {method!r} (use method = \"fv\")")
        if spec.model != "slip":
            return (f"{src}: contact[{k}].model: the FE contact is frictionless; method "
                    f"{method!r} needs model = \"slip\"")
        if spec.self_contact:
            return (f"{src}: contact[{k}].self: self-contact is not supported by method "
                    f"{method!r} (use method = \"fv\")")
        for name in spec.bodies:
            i = names.index(name)
            try:
                edges = _contact_surface(case, case.bodies[i].mesh, k, name)
            except InputError as exc:
                return str(exc)
            if i in used and not np.array_equal(used[i], edges):
                return (f"{src}: contact[{k}]: body {name!r} is in several contacts with "
                        f"different surfaces; method {method!r} takes one contact surface "
                        "per body")
            used[i] = edges
    return None


# --------------------------------------------------------------------------- stepper

class FEStepper:
    """The explicit FE baselines as a stepper of the run pipeline."""

    stages_per_step = 1  # one internal-force evaluation per step

    def __init__(self, bodies, contacts, method, cfl=0.5, plot_triangles=None):
        bodies = list(bodies)
        contacts = list(contacts)
        if not bodies:
            raise ValueError("no bodies")
        for b in bodies:
            _check_method(method, b.cells)
        self.method = method
        self.cfl = cfl
        self.bodies = bodies
        self.body_names = [b.name for b in bodies]
        self.node_off = np.cumsum([0] + [len(b.points) for b in bodies])
        self.cell_off = np.cumsum([0] + [len(b.cells) for b in bodies])
        nn = int(self.node_off[-1])
        self.X = np.concatenate([np.asarray(b.points, dtype=np.float64) for b in bodies])
        self.cells = np.concatenate([np.asarray(b.cells, dtype=np.int64) + self.node_off[i]
                                     for i, b in enumerate(bodies)])
        self.plot_triangles = plot_triangles or [
            quads_to_triangles(b.cells) if np.shape(b.cells)[1] == 4
            else np.asarray(b.cells, np.int64) for b in bodies]
        self.mtab = np.array([b.material.table_row() for b in bodies], dtype=np.float64)
        assert self.mtab.shape[1] == N_PROPS
        self.emat = np.concatenate([np.full(len(b.cells), i, dtype=np.int64)
                                    for i, b in enumerate(bodies)])
        grads, wj, area0, self.mass = [], [], [], np.zeros(nn)
        for i, b in enumerate(bodies):
            g, w, a, m = reference_geometry(b.points, b.cells, b.material.density)
            grads.append(g)
            wj.append(w)
            area0.append(a)
            self.mass[self.node_off[i]:self.node_off[i + 1]] = m
        self.grads = np.ascontiguousarray(np.concatenate(grads))
        self.wj = np.ascontiguousarray(np.concatenate(wj))
        self.area0 = np.concatenate(area0)
        if np.any(self.mass <= 0.0):
            raise ValueError("node without mass (not attached to any cell)")

        def per_node(arr, default, dtype):
            if arr is None:
                return np.full((len(default), 2), 0, dtype=dtype)
            a = np.asarray(arr, dtype=dtype)
            if a.shape != (len(default), 2):
                raise ValueError(f"per-node array has shape {a.shape}, expected "
                                 f"{(len(default), 2)}")
            return a

        v = np.concatenate([per_node(b.velocity, b.points, np.float64) for b in bodies])
        self.fmask = np.concatenate([per_node(b.fixed_mask, b.points, np.bool_)
                                     for b in bodies])
        fval = np.concatenate([per_node(b.fixed_value, b.points, np.float64) for b in bodies])
        self.fval = np.where(self.fmask, fval, 0.0)
        self.v = np.where(self.fmask, self.fval, v)
        self.minv = np.where(self.fmask, 0.0, 1.0 / self.mass[:, None])
        self.x = self.X.copy()
        self._contact_passes(contacts)
        # initial state
        self.f = np.zeros((nn, 2))
        self.acc = np.zeros((nn, 2))
        self.strain, self.dtlim, self.jmin = internal_forces(
            self.x, self.cells, self.grads, self.wj, self.area0, self.emat, self.mtab, self.f)
        self.acc[:] = -self.f * self.minv
        self.kinetic = float(0.5 * np.sum(self.mass * np.sum(self.v ** 2, axis=1)))
        self.momentum = self.mass @ self.v
        self.contact_energy = 0.0
        # the compiled step's bundles, of the very arrays above (it writes x, v, acc, f)
        self._state = State(self.x, self.v, self.acc, self.f)
        self._nodes = NodeData(self.mass, self.minv, self.fmask, self.fval)
        self._elements = Elements(self.cells, self.grads, self.wj, self.area0, self.emat,
                                  self.mtab)

    def _contact_passes(self, contacts):
        """Two passes per contact (nodes of a against segments of b and vice versa)."""
        X, off = self.X, self.node_off
        sl_ptr, sl_nodes, sg_ptr, sg, se_ptr, se, pc, pa, pdep = \
            [0], [], [0], [], [0], [], [], [], []
        for k, c in enumerate(contacts):
            if not (0 <= c.body_a < len(self.bodies) and 0 <= c.body_b < len(self.bodies)):
                raise ValueError(f"contact {k} refers to a missing body")
            ea, eb = (np.asarray(self.bodies[i].contact_edges
                                 if self.bodies[i].contact_edges is not None
                                 else np.empty((0, 2)), dtype=np.int64).reshape(-1, 2) + off[i]
                      for i in (c.body_a, c.body_b))
            lens = [np.linalg.norm(X[e[:, 1]] - X[e[:, 0]], axis=1) for e in (ea, eb) if len(e)]
            depth = 0.5 * min(float(length.min()) for length in lens) if lens else 0.0
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
        self.n_contacts = len(contacts)
        nn = len(X)
        self.passes = ContactPasses(
            np.array(sl_ptr, dtype=np.int64),
            np.concatenate(sl_nodes).astype(np.int64) if sl_nodes else np.zeros(0, np.int64),
            np.array(sg_ptr, dtype=np.int64),
            np.concatenate(sg).astype(np.int64) if sg else np.zeros((0, 2), np.int64),
            np.array(se_ptr, dtype=np.int64),
            np.concatenate(se).astype(np.int64) if se else np.zeros((0, 2), np.int64),
            np.array(pc, dtype=np.int64), np.array(pa, dtype=np.bool_),
            np.array(pdep, dtype=np.float64))
        ncap = max(len(self.passes.slave_nodes), 1)
        self.work = ContactWork(np.zeros((nn, 2)), np.zeros((nn, 2)),
                                np.empty((ncap, 3), np.int64), np.empty(ncap),
                                np.empty((ncap, 2)), np.empty(ncap, np.int64))
        self.cforce = np.zeros((max(self.n_contacts, 1), 2))
        self.cgap = np.full(max(self.n_contacts, 1), np.nan)
        self.tol = CONTACT_TOL_REL * (float(self.passes.depth.min()) if len(pdep) else 1.0)

    @classmethod
    def from_case(cls, case):
        """The FE problem of a validated case with ``run.method`` "fem-t3" or "fem-q4md"."""
        method = case.run.method
        problem = unsupported(case, method)
        if problem:
            raise InputError(problem)
        names = [b.name for b in case.bodies]
        bodies, meshes = [], []
        for ib, body in enumerate(case.bodies):
            mesh = case_mesh(body, method)
            mask = np.zeros(mesh.points.shape, bool)
            value = np.zeros(mesh.points.shape)
            for j, bc in enumerate(body.boundary):
                nodes = np.unique(mesh.regions[bc.region])
                for c, comp in enumerate(bc.velocity.components(2)):
                    if comp is not None:
                        mask[nodes, c] = True
                        value[nodes, c] = comp
            bodies.append(FemBody(body.name, np.asarray(mesh.points, float),
                                  np.asarray(mesh.cells, np.int64), body.material,
                                  body.initial_velocity(mesh.points), mask, value, None))
            meshes.append(mesh)
        contacts = []
        for k, spec in enumerate(case.contacts):
            ia, ib_ = (names.index(n) for n in spec.bodies)
            for i in (ia, ib_):
                bodies[i].contact_edges = _contact_surface(case, meshes[i], k, names[i])
            contacts.append(FemContact(ia, ib_))
        return cls(bodies, contacts, method, cfl=case.run.cfl)

    # ------------------------------------------------------------------ one step
    def stable_dt(self) -> float:
        return self.cfl * self.dtlim

    def step(self, dt: float, with_monitors: bool = True):
        """One step of size dt (``with_monitors``, whether a history row follows, is
        accepted for the time loop's sake: the step computes its monitors anyway)."""
        (self.strain, self.kinetic, px, py, dke, self.dtlim, self.jmin, _) = verlet_step(
            self._state, self._nodes, self._elements, self.passes, self.work, self.cforce,
            self.cgap, dt, CONTACT_MAX_ITER, self.tol)
        self.momentum = np.array([px, py])
        self.contact_energy -= dke

    def check(self, step: int, t: float):
        if not np.isfinite(self.dtlim) or self.jmin <= 0.0:
            raise SimulationError(
                f"{self.method}: element inverted or degenerate at step {step}, time "
                f"{t:.6e} s (min J = {self.jmin:.3g}); try a smaller cfl or a finer mesh",
                step=step, time=t)

    # ------------------------------------------------------------------ monitors and fields
    def history_columns(self) -> list[str]:
        return (["kinetic_energy", "strain_energy", "total_energy", "momentum_x",
                 "momentum_y", "contact_energy"]
                + [f"contact{k}_{c}" for k in range(self.n_contacts)
                   for c in ("fx", "fy", "gap")])

    def history_row(self) -> list[float]:
        total = self.kinetic + self.strain + self.contact_energy
        row = [self.kinetic, self.strain, total, *self.momentum, self.contact_energy]
        for k in range(self.n_contacts):
            row += [self.cforce[k, 0], self.cforce[k, 1], self.cgap[k]]
        return row

    def _stresses(self):
        pe = np.empty(len(self.cells))
        vme = np.empty(len(self.cells))
        element_pressure_von_mises(self.x, self.cells, self.grads, self.wj, self.area0,
                                   self.emat, self.mtab, pe, vme)
        pressure, von_mises = np.empty(len(self.x)), np.empty(len(self.x))
        for i, b in enumerate(self.bodies):
            n0, n1 = self.node_off[i], self.node_off[i + 1]
            c0, c1 = self.cell_off[i], self.cell_off[i + 1]
            cells = np.asarray(b.cells, dtype=np.int64)
            pressure[n0:n1] = nodal_average(cells, self.area0[c0:c1], pe[c0:c1], n1 - n0)
            von_mises[n0:n1] = nodal_average(cells, self.area0[c0:c1], vme[c0:c1], n1 - n0)
        return pressure, von_mises

    def _stress_and_J(self):
        """Nodal (reference-area-weighted) averages of the element Cauchy stress, as 3 x 3
        with the plane-strain sigma_zz, and of the element J."""
        m = len(self.cells)
        se, je = np.empty((m, 4)), np.empty(m)
        element_stress_and_J(self.x, self.cells, self.grads, self.wj, self.area0, self.emat,
                             self.mtab, se, je)
        n = len(self.x)
        stress, jac = np.zeros((n, 3, 3)), np.empty(n)
        where = ((0, 0), (1, 1), (0, 1), (2, 2))
        for i, b in enumerate(self.bodies):
            n0, n1 = self.node_off[i], self.node_off[i + 1]
            c0, c1 = self.cell_off[i], self.cell_off[i + 1]
            cells = np.asarray(b.cells, dtype=np.int64)
            a0 = self.area0[c0:c1]
            for c, (r, k) in enumerate(where):
                stress[n0:n1, r, k] = nodal_average(cells, a0, se[c0:c1, c].copy(), n1 - n0)
            jac[n0:n1] = nodal_average(cells, a0, je[c0:c1], n1 - n0)
        stress[:, 1, 0] = stress[:, 0, 1]
        return stress, jac

    def snapshot(self):
        """(reference points, cells, point data) for a ParaView frame; element values are
        averaged to the nodes."""
        pressure, von_mises = self._stresses()
        stress, jac = self._stress_and_J()
        body = np.repeat(np.arange(len(self.bodies)), np.diff(self.node_off)).astype(np.int32)
        return self.X, self.cells, {"velocity": self.v, "displacement": self.x - self.X,
                                    "pressure": pressure, "von_mises": von_mises,
                                    "stress": stress, "J": jac, "body": body}

    def body_fields(self) -> dict:
        """Per body: reference_points, points, cells, triangles (for plotting; quads split in
        two), velocity, displacement, pressure and von_mises (reference-area-weighted nodal
        averages of the element values)."""
        pressure, von_mises = self._stresses()
        out = {}
        for i, b in enumerate(self.bodies):
            s = slice(self.node_off[i], self.node_off[i + 1])
            out[b.name] = {
                "reference_points": self.X[s].copy(), "points": self.x[s].copy(),
                "cells": np.asarray(b.cells, np.int64).copy(),
                "triangles": np.asarray(self.plot_triangles[i], np.int64),
                "velocity": self.v[s].copy(), "displacement": self.x[s] - self.X[s],
                "pressure": pressure[s].copy(), "von_mises": von_mises[s].copy()}
        return out

    def summary(self) -> dict:
        return {"nodes": int(len(self.X)),
                "edges": int(sum(len(unique_edges(b.cells)) for b in self.bodies)),
                "cells": int(len(self.cells))}

    # ------------------------------------------------------------------ checkpoints
    def state_arrays(self) -> dict:
        return {"x": self.x, "v": self.v, "acc": self.acc, "cforce": self.cforce,
                "cgap": self.cgap,
                "scalars": np.array([self.strain, self.kinetic, self.dtlim, self.jmin,
                                     self.contact_energy, *self.momentum])}

    def restore(self, arrays) -> None:
        for name in ("x", "v", "acc", "cforce", "cgap"):
            target = getattr(self, name)
            if arrays[name].shape != target.shape:
                raise ValueError(f"{name} has shape {arrays[name].shape}, the case gives "
                                 f"{target.shape}")
            target[:] = arrays[name]
        (self.strain, self.kinetic, self.dtlim, self.jmin, self.contact_energy,
         *momentum) = map(float, arrays["scalars"])
        self.momentum = np.array(momentum)
