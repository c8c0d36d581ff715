"""The MPI world of a run, when it was launched by mpiexec on several ranks.

A process started by ``mpiexec`` (MPICH's hydra, Open MPI, Intel MPI, Slurm's srun with
PMI/PMIx) finds its rank count in the environment; only then is mpi4py imported, so a serial
run needs neither mpi4py nor an MPI library.
"""

from __future__ import annotations

import os

from ..errors import InputError

#: environment variables in which launchers give the number of ranks
SIZE_VARIABLES = ("PMI_SIZE", "OMPI_COMM_WORLD_SIZE", "PMIX_SIZE", "MPI_LOCALNRANKS",
                  "SLURM_NTASKS")

_world = []
_ending = []


def launched_size() -> int:
    """How many ranks the launcher started (1 when not started by one)."""
    for key in SIZE_VARIABLES[:3]:
        value = os.environ.get(key, "")
        if value.isdigit():
            return int(value)
    # srun without PMI variables, or a launcher that gives only the local count
    if any(key in os.environ for key in ("PMI_RANK", "OMPI_COMM_WORLD_RANK", "PMIX_RANK",
                                         "SLURM_PROCID")):
        for key in SIZE_VARIABLES[3:]:
            value = os.environ.get(key, "")
            if value.isdigit():
                return int(value)
    return 1


def world():
    """mpi4py's COMM_WORLD when this process is one of several MPI ranks, else None."""
    if _world:
        return _world[0]
    size = launched_size()
    comm = None
    if size > 1:
        try:
            from mpi4py import MPI
        except ImportError:
            raise InputError(f"started on {size} MPI ranks but mpi4py is not installed: "
                             "pip install 'impactfv[mpi]' (docs/parallel.md)") from None
        comm = MPI.COMM_WORLD if MPI.COMM_WORLD.Get_size() > 1 else None
        if comm is not None:
            # a communicator of its own for ending together (end_together), so that its
            # barrier never meets a collective of the run
            _ending.append(comm.Dup())
    _world.append(comm)
    return comm


def end_together(code: int, wait_s: float = 10.0):
    """A rank stopping with exit ``code``: when every rank stops too (an input error in the
    case, a simulation failure, a signal: all ranks see them together) they meet at a
    barrier and exit normally; a rank that stops alone (a file rank 0 cannot write, an
    unexpected error) would leave the others waiting in the run's next collective, so after
    ``wait_s`` seconds it aborts the whole job with its code."""
    if not _ending:
        return
    import time

    request = _ending[0].Ibarrier()
    deadline = time.monotonic() + wait_s
    while not request.Test():
        if time.monotonic() > deadline:
            _ending[0].Abort(code or 1)
        time.sleep(0.01)


def rank() -> int:
    comm = world()
    return 0 if comm is None else comm.Get_rank()
