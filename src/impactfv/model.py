"""Assembly of a validated case into flat arrays the kernels stream over.

All bodies share one set of node, edge and boundary arrays; edges never cross bodies, so
the interior scheme sees them as separate. Each body's nodes are renumbered for locality
(reverse Cuthill-McKee) and its edges sorted by node.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .case import Case
from .materials import N_PROPS
from .mesh.dual import median_dual
from .mesh.trimesh import renumber_for_locality


@dataclass
class BodyLayout:
    name: str
    start: int          # first global node
    stop: int           # one past the last
    triangles: np.ndarray  # global node indices
    regions: dict[str, np.ndarray]  # boundary edges per region, global indices
    boundary_edges: np.ndarray  # all boundary edges (global), body on the left of a->b
    material: object = None
    boundary_offset: int = 0    # index of its first boundary edge in the model's numbering


@dataclass
class Model:
    X: np.ndarray            # (n,2) reference positions
    node_mat: np.ndarray     # (n,) int32 material row
    mat: np.ndarray          # (nmat, N_PROPS)
    body_of_node: np.ndarray  # (n,) int32
    omega: np.ndarray        # (n,) dual areas
    node_length: np.ndarray  # (n,) shortest incident edge
    edges: np.ndarray        # (m,2)
    C: np.ndarray            # (m,2) area vectors
    C_len: np.ndarray        # (m,)
    half: np.ndarray         # (m,2) X_mid - X_a = (X_b - X_a)/2
    hb_node: np.ndarray      # (h,) node of each boundary half-edge
    hb_other: np.ndarray     # (h,) the other end of its boundary edge
    hb_C: np.ndarray         # (h,2) (L/2) N
    hb_edge: np.ndarray      # (h,) index of its boundary edge
    hb_bc: np.ndarray        # (h,) row of the boundary-condition table (0: traction-free)
    bc_fix: np.ndarray       # (nbc,2) bool: velocity component prescribed
    bc_v: np.ndarray         # (nbc,2)
    bc_t: np.ndarray         # (nbc,2)
    fixed_mask: np.ndarray   # (n,2) bool: strongly prescribed nodal velocity components
    fixed_value: np.ndarray  # (n,2)
    v0: np.ndarray           # (n,2) initial velocity
    edge_offsets: np.ndarray = None  # (nblocks+2,) edges grouped by node block, then cross
    body_start: np.ndarray = None    # (nbodies+1,) first node of each body
    bodies: list[BodyLayout] = field(default_factory=list)

    @property
    def n_nodes(self) -> int:
        return len(self.X)

    @property
    def n_edges(self) -> int:
        return len(self.edges)

    def body_index(self, name: str) -> int:
        return [b.name for b in self.bodies].index(name)


def build_model(case: Case) -> Model:
    mat_names = list(case.materials)
    mat = np.array([case.materials[k].table_row() for k in mat_names]).reshape(-1, N_PROPS)
    X, node_mat, body_of_node, omega, node_length = [], [], [], [], []
    edges, C, hb_node, hb_other, hb_C, hb_bc, hb_edge, v0 = [], [], [], [], [], [], [], []
    layouts = []
    bc_fix, bc_v, bc_t = [[False, False]], [[0.0, 0.0]], [[0.0, 0.0]]
    fixed_nodes = []  # (global node, component, value)
    offset = 0
    n_bnd = 0
    for ib, body in enumerate(case.bodies):
        mesh, _ = renumber_for_locality(body.mesh)
        dual = median_dual(mesh.points, mesh.triangles)
        n = mesh.n_nodes
        X.append(mesh.points)
        node_mat.append(np.full(n, mat_names.index(body.material.name), np.int32))
        body_of_node.append(np.full(n, ib, np.int32))
        omega.append(dual.dual_areas)
        node_length.append(dual.node_length)
        order = np.lexsort((dual.edges[:, 1], dual.edges[:, 0]))
        edges.append(dual.edges[order] + offset)
        C.append(dual.area_vectors[order])
        v0.append(body.initial_velocity(mesh.points))
        # boundary condition row per boundary edge (later entries override earlier ones)
        bnd = dual.boundary_edges
        edge_bc = np.zeros(len(bnd), np.int32)
        index = {(int(a), int(b)): k for k, (a, b) in enumerate(bnd)}
        for spec in body.boundary:
            rows = np.array([index[(int(a), int(b))] for a, b in mesh.regions[spec.region]])
            fix = [False, False]
            vel = [0.0, 0.0]
            trac = [0.0, 0.0]
            if spec.velocity is not None:
                for c, value in enumerate((spec.velocity.x, spec.velocity.y)):
                    if value is not None:
                        fix[c] = True
                        vel[c] = value
                        for node in np.unique(mesh.regions[spec.region]):
                            fixed_nodes.append((offset + node, c, value))
            if spec.traction is not None:
                trac = list(spec.traction)
            bc_fix.append(fix)
            bc_v.append(vel)
            bc_t.append(trac)
            edge_bc[rows] = len(bc_fix) - 1
        for side in (0, 1):
            hb_node.append(bnd[:, side] + offset)
            hb_other.append(bnd[:, 1 - side] + offset)
            hb_C.append(dual.boundary_normals)
            hb_bc.append(edge_bc)
            hb_edge.append(np.arange(len(bnd)) + n_bnd)
        layouts.append(BodyLayout(body.name, offset, offset + n, mesh.triangles + offset,
                                  {k: v + offset for k, v in mesh.regions.items()},
                                  bnd + offset, body.material, n_bnd))
        offset += n
        n_bnd += len(bnd)
    X = np.concatenate(X)
    edges = np.concatenate(edges).astype(np.int64)
    C = np.concatenate(C)
    edges, C, edge_offsets = partition_edges(edges, C, offset)
    fixed_mask = np.zeros((offset, 2), bool)
    fixed_value = np.zeros((offset, 2))
    for node, c, value in fixed_nodes:
        fixed_mask[node, c] = True
        fixed_value[node, c] = value
    v0 = np.concatenate(v0)
    v0[fixed_mask] = fixed_value[fixed_mask]
    # half-edges sorted by node for locality of the scatter
    hb_node = np.concatenate(hb_node)
    order = np.argsort(hb_node, kind="stable")
    return Model(
        X=X, node_mat=np.concatenate(node_mat), mat=mat,
        body_of_node=np.concatenate(body_of_node), omega=np.concatenate(omega),
        node_length=np.concatenate(node_length), edges=edges, C=C,
        C_len=np.linalg.norm(C, axis=1), half=0.5 * (X[edges[:, 1]] - X[edges[:, 0]]),
        hb_node=hb_node[order].astype(np.int64),
        hb_other=np.concatenate(hb_other)[order].astype(np.int64),
        hb_C=np.concatenate(hb_C)[order], hb_edge=np.concatenate(hb_edge)[order],
        hb_bc=np.concatenate(hb_bc)[order].astype(np.int32),
        bc_fix=np.array(bc_fix, bool), bc_v=np.array(bc_v, float), bc_t=np.array(bc_t, float),
        fixed_mask=fixed_mask, fixed_value=fixed_value, v0=v0, edge_offsets=edge_offsets,
        body_start=np.array([b.start for b in layouts] + [offset], np.int64), bodies=layouts)


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
