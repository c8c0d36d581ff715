"""Assembly of a validated case into the flat arrays the FV kernels stream over.

All bodies share one set of node, edge and boundary arrays; edges never cross bodies, so
the interior scheme sees them as separate. Each body's nodes are renumbered for locality
(reverse Cuthill-McKee) and its edges sorted by node. Arrays are shaped by the space
dimension d: positions (n, d), area vectors (m, d).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..case import Case
from ..physics.materials import N_PROPS
from ..mesh.core import renumber_for_locality
from ..mesh.dual import CLOSURE, median_dual
from ..mesh.edges import facet_index


@dataclass
class BodyLayout:
    """Where one body lives in the assembled arrays (global node numbers)."""

    name: str
    start: int                      # first node
    stop: int                       # one past the last
    cells: np.ndarray               # (m, d + 1)
    regions: dict[str, np.ndarray]  # region name -> its boundary facets
    facets: np.ndarray              # all boundary facets, oriented outward
    material: object = None
    facet_offset: int = 0           # index of its first facet in the global facet numbering


@dataclass
class Discretisation:
    """The median-dual arrays of all bodies, their materials and boundary conditions.

    Dual boundary faces ("bface"): the share of a boundary facet that belongs to the dual
    cell of one of its nodes (a half-edge in 2D); the boundary flux of that node is evaluated
    on it with the interior state (w u_a + sum of the other facet nodes) / denominator
    (mesh.dual.CLOSURE).
    """

    X: np.ndarray               # (n, d) reference positions
    node_material: np.ndarray   # (n,) int32 row of the material table
    material_table: np.ndarray  # (k, N_PROPS)
    body_of_node: np.ndarray    # (n,) int32
    volume: np.ndarray          # (n,) dual volumes Omega (areas in 2D)
    node_length: np.ndarray     # (n,) shortest incident edge
    edges: np.ndarray           # (m, 2)
    C: np.ndarray               # (m, d) dual area vectors, a -> b
    C_len: np.ndarray           # (m,)
    half: np.ndarray            # (m, d) X_mid - X_a = (X_b - X_a)/2
    bface_node: np.ndarray      # (h,) node of each dual boundary face
    bface_others: np.ndarray    # (h, d - 1) the other nodes of its facet
    bface_C: np.ndarray         # (h, d) its area vector S/d
    bface_facet: np.ndarray     # (h,) global index of its facet
    bface_bc: np.ndarray        # (h,) row of the boundary-condition table (0: traction-free)
    bc_fixed: np.ndarray        # (nbc, d) bool: velocity component prescribed
    bc_nodes: list              # per row of bc_fixed, the global nodes of its region
    fixed_mask: np.ndarray      # (n, d) bool: strongly prescribed nodal velocity components
    v0: np.ndarray              # (n, d) initial velocity (before prescribed values)
    edge_offsets: np.ndarray = None  # (nblocks + 2,) edges grouped by node block, then cross
    node_edge_start: np.ndarray = None  # (n + 1,) each node's edges in the node_* lists
    node_neighbour: np.ndarray = None   # (2m,) the other end b of each edge of node a
    node_C: np.ndarray = None           # (2m, d) its area vector seen from a (a -> b)
    node_half: np.ndarray = None        # (2m, d) X_mid - X_a
    bface_start: np.ndarray = None      # (n + 1,) each node's dual boundary faces (sorted)
    body_start: np.ndarray = None    # (nbodies + 1,) first node of each body
    bodies: list[BodyLayout] = field(default_factory=list)

    @property
    def dim(self) -> int:
        return self.X.shape[1]

    @property
    def closure(self) -> tuple[float, float]:
        """(weight of the node itself, denominator) of the boundary closure."""
        return CLOSURE[self.dim]

    @property
    def n_nodes(self) -> int:
        return len(self.X)

    @property
    def n_edges(self) -> int:
        return len(self.edges)

    def body_index(self, name: str) -> int:
        return [b.name for b in self.bodies].index(name)


def discretise(case: Case) -> Discretisation:
    """Build the assembled arrays of every body of ``case``."""
    material_names = list(case.materials)
    table = np.array([case.materials[k].table_row() for k in material_names])
    table = table.reshape(-1, N_PROPS)
    dim = case.bodies[0].mesh.dim
    parts = {k: [] for k in ("X", "node_material", "body_of_node", "volume", "node_length",
                             "edges", "C", "v0", "bface_node", "bface_others", "bface_C",
                             "bface_bc", "bface_facet")}
    layouts = []
    bc_fixed, bc_nodes = [[False] * dim], [np.zeros(0, np.int64)]
    fixed = []  # (global nodes, component): the strongly prescribed nodal components
    offset = 0
    n_facets = 0
    for ib, body in enumerate(case.bodies):
        mesh, _ = renumber_for_locality(body.mesh)
        dual = median_dual(mesh.points, mesh.cells)
        n = mesh.n_nodes
        parts["X"].append(mesh.points)
        parts["node_material"].append(np.full(n, material_names.index(body.material.name),
                                              np.int32))
        parts["body_of_node"].append(np.full(n, ib, np.int32))
        parts["volume"].append(dual.volumes)
        parts["node_length"].append(dual.node_length)
        order = np.lexsort((dual.edges[:, 1], dual.edges[:, 0]))
        parts["edges"].append(dual.edges[order] + offset)
        parts["C"].append(dual.area_vectors[order])
        parts["v0"].append(body.initial_velocity(mesh.points))
        facets = dual.facets
        facet_bc = np.zeros(len(facets), np.int32)
        for spec in body.boundary:
            region = mesh.regions[spec.region]
            rows = facet_index(facets, region, f"region {spec.region!r}")
            fix = [False] * dim
            nodes = offset + np.unique(region)
            if spec.velocity is not None:
                for c, value in enumerate(spec.velocity.components(dim)):
                    if value is not None:
                        fix[c] = True
                        fixed.append((nodes, c))
            bc_fixed.append(fix)
            bc_nodes.append(nodes)
            facet_bc[rows] = len(bc_fixed) - 1
        for k in range(dim):
            parts["bface_node"].append(facets[:, k] + offset)
            parts["bface_others"].append(facets[:, [j for j in range(dim) if j != k]] + offset)
            parts["bface_C"].append(dual.facet_vectors / dim)
            parts["bface_bc"].append(facet_bc)
            parts["bface_facet"].append(np.arange(len(facets)) + n_facets)
        layouts.append(BodyLayout(body.name, offset, offset + n, mesh.cells + offset,
                                  {k: v + offset for k, v in mesh.regions.items()},
                                  facets + offset, body.material, n_facets))
        offset += n
        n_facets += len(facets)
    cat = {k: np.concatenate(v) for k, v in parts.items()}
    X = cat["X"]
    edges, C, edge_offsets = partition_edges(cat["edges"].astype(np.int64), cat["C"], offset)
    fixed_mask = np.zeros((offset, dim), bool)
    for nodes, c in fixed:
        fixed_mask[nodes, c] = True
    half = 0.5 * (X[edges[:, 1]] - X[edges[:, 0]])
    node_edge_start, node_neighbour, node_C, node_half = node_edge_lists(edges, C, half, offset)
    # boundary faces sorted by node for locality of the scatter
    order = np.argsort(cat["bface_node"], kind="stable")
    return Discretisation(
        X=X, node_material=cat["node_material"], material_table=table,
        body_of_node=cat["body_of_node"], volume=cat["volume"],
        node_length=cat["node_length"], edges=edges, C=C, C_len=np.linalg.norm(C, axis=1),
        half=half, node_edge_start=node_edge_start, node_neighbour=node_neighbour,
        node_C=node_C, node_half=node_half,
        bface_start=np.searchsorted(cat["bface_node"][order], np.arange(offset + 1)),
        bface_node=cat["bface_node"][order].astype(np.int64),
        bface_others=np.ascontiguousarray(cat["bface_others"][order], dtype=np.int64),
        bface_C=cat["bface_C"][order], bface_facet=cat["bface_facet"][order],
        bface_bc=cat["bface_bc"][order].astype(np.int32),
        bc_fixed=np.array(bc_fixed, bool), bc_nodes=bc_nodes, fixed_mask=fixed_mask,
        v0=cat["v0"], edge_offsets=edge_offsets,
        body_start=np.array([b.start for b in layouts] + [offset], np.int64), bodies=layouts)


def node_edge_lists(edges, C, half, n_nodes):
    """Each node's edges in one list (CSR), for loops that gather over nodes instead of
    scattering over edges: start offsets (n + 1), the neighbour, and the area vector and
    midpoint offset X_mid - X_a seen from the node (as stored from an edge's first node,
    negated from its second)."""
    ends = np.concatenate([edges[:, 0], edges[:, 1]])
    order = np.argsort(ends, kind="stable")
    start = np.zeros(n_nodes + 1, np.int64)
    np.cumsum(np.bincount(ends, minlength=n_nodes), out=start[1:])
    neighbour = np.concatenate([edges[:, 1], edges[:, 0]])[order]
    return (start, np.ascontiguousarray(neighbour, dtype=np.int64),
            np.ascontiguousarray(np.concatenate([C, -C])[order]),
            np.ascontiguousarray(np.concatenate([half, -half])[order]))


def partition_edges(edges, C, n_nodes, n_blocks=None):
    """Group the edges by contiguous node blocks so that edge loops run in parallel.

    Nodes are split into ``n_blocks`` ranges with about equal numbers of edges (default: the
    numba thread count). Edges with both ends in block k come first, block by block, then the
    few edges joining two blocks; within a group the (a, b) order is kept for locality.
    Returns the reordered edges and area vectors and the group offsets (n_blocks + 2).
    """
    if n_blocks is None:
        import numba
        n_blocks = max(1, numba.get_num_threads())
    counts = np.bincount(edges[:, 0], minlength=n_nodes)
    cumulative = np.cumsum(counts)
    bounds = np.searchsorted(cumulative, np.arange(1, n_blocks) * len(edges) / n_blocks)
    block_a = np.searchsorted(bounds, edges[:, 0], side="right")
    block_b = np.searchsorted(bounds, edges[:, 1], side="right")
    group = np.where(block_a == block_b, block_a, n_blocks)
    order = np.argsort(group, kind="stable")
    offsets = np.concatenate([[0], np.cumsum(np.bincount(group, minlength=n_blocks + 1))])
    return edges[order], C[order], offsets.astype(np.int64)
