"""The FV stepper's energy balance and support reactions (docs/theory.md, "Energy balance").

Per stage the stepper hands over what its rates and its update returned; per step the
book integrates them with the Runge-Kutta weights:

    external_work += dt/2 (P_0 + P_1) + the kinetic energy supports give held components
    dissipated    += dt/2 (D_0 + D_1),  D = P - dE/dt (what the semi-discrete scheme removes)
    integration   += Heun's energy excess of the step (physics.runge_kutta)

so that kinetic + strain - external_work + dissipated - integration stays constant up to
the third-order part of the time-integration error. Each boundary entry with a prescribed
velocity reports the force its support exerts on the body.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def distinct_names(names: list[str]) -> list[str]:
    """The names made distinct for history columns: a name given twice gets _2, _3, ... but
    never another entry's name (["L", "L", "L_2"] -> ["L", "L_3", "L_2"])."""
    given = set(names)
    out = []
    for base in names:
        name, n = base, 2
        while name in out or (name != base and name in given):
            name = f"{base}_{n}"
            n += 1
        out.append(name)
    return out


class EnergyBook:
    """Energy and reaction bookkeeping of one FV run (of one rank's owned nodes under MPI:
    ``total`` sums over ranks)."""

    def __init__(self, case, disc, n_owned: int, mass, total):
        self.total = total
        self.mass = mass
        self.n_owned = n_owned
        # the power of the boundary tractions and body forces per stage, and its integral
        self.stage_power = np.zeros(2)
        self.external_work = 0.0
        # what the semi-discrete scheme removes per stage (power in minus the rate of the
        # energy the rates give), and its Runge-Kutta integral
        self.stage_dissipation = np.zeros(2)
        self.dissipated = 0.0
        # the energy the two-stage step adds beyond the Runge-Kutta mean of the stage rates,
        # per step and since t = 0
        self.stage_integration = 0.0
        self.integration = 0.0
        # the strongly held velocity components (owned nodes): the support's work there is
        # the kinetic energy it gives them minus the power of the force it cancels
        self.held = np.nonzero(disc.fixed_mask[:n_owned])      # (nodes, components)
        self.has_supports = bool(disc.bc_fixed.any())        # the same on every rank
        self._reactions_setup(case, disc)

    def _reactions_setup(self, case, m):
        """History columns reaction_<region>_f<c> (with several bodies
        reaction_<body>_<region>_f<c>) for each boundary entry with a prescribed velocity."""
        rows, names = [], []
        several = len(case.bodies) > 1
        for body in case.bodies:
            for spec in body.boundary:
                rows.append(spec)
                names.append(f"{body.name}_{spec.region}" if several else spec.region)
        self.reaction_rows = [k for k, spec in enumerate(rows, start=1) if m.bc_fixed[k].any()]
        self.reaction_names = distinct_names([names[k - 1] for k in self.reaction_rows])
        d, owned = m.dim, self.n_owned
        if self.reaction_rows:
            cols = [m.bc_nodes[k][m.bc_nodes[k] < owned] for k in self.reaction_rows]
            self.reaction_sum = sp.csr_matrix(
                (np.ones(sum(map(len, cols))),
                 (np.repeat(np.arange(len(cols)), list(map(len, cols))), np.concatenate(cols))),
                shape=(len(cols), owned))
            self.reaction_mask = np.array([m.bc_fixed[k] for k in self.reaction_rows], float)
        self.stage_reaction = np.zeros((2, len(self.reaction_rows), d))
        self.reaction = np.zeros((len(self.reaction_rows), d))

    def held_momentum(self, loads):
        """The momentum of each reaction's held nodes at the loads' current time."""
        o = self.n_owned
        return self.total(self.reaction_sum @ (self.mass[:o, None] * loads.fixed_value[:o]))

    def stage_reactions(self, bc_force, held_forces):
        """The reactions of a stage: through the Riemann tractions of the support's faces
        and, where the prescribed components are imposed on the nodes, by cancelling the
        force left on them."""
        return self.reaction_mask * (bc_force[self.reaction_rows] - held_forces)

    def close_stage(self, stage: int, sums, result, wall_power):
        """The stage's power, dissipation and reactions from what the rates returned
        (``sums``: power, reactions or None) and what its update returned (``result``,
        backends.loops.StageResult); ``wall_power``: a callable giving the power of rigid
        walls (the same on every rank). One reduction over ranks per stage."""
        power, reactions = sums
        power -= result.held_power
        extra = [] if reactions is None else [reactions.ravel()]
        sums = self.total(np.concatenate([[power, result.rate, result.integration], *extra]))
        power, rate = float(sums[0]), float(sums[1])
        self.stage_integration = float(sums[2])
        if self.reaction_rows:
            self.stage_reaction[stage] = sums[3:].reshape(self.stage_reaction[stage].shape)
        power += wall_power(stage)
        self.stage_power[stage] = power
        self.stage_dissipation[stage] = power - rate

    def close_step(self, dt, loads, held_start, held_momentum_start):
        """Integrate the step's stages. ``held_start``: the held velocities at the start of
        the step; ``held_momentum_start``: held_momentum() then (loads now at the end)."""
        self.external_work += 0.5 * dt * (self.stage_power[0] + self.stage_power[1])
        self.dissipated += 0.5 * dt * (self.stage_dissipation[0] + self.stage_dissipation[1])
        self.integration += self.stage_integration
        if self.has_supports:
            # the kinetic energy the support gives the held components
            self.external_work += self.total(0.5 * float(np.dot(
                self.mass[self.held[0]], loads.fixed_value[self.held] ** 2 - held_start ** 2)))
        if self.reaction_rows:
            # Runge-Kutta mean of the stages, plus the force that changes the momentum of
            # the held nodes when the prescribed velocity changes
            change = (self.held_momentum(loads) - held_momentum_start) / dt
            self.reaction[:] = 0.5 * (self.stage_reaction[0] + self.stage_reaction[1]) \
                + self.reaction_mask * change

    def columns(self, dim: int) -> list[str]:
        components = "xyz"[:dim]
        return [f"reaction_{name}_f{c}" for name in self.reaction_names for c in components]

    def state(self) -> dict:
        return {"external_work": np.array(self.external_work),
                "dissipated": np.array(self.dissipated),
                "integration": np.array(self.integration), "reaction": self.reaction}

    def restore(self, arrays):
        self.external_work = float(arrays["external_work"])
        self.dissipated = float(arrays["dissipated"])
        # checkpoints written before the column existed continue from zero
        self.integration = float(arrays["integration"]) if "integration" in arrays else 0.0
        self.reaction[:] = arrays["reaction"]
