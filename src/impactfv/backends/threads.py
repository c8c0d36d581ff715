"""Threads of the CPU kernels: how many, and how they wait.

numba runs a parallel loop on a pool of threads; between two parallel loops the threads
wait for the next one. By default the OpenMP runtime lets a waiting thread spin (busy-wait)
for a while. On a core that another process keeps busy a spinning thread steals the time
slices its sibling threads need, and every barrier waits for a descheduled thread: a step
with two threads took about 4 times as long as with one (docs/performance.md, "Threads on a
busy machine"). Importing this module (impactfv's ``__init__`` does) therefore asks the OpenMP
runtimes to wait passively, unless the environment already says otherwise:

* ``OMP_WAIT_POLICY=passive`` (GNU libgomp, the runtime of numba's ``omp`` layer on Linux,
  and Intel's): a waiting thread sleeps on a futex at once;
* ``KMP_BLOCKTIME=0`` (Intel OpenMP): the same for Intel's runtime.

Both are read when the runtime is loaded, i.e. the first time numba starts its threads; a
process that loaded an OpenMP runtime before impactfv was imported keeps that runtime's
policy. numba's ``workqueue`` layer never spins; ``tbb`` spins briefly and then sleeps.

The number of threads is a run setting (``[run] threads``, ``--threads``); the default is
the number of cores this process may use (``os.sched_getaffinity``), at most the size of
numba's pool (``NUMBA_NUM_THREADS``, numba's default: the CPU count).
"""

from __future__ import annotations

import os
from contextlib import contextmanager

#: what impactfv sets (unless already set) before any OpenMP runtime is loaded
WAIT_POLICY = {"OMP_WAIT_POLICY": "passive", "KMP_BLOCKTIME": "0"}

for _key, _value in WAIT_POLICY.items():
    os.environ.setdefault(_key, _value)


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity), at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def pool_size() -> int:
    """The number of threads numba starts (NUMBA_NUM_THREADS): the most a run can use."""
    from numba import config
    return int(config.NUMBA_NUM_THREADS)


def default_threads() -> int:
    """The cores this process may use, at most numba's pool."""
    return max(1, min(usable_cores(), pool_size()))


def threads_problem(threads: int | None) -> str | None:
    """Why ``threads`` cannot be used here (a message naming run.threads), or None."""
    if threads is None:
        return None
    if threads < 1:
        return f"run.threads must be at least 1, got {threads}"
    if threads > pool_size():
        return (f"run.threads = {threads}: numba's thread pool has {pool_size()} threads "
                "here (NUMBA_NUM_THREADS; by default the CPU count); ask for at most that, "
                "or raise NUMBA_NUM_THREADS")
    return None


@contextmanager
def using_threads(threads: int | None):
    """Run the body with ``threads`` numba threads (None: :func:`default_threads`), then
    give the caller back its own setting. Raises ValueError with :func:`threads_problem`'s
    message when the count cannot be used."""
    import numba

    problem = threads_problem(threads)
    if problem:
        raise ValueError(problem)
    before = numba.get_num_threads()
    numba.set_num_threads(default_threads() if threads is None else int(threads))
    try:
        yield numba.get_num_threads()
    finally:
        numba.set_num_threads(before)
