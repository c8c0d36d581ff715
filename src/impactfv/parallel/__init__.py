"""Domain decomposition over MPI (docs/parallel.md): the mesh partitioned by the graph of its
edges, a halo of ghost nodes exchanged twice per Runge-Kutta stage, contact surfaces
gathered on every rank. Serial runs never import mpi4py."""

from .comm import world

__all__ = ["world"]
