"""The loops interface of the FV stage sequence, and its CPU implementation.

scheme.stepper.FVStepper runs one stage sequence (stress, gradient, contact, fluxes,
relaxation, body forces, update) for every backend; each step of it is a method of a loops
object that owns where the state lives and how its loops run:

- :class:`CPULoops` (here): the numba loops of backends/cpu.py on the stepper's host arrays;
- backends.cuda.CUDALoops: the CUDA kernels of backends/cuda.py on the device's copies.

Both compile the same loop bodies (scheme/bodies.py). A method that reads or writes the
state does it in the loops' own copy; what the stepper needs back (the boundary power and
forces, the energy rate of a stage, the next time step and state check) is returned.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..physics.limiters import IDS as LIMITER_IDS
from . import cpu as K


@dataclass
class StageResult:
    """What a Runge-Kutta stage's update returns: the rate of the nodes' kinetic and strain
    energy in the stage's state, the power of the forces the supports cancel on held
    velocity components, and at the last stage the energy the step adds (Heun's excess), the
    smallest h lambda_min / c_p of the new state, its first bad node (-1: none), its
    monitors when asked (per body: kinetic and strain energy, momentum) and whether the
    stress (and U) of the owned nodes are the new state's."""

    rate: float
    held_power: float
    integration: float = 0.0
    smallest: float = np.inf
    bad: int = -1
    monitors: np.ndarray | None = None
    stress: bool = False


@dataclass(frozen=True)
class StateValues:
    """What the last stage of the step that made the current state computed of it, in one
    pass with the update (StageResult): the next stable time step, the first
    bad node (-1: none), the monitors (per body: kinetic and strain energy, momentum) and
    whether sigma (and U) of the owned nodes are this state's. None / False: not computed;
    stable_dt, check and history_row then compute them from the state."""

    next_dt: float | None = None
    bad: int | None = None
    monitors: np.ndarray | None = None
    stress: bool = False


#: nothing known of the state besides the state (the first step, after a restore, after code
#: outside the stepper wrote v, F or x: scheme.stepper.FVStepper.state_changed)
UNKNOWN = StateValues()


class CPULoops:
    """The stage's loops on the CPU (backends/cpu.py), on the stepper's host arrays. The
    node loops of the update run over the owned nodes (all of them in a serial run)."""

    #: the last stage leaves the new state's stress (rk_update_last), which the next step's
    #: first stage and a restart may use
    carries_stress = True

    def __init__(self, stepper):
        self.s = stepper

    def loads_changed(self):
        """The loads were brought to a new time (their arrays are read where they are)."""

    def stresses(self, rows: slice):
        """Cauchy stress (and with the stress reconstructed the packed fields U) of the
        nodes ``rows``."""
        s, m = self.s, self.s.disc
        if s.stress_reconstructed:
            K.stress_and_fields(s.F[rows], s.v[rows], m.node_material[rows], m.material_table,
                                s.sigma[rows], s.U[rows], s.dim)
        else:
            K.compute_stress(s.F[rows], m.node_material[rows], m.material_table,
                             s.sigma[rows], s.dim)

    def pack(self, rows: slice):
        """U of the nodes ``rows`` from their velocity and (carried) stress."""
        s = self.s
        K.pack_velocity_and_stress(s.v[rows], s.sigma[rows], s.U[rows], s.dim)

    def gradient(self, with_positions: bool):
        """The limited gradients of U; with ``with_positions`` the relaxation's mismatch."""
        s, m = self.s, self.s.disc
        K.limited_gradient(s.U, s.dual, m.closure, s.limiter, s.grad, s.components, s.x, s.F,
                           s.mismatch, with_positions, s.dim)

    def positions_mismatch(self):
        """The relaxation's mismatch D = F - G(x) alone (order 1)."""
        s, m = self.s, self.s.disc
        if s.positions_gradient is None:
            s.positions_gradient = np.zeros((m.n_nodes, m.dim, m.dim + 1))
        K.limited_gradient(s.x, s.dual, m.closure, LIMITER_IDS["none"], s.positions_gradient,
                           s.dim, s.x, s.F, s.mismatch, True, s.dim)

    def contact_stage(self, stage: int, stage_time: float):
        """The contact stage of the current state (contact.driver.ContactStage); the nodes it
        takes to first order lose their gradients."""
        s = self.s
        contact = s.contact.stage(s.x, s.v, s.F, s.sigma, s.dt, stage, stage_time)
        if s.order == 2:
            s.grad[contact.first_order] = 0.0
        return contact

    def fluxes(self, contact):
        """force and dF of the edges and boundary faces (free of ``contact``, the stage's
        ContactStage, for the part of each face in contact); returns (boundary power, the
        force of each boundary condition's faces)."""
        s, m, loads = self.s, self.s.disc, self.s.loads
        K.assemble_rates(s.v, s.F, s.sigma, s.grad, m.node_material, m.material_table,
                         s.edge_mesh, s.face_mesh,
                         (m.bc_fixed, loads.face_velocity, loads.face_traction,
                          s.tangential_correction),
                         s.flux_options, contact.state, contact.face_weight,
                         (s.force, s.dF, s.power, s.bc_force), s.dim)
        return s.power[0], s.bc_force

    def project_angular_momentum(self, projection, last, contact):
        """The interior fluxes' torque removed from the free bodies' force
        (scheme.angular_momentum), on the host arrays."""
        projection.project(last, contact)

    def contact_apply(self):
        s = self.s
        s.contact.apply(s.force, s.dF, s.loads.fixed_value)

    def relax(self):
        s, m = self.s, self.s.disc
        K.relax_towards_positions(s.mismatch, s.relaxation_weight, s.n_owned,
                                  m.node_edge_start, m.node_neighbour, s.dF, s.dim)

    def body_force(self) -> float:
        """Adds the body forces to force; returns their power on the owned nodes."""
        s, o, acceleration = self.s, self.s.n_owned, self.s.loads.acceleration
        s.force += s.mass[:, None] * acceleration
        return float(np.einsum("i,ij,ij->", s.mass[:o], acceleration[:o], s.v[:o]))

    def held_forces(self):
        """The force on each reaction's held nodes (owned), summed per reaction row."""
        s = self.s
        return s.energy.reaction_sum @ s.force[:s.n_owned]

    def update(self, alpha, dt, stage, last, with_monitors, contact) -> StageResult:
        """One Runge-Kutta stage of the owned nodes (the first stage saves the start of the
        step), nodes in ``contact`` (the stage's ContactStage) moving with their contact
        velocity; the last stage also gives the time step, the state check, the stress of
        the new state and, with ``with_monitors``, the monitors (in stepper.monitor_buf)."""
        s, m, o = self.s, self.s.disc, self.s.n_owned
        held = s.energy.held
        held_power = float(np.dot(s.force[held], s.v[held])) if s.energy.has_supports else 0.0
        start = (s.v0[:o], s.F0[:o], s.x0[:o])
        state = (s.v[:o], s.F[:o], s.x[:o])
        rates = (s.force[:o], s.dF[:o], s.sigma[:o])
        node_data = (m.volume[:o], m.fixed_mask[:o], s.loads.fixed_value[:o])
        nodal = (start, state, rates, contact.state[:o], contact.xdot[:o],
                 m.node_material[:o], m.material_table, node_data)
        if not last:
            return StageResult(K.rk_update(alpha, dt, *nodal, stage == 0, s.dim), held_power)
        smallest, bad, rate, integration = K.rk_update_last(
            alpha, dt, *nodal, m.node_length[:o], m.body_start, bool(with_monitors),
            s.monitor_buf, bool(s.stress_reconstructed), s.U[:o], s.stretch_bound[:o], s.dim)
        if m.dim == 3:
            # the last stage gave an upper bound of the minimum and each node's lower bound
            smallest = K.smallest_time_step_of_candidates(
                s.F[:o], m.node_material[:o], m.material_table, m.node_length[:o],
                s.stretch_bound[:o], smallest, s.dim)
        return StageResult(rate, held_power, integration, smallest, bad,
                           s.monitor_buf if with_monitors else None, True)

    def contact_end_step(self, time: float):
        s = self.s
        s.contact.end_step(s.x, s.v, s.F, time)

    def to_host(self):
        """The host arrays v, F, x are the state already."""

    def from_host(self):
        """The host arrays v, F, x are the state already."""
