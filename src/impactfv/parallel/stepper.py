"""The FV stepper on one MPI rank: the serial stepper on the rank's local discretisation
(parallel.partition), with the halo exchanged after each Runge-Kutta stage (v, F, x) and
after the limited gradients, the sums of the step (power, reactions, energies, momentum) and
the stable time step reduced over ranks, and the contact surfaces gathered
(parallel.contact). Outputs gather the owned rows of every rank into the global numbering,
so that files and checkpoints are those of a serial run."""

from __future__ import annotations

import numpy as np

from ..errors import InputError, SimulationError
from ..scheme.discretisation import discretise
from ..scheme.stepper import FVStepper
from .contact import GatheredContact
from .halo import Halo
from .partition import local_part, partition_nodes


class ParallelFVStepper(FVStepper):
    def __init__(self, case, comm):
        from mpi4py import MPI

        self.comm = comm
        self.MPI = MPI
        self.rank, self.size = comm.Get_rank(), comm.Get_size()
        if case.run.backend == "cuda":
            raise InputError(f"{case.source}: run.backend = \"cuda\" runs on one rank; "
                             "start it without mpiexec")
        self.global_disc = G = discretise(case)
        parts = partition_nodes(G, self.size) if self.rank == 0 else None
        self.parts = comm.bcast(parts, root=0)
        self.part = local_part(G, self.parts, self.rank)
        self.n_owned = self.part.n_owned
        self.halo = Halo(comm, self.part)
        self._pending = None          # a state exchange under way (begun after a stage)
        super().__init__(case, self.part.disc)
        # what the outputs gather: each rank's owned rows, in the order of all ranks' shares
        shares = comm.allgather(self.part.owned)
        self.gather_counts = np.array([len(s) for s in shares], np.int64)
        self.gather_order = np.concatenate(shares)
        # the global edge arrays served the partition and the local part: let them go (the
        # contact, the outputs and the messages keep the nodes' and faces' arrays)
        self.n_global_edges = G.n_edges
        for name in ("edges", "C", "C_len", "half", "node_edge_start", "node_neighbour",
                     "node_C", "node_half", "edge_offsets"):
            setattr(G, name, None)

    def _make_contact(self, case, m):
        contact = GatheredContact(case, self.global_disc, self.part, self.comm)
        contact.fixed = self.loads.fixed_value
        return contact

    # ------------------------------------------------------------------ communication
    def _sum(self, values):
        if np.isscalar(values) or np.ndim(values) == 0:
            return self.comm.allreduce(float(values), op=self.MPI.SUM)
        out = np.empty_like(values)
        self.comm.Allreduce(np.ascontiguousarray(values), out, op=self.MPI.SUM)
        return out

    def _min(self, value):
        return self.comm.allreduce(float(value), op=self.MPI.MIN)

    def _begin_state_exchange(self, stress_carried=False):
        # after the last stage the owned stresses are the new state's (carried to the next
        # step): the ghosts take their owners' with the state, so that every rank uses one
        # stress per node, the serial run's
        carried = (self.sigma,) if stress_carried else ()
        self._pending = self.halo.begin(self.v, self.F, self.x, *carried)

    def _end_state_exchange(self):
        if self._pending is not None:
            self.halo.end(self._pending)
            self._pending = None

    def _exchange_gradients(self):
        self.halo.exchange(self.grad)

    def _exchange_mismatch(self):
        self.halo.exchange(self.mismatch)

    def _first_bad(self, bad):
        n = self.global_disc.n_nodes
        mine = int(self.part.nodes[bad]) if bad >= 0 else n
        first = self.comm.allreduce(mine, op=self.MPI.MIN)
        return first if first < n else -1      # a global node number

    def _global(self, a):
        """The global array of a per-node array from every rank's owned rows."""
        mine = np.ascontiguousarray(a[:self.n_owned])
        width = int(np.prod(a.shape[1:]))
        every = np.empty((len(self.gather_order),) + a.shape[1:], a.dtype)
        mpi_type = self.MPI._typedict[a.dtype.char]
        self.comm.Allgatherv(mine, [every, self.gather_counts * width, mpi_type])
        out = np.empty_like(every)
        out[self.gather_order] = every
        return out

    # ------------------------------------------------------------------ the serial interface
    def check(self, step: int, t: float):
        bad = self.known.bad
        if bad is None:
            from ..backends import cpu as K
            o = self.n_owned
            bad = self._first_bad(K.state_is_bad(self.v[:o], self.F[:o], self.dim))
        if bad < 0:
            return
        G = self.global_disc
        F, v = self._global(self.F)[bad], self._global(self.v)[bad]
        with np.errstate(invalid="ignore"):
            J = float(np.linalg.det(F))
        body = G.bodies[G.body_of_node[bad]]
        what = "non-finite state" if not np.isfinite(J) or not np.all(np.isfinite(v)) \
            else f"collapsed control volume (J = {J:.3g})"
        raise SimulationError(
            f"{what} at step {step}, time {t:.6e} s, body {body.name!r}, node "
            f"{bad - body.start} (reference position {G.X[bad].tolist()}); try a smaller "
            "cfl or a finer mesh", step=step, time=t, body=body.name, node=bad - body.start)

    def _whole_state(self):
        G = self.global_disc
        v, F, x = (self._global(a) for a in (self.v, self.F, self.x))
        s = self.contact.system if self.contact is not None else None
        return (G, v, F, x, None if s is None else s.state, None if s is None else s.tstar_n)

    def summary(self):
        G = self.global_disc
        return {"nodes": int(G.n_nodes), "edges": int(self.n_global_edges), "ranks": self.size}

    def state_arrays(self):
        arrays = super().state_arrays()
        # the carried stress is this rank's; a restart (on any number of ranks) computes it
        arrays.pop("sigma", None)
        for name in ("v", "F", "x"):
            arrays[name] = self._global(getattr(self, name))
        return arrays

    def restore(self, arrays):
        G = self.global_disc
        local = dict(arrays)
        local.pop("sigma", None)
        for name in ("v", "F", "x"):
            a = arrays[name]
            if a.shape[0] != G.n_nodes:
                raise ValueError(f"{name} has {a.shape[0]} rows, the case has {G.n_nodes} "
                                 "nodes")
            local[name] = a[self.part.nodes]
        super().restore(local)
