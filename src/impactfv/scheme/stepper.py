"""The finite-volume stepper: state and work arrays of one FV run, and one time step.

It plugs into the run pipeline (impactfv.pipeline) like the FE steppers do: the pipeline
owns the time loop, the output and checkpoint schedule and the files; the stepper owns the
physics of a step. Data flows one way: case -> Discretisation -> state -> kernels.
"""

from __future__ import annotations

import numpy as np

from ..compiled import dim_tag, superword_vectorization
from ..case import Case
from ..errors import InputError, SimulationError
from ..backends import cpu as K
from .discretisation import Discretisation, discretise
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


class FVStepper:
    """Upwind vertex-centred finite volumes (p-F), two-stage TVD Runge-Kutta."""

    method = "fv"
    stages_per_step = 2

    def __init__(self, case: Case, disc: Discretisation | None = None):
        self.case = case
        self.disc = m = disc if disc is not None else discretise(case)
        n, d = m.n_nodes, m.dim
        # nodes 0 .. n_owned - 1 are this process's; under MPI (impactfv.parallel) the rest
        # are ghosts whose state comes from their owners
        self.n_owned = getattr(self, "n_owned", n)
        self.dim = dim_tag(d)
        self.order = case.run.order
        self.limiter = LIMITER_IDS[case.run.limiter]
        self.cfl = case.run.cfl
        self.upwind_geometric = case.run.geometric_flux == "upwind"
        # U-MUSCL blend of the reconstruction (kernels._flux_edge)
        self.bias = float(case.run.muscl_chi)
        self.switch = float(case.run.smooth_switch)
        # normal-only keeps compressed free surfaces from folding in 2D; in 3D the tangential
        # part is needed to damp the free faces' tangential modes (docs/theory.md)
        correction = case.run.boundary_correction or ("normal" if d == 2 else "full")
        self.tangential_correction = 1.0 if correction == "full" else 0.0
        # the upwind geometric flux needs the reconstructed tractions to be second order
        self.stress_reconstructed = self.order == 2 and self.upwind_geometric
        # the edge flux's options (scheme.bodies.edge_flux)
        self.flux_options = (self.order == 2, self.stress_reconstructed, self.upwind_geometric,
                             self.bias, self.switch)
        # the discretisation's arrays as the loops take them
        self._dual = (m.node_edge_start, m.node_neighbour, m.node_C, m.node_half,
                      m.bface_start, m.bface_others, m.bface_C, m.volume)
        self._edge_mesh = (m.edges, m.C, m.C_len, m.half, m.edge_offsets)
        self._face_mesh = (m.bface_node, m.bface_others, m.bface_C, m.bface_bc, m.closure)
        # the grid-scale part of F's mismatch with the gradient of the positions relaxed at
        # the rate 1 / tau_a, tau_a = compatibility_time h_a / c_p,a (docs/theory.md,
        # "Compatibility relaxation")
        beta = float(case.run.compatibility_time)
        self.relaxation_weight = None
        # F - G(x), written by the gradient pass (empty without the relaxation)
        self.mismatch = np.zeros((0, d, d))
        if beta > 0.0:
            self.relaxation_weight = relaxation_weights(m, beta)
            self.mismatch = np.zeros((n, d, d))
        self._positions_gradient = None    # scratch of a positions-only gradient pass
        self.loads = Loads(case, m)
        self.time = 0.0
        # state
        self.v = m.v0.copy()
        self.v[m.fixed_mask] = self.loads.fixed_value[m.fixed_mask]
        self.F = np.zeros((n, d, d))
        for i in range(d):
            self.F[:, i, i] = 1.0
        self.x = m.X.copy()
        # work arrays, allocated once
        self.v0, self.F0, self.x0 = (np.empty_like(a) for a in (self.v, self.F, self.x))
        self.sigma = np.empty((n, d, d))  # Cauchy stress
        ncomp = d + d * (d + 1) // 2 if self.stress_reconstructed else d
        self.components = dim_tag(ncomp)
        self.U = np.empty((n, ncomp)) if self.stress_reconstructed else self.v
        self.grad = np.zeros((n, ncomp, d + 1))
        self.force = np.empty((n, d))
        self.dF = np.empty((n, d, d))
        self.monitor_buf = np.zeros((len(m.bodies), 2 + d))
        # 3D: each node's lower bound of h lambda_min / c_p (kernels.rk_update_last)
        self.stretch_bound = np.empty(n if d == 3 else 0)
        # what the last stage computed of the new state (rk_update_last): the next stable
        # time step, the first bad node, the monitors; None / False when not computed for
        # the current state
        self._next_dt = None
        self._bad = None
        self._monitors_fresh = False
        # sigma (and U) of the owned nodes are those of the current state: the next step's
        # first stage need not compute them (code that writes v, F or x outside the stepper's
        # own methods calls _forget_state_values)
        self._stress_carried = False
        #: set by the time loop before a step: whether a history row follows it (the
        #: monitors are then computed in the last stage's pass; otherwise on demand)
        self.history_due = True
        self.mass = m.material_table[m.node_material, 0] * m.volume
        self.dt = 0.0
        # energy bookkeeping: the power of the boundary tractions and body forces per stage
        self.power = np.zeros(1)
        self.stage_power = np.zeros(2)
        self.external_work = 0.0
        # what the semi-discrete scheme removes per stage (power in minus the rate of the
        # energy the rates give), and its Runge-Kutta integral
        self.stage_dissipation = np.zeros(2)
        self.dissipated = 0.0
        # the energy the two-stage Runge-Kutta step adds beyond the Runge-Kutta mean of the
        # stage rates (scheme.time.heun_energy_excess), per step and since t = 0
        self.stage_integration = 0.0
        self.integration = 0.0
        # the strongly held velocity components (owned nodes): the support's work there is
        # the kinetic energy it gives them minus the power of the force it cancels
        self.held = np.nonzero(m.fixed_mask[:self.n_owned])      # (nodes, components)
        self.has_supports = bool(m.bc_fixed.any())      # the same on every rank
        self._reactions_setup()
        if case.contacts:
            self.contact = self._make_contact(case, m)
            self.contact_state, self.contact_xdot = self.contact.state, self.contact.xdot
            self.face_contact_weight = self.contact.face_weight
            self.contact.end_step(self.x, self.v, self.F, 0.0)  # initial gaps
        else:
            self.contact = None
            self.contact_state = np.zeros(n, np.int8)
            self.contact_xdot = np.zeros((n, d))
            self.face_contact_weight = np.zeros(len(m.bface_node))
        # the loops: numba on the CPU (scheme.kernels) or CUDA (backends.cuda), which keeps
        # the state on the device and copies it back into v, F, x only for outputs
        self.device = None
        self._host_stale = False
        if case.run.backend == "cuda":
            from ..backends import cuda
            why = cuda.problem(case)
            if why:
                raise InputError(f"{case.source}: {why}")
            self.device = cuda.DeviceState(self)

    def _make_contact(self, case, m):
        from ..contact.driver import ContactSystem
        return ContactSystem(case, m)

    # what a serial run does where a run over MPI ranks (parallel.stepper) communicates
    def _sum(self, values):
        return values

    def _min(self, value):
        return value

    def _begin_state_exchange(self):
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

    def _reactions_setup(self):
        """Each boundary entry with a prescribed velocity reports the force its support
        exerts on the body (history columns reaction_<region>_f<c>, with several bodies
        reaction_<body>_<region>_f<c>)."""
        import scipy.sparse as sp

        m = self.disc
        rows, names = [], []
        several = len(self.case.bodies) > 1
        for ib, body in enumerate(self.case.bodies):
            for spec in body.boundary:
                rows.append(spec)
                names.append(f"{body.name}_{spec.region}" if several else spec.region)
        self.reaction_rows = [k for k, spec in enumerate(rows, start=1)
                              if m.bc_fixed[k].any()]
        seen = {}
        self.reaction_names = []
        owned = self.n_owned
        for k in self.reaction_rows:
            base = names[k - 1]
            seen[base] = seen.get(base, 0) + 1
            self.reaction_names.append(base if seen[base] == 1 else f"{base}{seen[base]}")
        d = m.dim
        if self.reaction_rows:
            cols = [m.bc_nodes[k][m.bc_nodes[k] < owned] for k in self.reaction_rows]
            self.reaction_sum = sp.csr_matrix(
                (np.ones(sum(map(len, cols))),
                 (np.repeat(np.arange(len(cols)), list(map(len, cols))), np.concatenate(cols))),
                shape=(len(cols), owned))
            self.reaction_mask = np.array([m.bc_fixed[k] for k in self.reaction_rows], float)
        self.stage_reaction = np.zeros((2, len(self.reaction_rows), d))
        self.bc_force = np.zeros((len(m.bc_fixed), d))
        self.reaction = np.zeros((len(self.reaction_rows), d))

    # ------------------------------------------------------------------ one step
    def rates(self, stage=0, stress_carried=False):
        """Momentum and deformation-gradient rates (force, dF = Omega dF/dt) of the current
        state, at the stage's time (the loads are brought to it by the caller), and this
        rank's boundary power and reactions of the stage, which _close_stage completes with
        the energy rate of the Runge-Kutta update. ``stress_carried``: the owned nodes'
        sigma (and U) are those of the current state already (written by the last stage of
        the step that made it, kernels.rk_update_last)."""
        m = self.disc
        # under MPI the owned nodes' stresses are computed while their ghosts' states arrive
        o = self.n_owned
        if not stress_carried:
            self._stresses(slice(0, o))
        self._end_state_exchange()
        if o < m.n_nodes:
            if not stress_carried:
                self._stresses(slice(o, None))
            elif self.stress_reconstructed:
                # the ghosts' carried stress came with their state (ParallelStepper)
                K.pack_velocity_and_stress(self.v[o:], self.sigma[o:], self.U[o:], self.dim)
        relaxed = self.relaxation_weight is not None
        if self.order == 2:
            # the positions' gradient of the compatibility relaxation in the same pass (the
            # contact stage and the flux assembly do not move the positions)
            K.limited_gradient(self.U, self._dual, m.closure, self.limiter, self.grad,
                               self.components, self.x, self.F, self.mismatch, relaxed,
                               self.dim)
            self._exchange_gradients()
        loads = self.loads
        stage_time = self.time + (self.dt if stage else 0.0)
        if self.contact is not None:
            self.contact.stage(self.x, self.v, self.F, self.sigma, self.grad, self.order == 2,
                               self.dt, stage, stage_time)
        K.assemble_rates(self.v, self.F, self.sigma, self.grad, m.node_material,
                         m.material_table, self._edge_mesh, self._face_mesh,
                         (m.bc_fixed, loads.face_velocity, loads.face_traction,
                          self.tangential_correction),
                         self.flux_options, self.contact_state, self.face_contact_weight,
                         self.force, self.dF, self.power, self.bc_force, self.dim)
        if self.contact is not None:
            self.contact.apply(self.force, self.dF, loads.fixed_value)
        if relaxed:
            self._relax_towards_positions(gradient_done=self.order == 2)
        power = self.power[0]
        o = self.n_owned
        if loads.has_body_force:
            self.force += self.mass[:, None] * loads.acceleration
            power += float(np.einsum("i,ij,ij->", self.mass[:o], loads.acceleration[:o],
                                     self.v[:o]))
        if self.has_supports:
            # the power of the support's cancelling of the force on held components (the
            # kinetic energy it gives them is added at the end of the step)
            power -= float(np.dot(self.force[self.held], self.v[self.held]))
        # the stage's energy rate is summed by its Runge-Kutta update and reduced with these
        # in _close_stage
        self._stage_sums = [power]
        if self.reaction_rows:
            # the support acts through the Riemann tractions of its faces and, where the
            # prescribed components are imposed on the nodes, by cancelling what is left
            self._stage_sums.append(self.reaction_mask * (self.bc_force[self.reaction_rows]
                                                          - self.reaction_sum @ self.force[:o]))

    def _relax_towards_positions(self, gradient_done=False):
        """Omega_a dF_a/dt -= sum over a's edge neighbours b of w_ab (D_a - D_b),
        D = F - G(x), with G(x) the Green-Gauss gradient of the nodal positions on the
        node's dual (with the boundary closure, so that it is exact for linear motions and a
        uniform state stays uniform) and w_ab = w_ba (relaxation_weights): only the
        grid-scale part of the mismatch is relaxed, and a uniform stress does no work on it.
        ``gradient_done``: the gradient pass of the fields wrote D already (order 2)."""
        m = self.disc
        if not gradient_done:     # order 1: the positions' gradient pass alone
            if self._positions_gradient is None:
                self._positions_gradient = np.zeros((m.n_nodes, m.dim, m.dim + 1))
            K.limited_gradient(self.x, self._dual, m.closure, LIMITER_IDS["none"],
                               self._positions_gradient, self.dim, self.x, self.F,
                               self.mismatch, True, self.dim)
        # the owned nodes' differences read their ghost neighbours' mismatch (MPI)
        self._exchange_mismatch()
        K.relax_towards_positions(self.mismatch, self.relaxation_weight, self.n_owned,
                                  m.node_edge_start, m.node_neighbour, self.dF, self.dim)

    def _exchange_mismatch(self):
        pass

    def _close_stage(self, stage: int, rate: float, integration: float = 0.0):
        """The stage's power, dissipation and reactions from what rates() left and the energy
        rate its Runge-Kutta update summed (and at the last stage the energy the step adds,
        scheme.time.heun_energy_excess): one reduction over ranks per stage."""
        power, *reaction = self._stage_sums
        sums = self._sum(np.concatenate([[power, rate, integration],
                                         *(r.ravel() for r in reaction)]))
        power, rate = float(sums[0]), float(sums[1])
        self.stage_integration = float(sums[2])
        if self.reaction_rows:
            self.stage_reaction[stage] = sums[3:].reshape(self.stage_reaction[stage].shape)
        if self.contact is not None:
            power += self.contact.wall_power(stage)     # the same on every rank
        self.stage_power[stage] = power
        self.stage_dissipation[stage] = power - rate

    def _stresses(self, rows: slice):
        """Cauchy stress (and with the upwind geometric flux the packed fields U) of the
        nodes ``rows``."""
        m = self.disc
        if self.stress_reconstructed:
            K.stress_and_fields(self.F[rows], self.v[rows], m.node_material[rows],
                                m.material_table, self.sigma[rows], self.U[rows], self.dim)
        else:
            K.compute_stress(self.F[rows], m.node_material[rows], m.material_table,
                             self.sigma[rows], self.dim)

    def stable_dt(self) -> float:
        """cfl x min over nodes of h lambda_min / c_p: computed by the last stage of the step
        that made the current state, or here (first step, after a restore)."""
        if self._next_dt is not None:
            return self._next_dt
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

    def _forget_state_values(self):
        self._next_dt = None
        self._bad = None
        self._monitors_fresh = False
        self._stress_carried = False

    def _host(self):
        """Bring the host copies of v, F, x up to date (CUDA backend)."""
        if self.device is not None and self._host_stale:
            self.device.to_host()
            self._host_stale = False

    def _device_step(self, dt: float):
        """step() with the CUDA backend's loops (backends.cuda.DeviceState): the same
        stages, loads, power and reactions, with the state on the device."""
        dev, loads = self.device, self.loads
        dev.save_start()
        self.dt = dt
        t = self.time
        if self.reaction_rows:
            held = self.reaction_sum @ (self.mass[:, None] * loads.fixed_value)
        last = len(STAGES) - 1
        for stage, alpha in enumerate(STAGES):
            loads.at(t + (dt if stage else 0.0))
            if stage == 0 and self.has_supports:
                held_start = loads.fixed_value[self.held]   # the held velocities at t
            if loads.varies:
                dev.loads_up()
            power, self.bc_force[:], held_force = dev.rates(stage, t + (dt if stage else 0.0))
            if self.contact is not None:
                power += self.contact.wall_power(stage)
            self.stage_power[stage] = power
            self.stage_dissipation[stage] = power - dev.rate
            self.stage_integration = dev.integration
            if self.reaction_rows:
                self.stage_reaction[stage] = self.reaction_mask * (
                    self.bc_force[self.reaction_rows] - held_force)
            loads.at(t + dt)
            if loads.varies:
                dev.loads_up()
            out = dev.update(alpha, dt, stage == last, bool(self.history_due))
        smallest, bad = out
        self._next_dt = self.cfl * smallest
        self._bad = bad
        self._monitors_fresh = bool(self.history_due)
        self._host_stale = True
        self.time = t + dt
        if self.contact is not None:
            dev.contact.end_step(self.time)
        self.external_work += 0.5 * dt * (self.stage_power[0] + self.stage_power[1])
        self.dissipated += 0.5 * dt * (self.stage_dissipation[0] + self.stage_dissipation[1])
        self.integration += self.stage_integration
        if self.has_supports:
            self.external_work += 0.5 * float(np.dot(
                self.mass[self.held[0]], loads.fixed_value[self.held] ** 2 - held_start ** 2))
        if self.reaction_rows:
            change = (self.reaction_sum @ (self.mass[:, None] * loads.fixed_value) - held) / dt
            self.reaction[:] = 0.5 * (self.stage_reaction[0] + self.stage_reaction[1]) \
                + self.reaction_mask * change

    def step(self, dt: float):
        if self.device is not None:
            self._forget_state_values()
            return self._device_step(dt)
        with superword_vectorization(self.disc.dim == 3):
            self._host_step(dt)

    def _host_step(self, dt: float):
        m = self.disc
        loads = self.loads
        # the last stage of the previous step left the stress of this state (unless a
        # restore or _forget_state_values came since)
        carried = self._stress_carried
        # the start of the step (v0, F0, x0) is saved by the first stage's update
        # (kernels.rk_update), in its pass over the nodes
        self.dt = dt
        t = self.time
        o = self.n_owned
        if self.reaction_rows:
            held = self._sum(self.reaction_sum @ (self.mass[:o, None] * loads.fixed_value[:o]))
        self._forget_state_values()
        last = len(STAGES) - 1
        for stage, alpha in enumerate(STAGES):
            loads.at(t + (dt if stage else 0.0))
            self.rates(stage, carried and stage == 0)
            # both stages end at t + dt (Heun), where the prescribed velocities are imposed
            loads.at(t + dt)
            # the owned nodes (all of them in a serial run)
            start = (self.v0[:o], self.F0[:o], self.x0[:o])
            state = (self.v[:o], self.F[:o], self.x[:o])
            rates = (self.force[:o], self.dF[:o], self.sigma[:o])
            node_data = (m.volume[:o], m.fixed_mask[:o], loads.fixed_value[:o])
            nodal = (start, state, rates, self.contact_state[:o], self.contact_xdot[:o],
                     m.node_material[:o], m.material_table, node_data)
            if stage < last:
                rate = K.rk_update(alpha, dt, *nodal, stage == 0, self.dim)
                self._begin_state_exchange()
                self._close_stage(stage, rate)
                continue
            # the last stage also gives the next time step, the state check and (when a
            # history row follows) the monitors, in the same pass over the nodes
            smallest, bad, rate, integration = K.rk_update_last(
                alpha, dt, *nodal, m.node_length[:o], m.body_start,
                bool(self.history_due), self.monitor_buf, bool(self.stress_reconstructed),
                self.U[:o], self.stretch_bound[:o], self.dim)
            if self.disc.dim == 3:
                # the last stage gave an upper bound of the minimum and each node's lower bound
                smallest = K.smallest_time_step_of_candidates(
                    self.F[:o], m.node_material[:o], m.material_table, m.node_length[:o],
                    self.stretch_bound[:o], smallest, self.dim)
            self._stress_carried = True
            self._begin_state_exchange()
            self._close_stage(stage, rate, integration)
            self._next_dt = self.cfl * self._min(smallest)
            self._bad = self._first_bad(bad)
            self._monitors_fresh = bool(self.history_due)
        self.time = t + dt
        self.external_work += 0.5 * dt * (self.stage_power[0] + self.stage_power[1])
        self.dissipated += 0.5 * dt * (self.stage_dissipation[0] + self.stage_dissipation[1])
        self.integration += self.stage_integration
        if self.has_supports:
            self.external_work += self._sum(0.5 * float(np.dot(
                self.mass[self.held[0]], self.v[self.held] ** 2 - self.v0[self.held] ** 2)))
        if self.reaction_rows:
            # Runge-Kutta mean of the stages, plus the force that changes the momentum of
            # the held nodes when the prescribed velocity changes
            change = (self._sum(self.reaction_sum @ (self.mass[:o, None]
                                                     * loads.fixed_value[:o])) - held) / dt
            self.reaction[:] = 0.5 * (self.stage_reaction[0] + self.stage_reaction[1]) \
                + self.reaction_mask * change
        if self.contact is not None:
            self.contact.end_step(self.x, self.v, self.F, self.time)
        self._end_state_exchange()

    def check(self, step: int, t: float):
        """Raise SimulationError naming the first node with a non-finite state or J <= 0."""
        bad = self._bad if self._bad is not None else K.state_is_bad(self.v, self.F, self.dim)
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

    # ------------------------------------------------------------------ monitors and fields
    def history_columns(self) -> list[str]:
        components = "xyz"[:self.disc.dim]
        momentum = [f"momentum_{c}" for c in components]
        reactions = [f"reaction_{name}_f{c}" for name in self.reaction_names
                     for c in components]
        return (["kinetic_energy", "strain_energy", "total_energy", *momentum,
                 "external_work", "dissipated_energy", "integration_energy", "energy_balance",
                 *reactions]
                + (self.contact.history_columns() if self.contact is not None else []))

    def history_row(self) -> list[float]:
        m = self.disc
        if not self._monitors_fresh:
            self._host()
            K.monitors(self.v, self.F, m.node_material, m.material_table, m.volume,
                       m.body_start, self.monitor_buf, self.dim)
            self._monitors_fresh = True
        kinetic, strain, *momentum = self._sum(self.monitor_buf).sum(axis=0)
        extra = self.contact.history_values() if self.contact is not None else []
        # the energy balance: what the bodies hold minus the work done on them plus what the
        # scheme dissipated (upwinding at fronts and boundaries, the contacts) minus what the
        # time stepping added; constant up to the third-order part of the time-integration
        # error
        balance = kinetic + strain - self.external_work + self.dissipated - self.integration
        return [kinetic, strain, kinetic + strain, *momentum, self.external_work,
                self.dissipated, self.integration, balance, *self.reaction.ravel(), *extra]

    def _whole_state(self):
        """(discretisation, v, F, x, contact status, contact normal traction) of all nodes:
        the outputs' view of the state (under MPI gathered from every rank)."""
        self._host()
        c = self.contact
        return (self.disc, self.v, self.F, self.x, None if c is None else c.state,
                None if c is None else c.tstar_n)

    def point_data(self, whole=None) -> dict[str, np.ndarray]:
        m, v, F, x, status, tstar_n = whole or self._whole_state()
        n = m.n_nodes
        pressure, von_mises, jac = np.empty(n), np.empty(n), np.empty(n)
        stress = np.empty((n, 3, 3))
        K.point_fields(np.ascontiguousarray(F), m.node_material, m.material_table, pressure,
                       von_mises, jac, stress, self.dim)
        data = {"velocity": v, "displacement": x - m.X, "pressure": pressure,
                "von_mises": von_mises, "stress": stress, "J": jac,
                "body": m.body_of_node.astype(np.int32)}
        if status is not None:
            data["contact_status"] = status.astype(np.int32)  # 0 open 1 stick 2 slip
            data["contact_pressure"] = -tstar_n
        return data

    def snapshot(self):
        """(reference points, cells, point data) of all bodies for a ParaView frame."""
        whole = self._whole_state()
        cells = np.concatenate([b.cells for b in whole[0].bodies])
        return whole[0].X, cells, self.point_data(whole)

    def body_fields(self) -> dict[str, dict[str, np.ndarray]]:
        """The point fields of each body (copies), plus its mesh and F."""
        whole = self._whole_state()
        m, _, F, x, status, _ = whole
        data = self.point_data(whole)
        data.pop("body")
        out = {}
        for b in m.bodies:
            s = slice(b.start, b.stop)
            fields = {key: np.array(value[s]) for key, value in data.items()}
            if status is not None:
                fields["contact_status"] = status[s].copy()
            cells = b.cells - b.start
            fields.update(reference_points=m.X[s].copy(), points=x[s].copy(),
                          cells=cells, F=F[s].copy())
            fields["triangles" if m.dim == 2 else "tetrahedra"] = cells
            out[b.name] = fields
        return out

    def summary(self) -> dict:
        return {"nodes": int(self.disc.n_nodes), "edges": int(self.disc.n_edges)}

    # ------------------------------------------------------------------ checkpoints
    def state_arrays(self) -> dict[str, np.ndarray]:
        """Everything a restart needs besides the case."""
        self._host()
        arrays = {"v": self.v, "F": self.F, "x": self.x, "time": np.array(self.time),
                  "external_work": np.array(self.external_work),
                  "dissipated": np.array(self.dissipated),
                  "integration": np.array(self.integration), "reaction": self.reaction}
        if self.contact is not None:
            arrays["contact_memory"] = self.contact.memory
        if self._stress_carried:
            # the stress the last stage computed for the next step (kernels.rk_update_last):
            # the continued run uses it as the uninterrupted one does, to the last bit
            arrays["sigma"] = self.sigma
        return arrays

    def restore(self, arrays) -> None:
        """Continue from ``state_arrays`` of an earlier run of the same case."""
        for name in ("v", "F", "x"):
            target = getattr(self, name)
            if arrays[name].shape != target.shape:
                raise ValueError(f"{name} has shape {arrays[name].shape}, the case gives "
                                 f"{target.shape}")
            target[:] = arrays[name]
        self._forget_state_values()
        # (a checkpoint without it, or with a stress that is not finite: computed again)
        carried = arrays.get("sigma")
        if carried is not None and carried.shape == self.sigma.shape \
                and self.device is None and np.all(np.isfinite(carried)):
            self.sigma[:] = carried
            if self.stress_reconstructed:
                K.pack_velocity_and_stress(self.v, self.sigma, self.U, self.dim)
            self._stress_carried = True
        if self.device is not None:
            self.device.from_host()
            self._host_stale = False
        self.time = float(arrays["time"])
        self.external_work = float(arrays["external_work"])
        self.dissipated = float(arrays["dissipated"])
        # checkpoints written before the column existed continue from zero
        self.integration = float(arrays["integration"]) if "integration" in arrays else 0.0
        self.reaction[:] = arrays["reaction"]
        self.loads.at(self.time)
        if self.contact is not None:
            self.contact.end_step(self.x, self.v, self.F, self.time)
            self.contact.restore_memory(arrays["contact_memory"])
