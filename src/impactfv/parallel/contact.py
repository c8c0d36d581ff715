"""Contact across ranks: the contact surfaces gathered on every rank.

Each stage, every rank sends the state of the contact-surface nodes it owns (positions,
velocity, F, Cauchy stress, gradients, prescribed velocities) to all ranks, and every rank
runs the whole contact stage of the serial code (contact.driver.ContactSystem, on the
global numbering) on the gathered surface. The results are identical on all ranks and to
the serial run's (same inputs, same order); each rank then keeps what falls on its local
nodes and faces. The cost grows with the contact surface, not with the volume.
"""

from __future__ import annotations

import numpy as np

from ..contact.driver import ContactStage, ContactSystem


class GatheredContact:
    """The interface of ContactSystem seen from one rank's local numbering."""

    def __init__(self, case, global_disc, part, comm):
        self.comm = comm
        self.system = s = ContactSystem(case, global_disc)
        n, d = global_disc.n_nodes, global_disc.dim
        self.part = part
        surface = s.surface_nodes
        self.local = local = np.full(n, -1, np.int64)   # local number of a global node
        local[part.nodes] = np.arange(len(part.nodes))
        where = local[surface]
        owned = (where >= 0) & (where < part.n_owned)
        # this rank's share of the gathered surface, and where all shares go
        self.send_local = where[owned]
        self.send_global = surface[owned]
        shares = comm.allgather(self.send_global)
        self.counts = np.array([len(x) for x in shares], np.int64)
        self.order = np.concatenate(shares)
        # the surface nodes this rank holds (owned or ghost), local and global numbers
        held = where >= 0
        self.held_local, self.held_global = where[held], surface[held]
        self.faces_local = np.flatnonzero(np.isin(part.bfaces, s.faces))
        self.faces_global = part.bfaces[self.faces_local]
        # global-size buffers: only the surface rows are ever written or read
        self.x = np.zeros((n, d))
        self.v = np.zeros((n, d))
        self.F = np.zeros((n, d, d))
        self.sigma = np.zeros((n, d, d))
        self.fixed_value = np.zeros((n, d))
        self.force = np.zeros((n, d))
        self.dF = np.zeros((n, d, d))
        n_local = len(part.nodes)
        self.state = np.zeros(n_local, np.int8)
        self.xdot = np.zeros((n_local, d))
        self.tstar_n = np.zeros(n_local)
        self.face_weight = np.zeros(len(part.bfaces))
        self.fixed = None          # the stepper's prescribed nodal velocities (Loads)

    # ------------------------------------------------------------------ gathering
    def _gather(self, pairs):
        """Fill the global buffers' surface rows from every rank's owned surface nodes:
        ``pairs`` = [(global buffer, local array), ...], one message for all."""
        from mpi4py import MPI

        k = len(self.send_local)
        widths = [int(np.prod(g.shape[1:])) for g, _ in pairs]
        total = sum(widths)
        mine = np.empty((k, total))
        col = 0
        for (g, a), w in zip(pairs, widths):
            mine[:, col:col + w] = a[self.send_local].reshape(k, w)
            col += w
        every = np.empty((len(self.order), total))
        self.comm.Allgatherv(mine, [every, self.counts * total, MPI.DOUBLE])
        col = 0
        for (g, _), w in zip(pairs, widths):
            g[self.order] = every[:, col:col + w].reshape((len(self.order),) + g.shape[1:])
            col += w

    def _scatter_state(self):
        s = self.system
        self.state[self.held_local] = s.state[self.held_global]
        self.xdot[self.held_local] = s.xdot[self.held_global]
        self.tstar_n[self.held_local] = s.tstar_n[self.held_global]
        self.face_weight[self.faces_local] = s.face_weight[self.faces_global]

    # ------------------------------------------------------------------ ContactSystem's interface
    def stage(self, x, v, F, sigma, dt, stage_index, time=0.0) -> ContactStage:
        pairs = [(self.x, x), (self.v, v), (self.F, F), (self.sigma, sigma),
                 (self.fixed_value, self.fixed)]
        self._gather(pairs)
        result = self.system.stage(self.x, self.v, self.F, self.sigma, dt, stage_index, time)
        self._scatter_state()
        first_order = self.local[result.first_order]
        return ContactStage(self.state, self.xdot, self.face_weight,
                            first_order[first_order >= 0])

    def apply(self, force, dF, fixed_value):
        # the contact terms are added to the nodes' sums in the serial order (onto the
        # fluxes, one by one), so that the result is the serial one bit for bit
        s = self.system
        lo, gl = self.held_local, self.held_global
        self.force[gl] = force[lo]
        self.dF[gl] = dF[lo]
        s.apply(self.force, self.dF, self.fixed_value)
        force[lo] = self.force[gl]
        dF[lo] = self.dF[gl]
        self.xdot[lo] = s.xdot[gl]

    def wall_power(self, stage_index) -> float:
        return self.system.wall_power(stage_index)

    def end_step(self, x, v, F, time=0.0):
        self._gather([(self.x, x), (self.v, v), (self.F, F)])
        self.system.end_step(self.x, self.v, self.F, time)

    @property
    def memory(self):
        return self.system.memory

    def restore_memory(self, memory):
        self.system.restore_memory(memory)

    def history_columns(self):
        return self.system.history_columns()

    def history_values(self):
        return self.system.history_values()
