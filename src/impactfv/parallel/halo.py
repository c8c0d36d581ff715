"""The halo exchange: each rank sends the rows of its owned nodes that other ranks hold as
ghosts, and receives the rows of its own ghosts, with non-blocking point-to-point messages
(one per neighbour rank and exchange, all fields of the exchange packed in it)."""

from __future__ import annotations

import numpy as np


class Halo:
    def __init__(self, comm, part):
        self.comm = comm
        size = comm.Get_size()
        ghosts = part.nodes[part.n_owned:]
        # ask each owner for the ghosts it owns (sorted by global number on both sides)
        wanted = [ghosts[part.ghost_owner == r] for r in range(size)]
        asked = comm.alltoall(wanted)
        local = {int(g): i for i, g in enumerate(part.nodes[:part.n_owned])}
        self.send = {r: np.array([local[int(g)] for g in ids], np.int64)
                     for r, ids in enumerate(asked) if len(ids)}
        start = part.n_owned
        self.recv = {}
        for r in range(size):
            count = len(wanted[r])
            if count:
                self.recv[r] = np.arange(start, start + count)
                start += count
        self.neighbours = sorted(set(self.send) | set(self.recv))
        self.messages = 0          # per exchange, sent by this rank
        self.bytes = 0             # per exchange of the last call, sent by this rank

    def exchange(self, *arrays):
        """Overwrite the ghost rows of ``arrays`` (first axis: local nodes) with their
        owners' rows."""
        self.end(self.begin(*arrays))

    def begin(self, *arrays):
        """Post the messages of an exchange (returns what :meth:`end` completes); the owned
        rows may be read, the ghost rows must not be, until then."""
        width = [int(np.prod(a.shape[1:])) for a in arrays]
        total = sum(width)
        requests, inbox, outbox = [], {}, []
        for r, rows in self.recv.items():
            inbox[r] = np.empty((len(rows), total))
            requests.append(self.comm.Irecv(inbox[r], source=r, tag=7))
        sent = 0
        for r, rows in self.send.items():
            buf = np.empty((len(rows), total))
            col = 0
            for a, w in zip(arrays, width):
                buf[:, col:col + w] = a[rows].reshape(len(rows), w)
                col += w
            outbox.append(buf)
            sent += buf.nbytes
            requests.append(self.comm.Isend(buf, dest=r, tag=7))
        self.messages, self.bytes = len(self.send), sent
        return arrays, width, requests, inbox, outbox

    def end(self, pending):
        """Wait for the messages of :meth:`begin` and write the ghost rows."""
        from mpi4py import MPI

        arrays, width, requests, inbox, _ = pending
        MPI.Request.Waitall(requests)
        for r, rows in self.recv.items():
            col = 0
            for a, w in zip(arrays, width):
                a[rows] = inbox[r][:, col:col + w].reshape((len(rows),) + a.shape[1:])
                col += w
