"""The partition of a discretisation over ranks, and the local discretisation of one rank.

Nodes are split by the graph of the edges (METIS, through pymetis), so bodies may be cut
anywhere, through their contact faces too. A rank owns its nodes; its local discretisation
holds them first (in increasing global number, so each body's owned nodes stay contiguous
and in the serial order), then its ghosts: the nodes joined to an owned node by an edge,
sorted by owner and global number. It keeps every edge with an owned end and every dual
boundary face of an owned node, so that the fluxes of an owned node are those of the serial
run; a ghost's own sums are incomplete and never used (its state and gradient come from its
owner through the halo).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..errors import InputError
from ..scheme.discretisation import (BodyLayout, Discretisation, node_edge_lists,
                                     partition_edges)


def partition_nodes(disc: Discretisation, n_parts: int) -> np.ndarray:
    """(n,) the rank of each node: METIS k-way on the edge graph (all bodies together)."""
    n = disc.n_nodes
    if n_parts == 1:
        return np.zeros(n, np.int32)
    if n_parts > n:
        raise InputError(f"{n_parts} ranks for {n} nodes: use at most one rank per node")
    try:
        import pymetis
    except ImportError:
        raise InputError("partitioning over MPI ranks needs pymetis: "
                         "pip install 'impactfv[mpi]' (docs/parallel.md)") from None
    if hasattr(pymetis, "CSRAdjacency"):          # pymetis >= 2025
        graph = pymetis.CSRAdjacency(disc.node_edge_start, disc.node_neighbour)
        _, parts = pymetis.part_graph(n_parts, graph)
    else:
        _, parts = pymetis.part_graph(n_parts, xadj=disc.node_edge_start,
                                      adjncy=disc.node_neighbour)
    parts = np.asarray(parts, np.int32)
    # METIS may leave a part empty on tiny graphs: give it a node of the largest part
    for r in range(n_parts):
        if not np.any(parts == r):
            largest = np.argmax(np.bincount(parts, minlength=n_parts))
            parts[np.flatnonzero(parts == largest)[-1]] = r
    return parts


@dataclass
class LocalPart:
    """What one rank holds of the global discretisation."""

    rank: int
    disc: Discretisation        # local numbering: owned nodes, then ghosts
    nodes: np.ndarray           # (n_local,) global number of each local node
    n_owned: int
    ghost_owner: np.ndarray     # (n_local - n_owned,) rank owning each ghost
    bfaces: np.ndarray          # (h_local,) global index of each local dual boundary face
    n_cut_edges: int            # edges joining an owned node to a ghost

    @property
    def owned(self) -> np.ndarray:
        return self.nodes[:self.n_owned]


def local_part(disc: Discretisation, parts: np.ndarray, rank: int,
               n_blocks: int | None = None) -> LocalPart:
    """The local discretisation of ``rank`` (see the module docstring)."""
    n = disc.n_nodes
    is_owned = parts == rank
    owned = np.flatnonzero(is_owned)
    a, b = disc.edges[:, 0], disc.edges[:, 1]
    keep = is_owned[a] | is_owned[b]
    touching = np.zeros(n, bool)
    touching[a[keep]] = True
    touching[b[keep]] = True
    ghosts = np.flatnonzero(touching & ~is_owned)
    ghosts = ghosts[np.lexsort((ghosts, parts[ghosts]))]
    nodes = np.concatenate([owned, ghosts])
    local = np.full(n, -1, np.int64)
    local[nodes] = np.arange(len(nodes))
    edges = local[disc.edges[keep]]
    C = disc.C[keep]
    X = disc.X[nodes]
    n_local = len(nodes)
    if n_blocks is None:
        import numba
        n_blocks = max(1, numba.get_num_threads())
    if n_blocks == 1:
        # the edges in their global order: every owned node sums its fluxes in the order of
        # the serial run, so that the states are bit for bit the serial ones (only the sums
        # over ranks of energies, momentum and power differ, by round-off)
        edge_offsets = np.array([0, len(edges), len(edges)], np.int64)
    else:
        edges, C, edge_offsets = partition_edges(edges, C, n_local, n_blocks)
    half = 0.5 * (X[edges[:, 1]] - X[edges[:, 0]])
    node_edge_start, node_neighbour, node_C, node_half = node_edge_lists(edges, C, half,
                                                                         n_local)
    faces = np.flatnonzero(is_owned[disc.bface_node])
    bface_node = local[disc.bface_node[faces]]
    bface_others = local[disc.bface_others[faces]]
    if (bface_others < 0).any():      # the other nodes of a facet share an edge with it
        raise RuntimeError("a boundary facet's node is missing from the halo")
    owned_body = disc.body_of_node[owned]
    body_start = np.searchsorted(owned_body, np.arange(len(disc.bodies) + 1)).astype(np.int64)
    layouts = [BodyLayout(b.name, int(body_start[k]), int(body_start[k + 1]),
                          np.zeros((0, disc.dim + 1), np.int64), {}, np.zeros((0, disc.dim),
                                                                            np.int64),
                          b.material, b.facet_offset)
               for k, b in enumerate(disc.bodies)]
    bc_nodes = []
    for nodes_of_bc in disc.bc_nodes:
        mapped = local[nodes_of_bc]
        bc_nodes.append(np.sort(mapped[mapped >= 0]))
    sub = replace(
        disc, X=X, node_material=disc.node_material[nodes],
        body_of_node=disc.body_of_node[nodes], volume=disc.volume[nodes],
        node_length=disc.node_length[nodes], edges=edges, C=C,
        C_len=np.linalg.norm(C, axis=1), half=half, bface_node=bface_node,
        bface_others=np.ascontiguousarray(bface_others), bface_C=disc.bface_C[faces],
        bface_facet=disc.bface_facet[faces], bface_bc=disc.bface_bc[faces],
        bc_nodes=bc_nodes, fixed_mask=disc.fixed_mask[nodes], v0=disc.v0[nodes],
        edge_offsets=edge_offsets, node_edge_start=node_edge_start,
        node_neighbour=node_neighbour, node_C=node_C, node_half=node_half,
        bface_start=np.searchsorted(bface_node, np.arange(n_local + 1)),
        body_start=body_start, bodies=layouts)
    cut = int(np.count_nonzero(is_owned[a] != is_owned[b]))
    return LocalPart(rank, sub, nodes, len(owned), parts[ghosts].astype(np.int32), faces, cut)


def partition_report(disc: Discretisation, n_parts: int) -> list[str]:
    """Lines for ``impactfv check --ranks N``: per rank its nodes, halo nodes and cut edges,
    and the halo's share of all nodes."""
    parts = partition_nodes(disc, n_parts)
    lines = [f"partition over {n_parts} ranks (METIS on the edge graph):"]
    total_halo = 0
    for r in range(n_parts):
        p = local_part(disc, parts, r, n_blocks=1)
        halo = len(p.nodes) - p.n_owned
        total_halo += halo
        lines.append(f"  rank {r}: {p.n_owned} nodes, {halo} halo nodes, "
                     f"{p.n_cut_edges} cut edges, {len(set(p.ghost_owner.tolist()))} "
                     "neighbour ranks")
    lines.append(f"  halo nodes: {total_halo / disc.n_nodes:.1%} of the nodes")
    return lines
