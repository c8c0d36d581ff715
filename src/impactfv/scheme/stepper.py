"""The finite-volume stepper: state and work arrays of one FV run, and one time step.

It plugs into the run pipeline (impactfv.pipeline) like the FE steppers do: the pipeline
owns the time loop, the output and checkpoint schedule and the files; the stepper owns the
physics of a step. Data flows one way: case -> Discretisation -> state -> loops (backends).
"""

from __future__ import annotations

import numpy as np

from ..compiled import dim_tag, superword_vectorization, variant
from ..case import Case
from ..errors import InputError, SimulationError
from ..backends import cpu as K
from ..backends.loops import UNKNOWN, CPULoops, StateValues
from ..contact.driver import ContactStage
from .discretisation import Discretisation, discretise
from .angular_momentum import AngularMomentumProjection
from .energy import EnergyBook
from .outputs import FVOutputs
from ..physics.limiters import IDS as LIMITER_IDS
from .loads import Loads
from ..physics.runge_kutta import STAGES


def relaxation_weights(m, beta):
    """The edge weights w_ab = w_ba of the compatibility relaxation, per slot of
    m.node_neighbour: the relaxation rate 1 / tau = c_p / (beta h) (the mean of the two
    nodes') times the edge's share of the dual volumes, C_ab . (X_b - X_a) / (2 d). The
    shares are positive on a median dual and sum to Omega_a over a node's edges (the
    Green-Gauss gradient of X is exact; a boundary face's C is normal to X_face - X_a), so
    sum_b w_ab = Omega_a / tau_a on a uniform mesh."""
    cp = m.material_table[m.node_material, K.CP]
    inverse_time = cp / (beta * m.node_length)
    counts = np.diff(m.node_edge_start)
    a = np.repeat(np.arange(len(counts)), counts)
    b = m.node_neighbour
    share = np.einsum("kj,kj->k", m.node_C, m.X[b] - m.X[a]) / (2 * m.dim)
    return np.ascontiguousarray(0.5 * (inverse_time[a] + inverse_time[b]) * share)


class FVStepper(FVOutputs):
    """Upwind vertex-centred finite volumes (p-F), two-stage TVD Runge-Kutta."""

    method = "fv"
    stages_per_step = 2

    def __init__(self, case: Case, disc: Discretisation | None = None):
        self.case = case
        self.disc = m = disc if disc is not None else discretise(case)
        # nodes 0 .. n_owned - 1 are this process's; under MPI (impactfv.parallel) the rest
        # are ghosts whose state comes from their owners
        self.n_owned = getattr(self, "n_owned", m.n_nodes)
        self.dim = dim_tag(m.dim)
        self.cfl = case.run.cfl
        self._scheme_options(case.run, m.dim)
        self._mesh_bundles(m)
        self._relaxation(case.run, m)
        self.loads = Loads(case, m)
        self.time = 0.0
        self.dt = 0.0
        self._state_and_work_arrays(m)
        #: what the last stage computed of the current state
        self.known = UNKNOWN
        self.mass = m.material_table[m.node_material, 0] * m.volume
        # the energy balance and the supports' reactions (scheme.energy)
        self.energy = EnergyBook(case, m, self.n_owned, self.mass, self._sum)
        # [run] angular_momentum = "projected": the interior fluxes' torque removed from
        # every free body (scheme.angular_momentum)
        self.angular_projection = None
        if case.run.angular_momentum == "projected":
            projection = AngularMomentumProjection(self)
            self.angular_projection = projection if projection.active else None
        # the contact's stage result when there is no contact (or between contacts' stages)
        self.no_contact = ContactStage.none(m.n_nodes, len(m.bface_node), m.dim)
        self.contact = None
        if case.contacts:
            self.contact = self._make_contact(case, m)
            self.contact.end_step(self.x, self.v, self.F, 0.0)  # initial gaps
        # the loops of the stage sequence: numba on the CPU (backends.loops) or CUDA
        # (backends.cuda), which keeps the state on the device and copies it back into v, F,
        # x only for outputs
        if case.run.backend == "cuda":
            from ..backends import cuda
            why = cuda.problem(case)
            if why:
                raise InputError(f"{case.source}: {why}")
            self.loops = cuda.CUDALoops(self)
        else:
            self.loops = CPULoops(self)

    def _scheme_options(self, run, d):
        self.order = run.order
        self.limiter = LIMITER_IDS[run.limiter]
        self.upwind_geometric = run.geometric_flux == "upwind"
        # the upwind geometric flux needs the reconstructed tractions to be second order
        self.stress_reconstructed = self.order == 2 and self.upwind_geometric
        # normal-only keeps compressed free surfaces from folding in 2D; in 3D the tangential
        # part is needed to damp the free faces' tangential modes (docs/theory.md)
        correction = run.boundary_correction or ("normal" if d == 2 else "full")
        self.tangential_correction = 1.0 if correction == "full" else 0.0
        # the edge flux's options (scheme.bodies.edge_flux): the variant is compiled in
        # (compiled.variant); the U-MUSCL blend and the smoothness switch's chi are values
        self.flux_options = (variant(self.order == 2), variant(self.stress_reconstructed),
                             variant(self.upwind_geometric), float(run.muscl_chi),
                             float(run.smooth_switch))

    def _mesh_bundles(self, m):
        """The discretisation's arrays as the loops take them."""
        self.dual = (m.node_edge_start, m.node_neighbour, m.node_C, m.node_half,
                     m.bface_start, m.bface_others, m.bface_C, m.volume)
        self.edge_mesh = (m.edges, m.C, m.C_len, m.half, m.edge_offsets)
        self.face_mesh = (m.bface_node, m.bface_others, m.bface_C, m.bface_bc, m.closure)

    def _relaxation(self, run, m):
        """The grid-scale part of F's mismatch with the gradient of the positions relaxed at
        the rate 1 / tau_a, tau_a = compatibility_time h_a / c_p,a (docs/theory.md,
        "Compatibility relaxation")."""
        beta = float(run.compatibility_time)
        self.relaxation_weight = None
        # F - G(x), written by the gradient pass (empty without the relaxation)
        self.mismatch = np.zeros((0, m.dim, m.dim))
        if beta > 0.0:
            self.relaxation_weight = relaxation_weights(m, beta)
            self.mismatch = np.zeros((m.n_nodes, m.dim, m.dim))
        self.positions_gradient = None    # scratch of a positions-only gradient pass

    def _state_and_work_arrays(self, m):
        """The state (v, F, x) at rest in the reference configuration (the initial velocity
        and the prescribed velocities of the case), and the work arrays, allocated once."""
        n, d = m.n_nodes, m.dim
        self.v = m.v0.copy()
        self.v[m.fixed_mask] = self.loads.fixed_value[m.fixed_mask]
        self.F = np.zeros((n, d, d))
        for i in range(d):
            self.F[:, i, i] = 1.0
        self.x = m.X.copy()
        self.v0, self.F0, self.x0 = (np.empty_like(a) for a in (self.v, self.F, self.x))
        self.sigma = np.empty((n, d, d))  # Cauchy stress
        ncomp = d + d * (d + 1) // 2 if self.stress_reconstructed else d
        self.components = dim_tag(ncomp)
        self.U = np.empty((n, ncomp)) if self.stress_reconstructed else self.v
        self.grad = np.zeros((n, ncomp, d + 1))
        self.force = np.empty((n, d))
        self.dF = np.empty((n, d, d))
        self.monitor_buf = np.zeros((len(m.bodies), 2 + d))
        # 3D: each node's lower bound of h lambda_min / c_p (backends.cpu.rk_update_last)
        self.stretch_bound = np.empty(n if d == 3 else 0)
        # the boundary power of a stage and the force of each boundary condition's faces
        # (the flux loops' outputs)
        self.power = np.zeros(1)
        self.bc_force = np.zeros((len(m.bc_fixed), d))

    def _make_contact(self, case, m):
        from ..contact.driver import ContactSystem
        return ContactSystem(case, m)

    # what a serial run does where a run over MPI ranks (parallel.stepper) communicates
    def _sum(self, values):
        return values

    def _min(self, value):
        return value

    def _begin_state_exchange(self, stress_carried=False):
        pass

    def _end_state_exchange(self):
        pass

    def _first_bad(self, bad):
        return bad

    def _exchange_gradients(self):
        pass

    @property
    def body_names(self) -> list[str]:
        return [b.name for b in self.disc.bodies]

    # ------------------------------------------------------------------ one step
    def rates(self, stage=0, stress_carried=False):
        """Momentum and deformation-gradient rates (force, dF = Omega dF/dt) of the current
        state, at the stage's time (the loads are brought to it by the caller). Returns this
        rank's power of the boundary tractions and body forces, the reactions of the stage
        (or None), which EnergyBook.close_stage completes with what the update returns, and
        the stage's contact (contact.driver.ContactStage; no_contact without contacts), which
        the update reads.
        ``stress_carried``: the owned nodes' sigma (and U) are those of the current state
        already (written by the last stage of the step that made it)."""
        m, loops = self.disc, self.loops
        # under MPI the owned nodes' stresses are computed while their ghosts' states arrive
        o = self.n_owned
        if not stress_carried:
            loops.stresses(slice(0, o))
        self._end_state_exchange()
        if o < m.n_nodes:
            if not stress_carried:
                loops.stresses(slice(o, None))
            elif self.stress_reconstructed:
                # the ghosts' carried stress came with their state (ParallelStepper)
                loops.pack(slice(o, None))
        relaxed = self.relaxation_weight is not None
        if self.order == 2:
            # the positions' mismatch of the compatibility relaxation in the same pass (the
            # contact stage and the flux assembly do not move the positions)
            loops.gradient(relaxed)
            self._exchange_gradients()
        contact = self.no_contact
        if self.contact is not None:
            contact = loops.contact_stage(stage, self.time + (self.dt if stage else 0.0))
        power, bc_force = loops.fluxes(contact)
        if self.angular_projection is not None:
            # before the contact and body forces, which keep their torque
            loops.project_angular_momentum(self.angular_projection, stage == len(STAGES) - 1,
                                           contact)
        if self.contact is not None:
            loops.contact_apply()
        if relaxed:
            self._relax_towards_positions(gradient_done=self.order == 2)
        if self.loads.has_body_force:
            power += loops.body_force()
        reactions = None
        if self.energy.reaction_rows:
            reactions = self.energy.stage_reactions(bc_force, loops.held_forces())
        return power, reactions, contact

    def _relax_towards_positions(self, gradient_done=False):
        """Omega_a dF_a/dt -= sum over a's edge neighbours b of w_ab (D_a - D_b),
        D = F - G(x) (scheme.bodies.relaxation_change). ``gradient_done``: the gradient pass
        of the fields wrote D already (order 2)."""
        if not gradient_done:
            self.loops.positions_mismatch()
        # the owned nodes' differences read their ghost neighbours' mismatch (MPI)
        self._exchange_mismatch()
        self.loops.relax()

    def _exchange_mismatch(self):
        pass

    def stable_dt(self) -> float:
        """cfl x min over nodes of h lambda_min / c_p: computed by the last stage of the step
        that made the current state, or here (first step, after a restore)."""
        if self.known.next_dt is not None:
            return self.known.next_dt
        self._host()
        m = self.disc
        o = self.n_owned
        if m.dim == 3:
            # every node a candidate of the kernel the last stage's candidates go through:
            # the same compiled arithmetic, so that a continued run takes the time step of
            # the uninterrupted one (min_stretch compiled into another kernel can differ at
            # strongly compressed nodes, by up to 1e-7 relative)
            return self.cfl * self._min(K.smallest_time_step_of_candidates(
                self.F[:o], m.node_material[:o], m.material_table, m.node_length[:o],
                np.zeros(o), np.inf, self.dim))
        return self.cfl * self._min(K.stable_time_step(
            self.F[:o], m.node_material[:o], m.material_table, m.node_length[:o], self.dim))

    def state_changed(self):
        """Code outside the stepper wrote v, F or x (on the host): what the last stage
        computed of the state no longer holds, and the loops take the new state."""
        self.known = UNKNOWN
        self.loops.from_host()

    def _wall_power(self, stage):
        return 0.0 if self.contact is None else self.contact.wall_power(stage)

    def _host(self):
        """Bring the host copies of v, F, x up to date (the CUDA backend keeps the state on
        the device; on the CPU they are the state)."""
        self.loops.to_host()

    def step(self, dt: float, with_monitors: bool = True):
        """Advance the state by dt. ``with_monitors``: a history row follows, whose monitors
        the last stage computes in its pass over the nodes."""
        with superword_vectorization(self.disc.dim == 3):
            self._step(dt, with_monitors)

    def _step(self, dt: float, with_monitors: bool):
        loads, loops = self.loads, self.loops
        # the last stage of the previous step left the stress of this state (unless a
        # restore or state_changed came since)
        carried = self.known.stress
        self.known = UNKNOWN
        # the start of the step (v0, F0, x0) is saved by the first stage's update
        self.dt = dt
        t = self.time
        energy = self.energy
        held_momentum = energy.held_momentum(loads) if energy.reaction_rows else None
        held_start = None
        last = len(STAGES) - 1
        for stage, alpha in enumerate(STAGES):
            loads.at(t + (dt if stage else 0.0))
            loops.loads_changed()
            if stage == 0 and energy.has_supports:
                held_start = loads.fixed_value[energy.held]   # the held velocities at t
            power, reactions, contact = self.rates(stage, carried and stage == 0)
            # both stages end at t + dt (Heun), where the prescribed velocities are imposed
            loads.at(t + dt)
            loops.loads_changed()
            # the last stage also gives the next time step, the state check and (when a
            # history row follows) the monitors, in the same pass over the nodes
            result = loops.update(alpha, dt, stage, stage == last, bool(with_monitors),
                                  contact)
            self._begin_state_exchange(result.stress)
            energy.close_stage(stage, (power, reactions), result, self._wall_power)
        self.known = StateValues(self.cfl * self._min(result.smallest),
                                 self._first_bad(result.bad), result.monitors, result.stress)
        self.time = t + dt
        energy.close_step(dt, loads, held_start, held_momentum)
        if self.contact is not None:
            loops.contact_end_step(self.time)
        self._end_state_exchange()

    def check(self, step: int, t: float):
        """Raise SimulationError naming the first node with a non-finite state or J <= 0."""
        bad = self.known.bad
        if bad is None:
            self._host()
            bad = K.state_is_bad(self.v, self.F, self.dim)
        if bad < 0:
            return
        self._host()
        m = self.disc
        body = m.bodies[m.body_of_node[bad]]
        with np.errstate(invalid="ignore"):
            J = float(np.linalg.det(self.F[bad]))
        what = "non-finite state" if not np.isfinite(J) or not np.all(
            np.isfinite(self.v[bad])) else f"collapsed control volume (J = {J:.3g})"
        raise SimulationError(
            f"{what} at step {step}, time {t:.6e} s, body {body.name!r}, node "
            f"{bad - body.start} (reference position {m.X[bad].tolist()}); try a smaller "
            "cfl or a finer mesh", step=step, time=t, body=body.name, node=bad - body.start)
