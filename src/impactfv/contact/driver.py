"""The contact driver: the contact surfaces of a case and one Runge-Kutta stage of contact.

Each [[contact]] pairs two bodies (both treated alike: the nodes of each are checked against
the segments of the other, each pass contributing half the force) or one body and a rigid
wall. Per stage: search -> overlap -> Riemann step -> assembly. Active contact nodes take
the Riemann contact velocity in their F equation and their positions, and the Riemann
traction in their momentum equation, in place of the free boundary flux of their faces.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..backends.cpu import dim_tag
from ..geometry.bins import build_bins
from ..geometry.surfaces import surface_facets
from ..mesh.edges import facet_index
from . import riemann_step as RS
from .overlap import contact_pieces
from .search import find_partners, surface_geometry, wall_gaps


@dataclass
class Surface:
    """The contact surface of one body in one contact."""

    nodes: np.ndarray   # its nodes
    facets: np.ndarray  # its boundary facets (segments in 2D)
    faces: np.ndarray   # the dual boundary faces on them


@dataclass
class Pair:
    """One [[contact]]: two surfaces in body order, or one surface and a wall."""

    index: int
    surfaces: list
    stick: bool
    flip: float                     # -1 when the case names the bodies in reverse order
    wall_point: np.ndarray = None
    wall_normal: np.ndarray = None  # out of the wall
    wall_velocity: np.ndarray = None
    gap: float = np.nan
    fsum: np.ndarray = None         # force on the first body, per stage


class ContactSystem:
    def __init__(self, case, disc):
        n, d = disc.n_nodes, disc.dim
        self.disc = disc
        self.dim = dim_tag(d)
        self.pairs = []
        for k, spec in enumerate(case.contacts):
            # passes run in body order whatever the order in the case, so that swapping the
            # names in `bodies` gives bit-identical results; `flip` restores the sign
            names = sorted(spec.bodies, key=disc.body_index)
            pair = Pair(k, [self._surface(case, disc, name, spec.regions, k) for name in names],
                        spec.model == "stick", -1.0 if names[0] != spec.bodies[0] else 1.0,
                        fsum=np.zeros((2, d)))
            if spec.wall is not None:
                normal = np.array(spec.wall.normal, float)
                pair.wall_point = np.array(spec.wall.point, float)
                pair.wall_normal = normal / np.linalg.norm(normal)
                pair.wall_velocity = np.array(spec.wall.velocity, float)
            self.pairs.append(pair)
        surfaces = [s for p in self.pairs for s in p.surfaces]
        all_facets = np.concatenate([s.facets for s in surfaces])
        lengths = np.linalg.norm(disc.X[all_facets[:, 1]] - disc.X[all_facets[:, 0]], axis=1)
        self.pad = 2.0 * lengths.max()
        self.surface_nodes = np.unique(np.concatenate([s.nodes for s in surfaces]))
        self.faces = np.unique(np.concatenate([s.faces for s in surfaces]))
        h = len(disc.bface_node)
        self.face_active = np.zeros(h, bool)
        self.face_velocity = np.zeros((h, d))  # overlap-weighted v* per face
        self.cover = np.zeros(h)               # fraction of each face in contact
        # contact faces of each node (CSR over all nodes)
        owners = disc.bface_node[self.faces]
        self.face_list = self.faces[np.argsort(owners, kind="stable")]
        self.face_start = np.concatenate([[0], np.cumsum(np.bincount(owners, minlength=n))])
        self.state = np.zeros(n, np.int8)       # OPEN, STICK or SLIP
        self.was_active = np.zeros(n, np.int8)
        self.vstar = np.zeros((n, d))
        self.xdot = np.zeros((n, d))            # velocity moving the positions of contact nodes
        self.tstar_n = np.zeros(n)
        self.force_acc = np.zeros((n, d))
        self.normal_out = np.zeros((n, d))      # outward surface normal
        self.sig = np.zeros((n, d, d))          # Cauchy stress of surface nodes
        # search results of the current pass
        self.partner = np.full(n, -1, np.int64)
        self.partner_xi = np.zeros(n)
        self.partner_dist = np.zeros(n)
        self.gap = np.zeros(n)
        self.normal = np.zeros((n, d))          # contact normal, from the node into the partner
        # per-node sums of the Riemann step
        self.length_sum = np.zeros(n)
        self.velocity_sum = np.zeros((n, d))
        self.traction_sum = np.zeros(n)
        self._pieces(4 * len(self.faces) + 16)
        self.wall_faces = np.zeros(max(int(np.diff(self.face_start).max()), 1), np.int64)

    def _pieces(self, capacity):
        d = self.disc.dim
        self.piece_node = np.zeros(capacity, np.int64)
        self.piece_face = np.zeros(capacity, np.int64)
        self.piece_partner = np.zeros(capacity, np.int64)
        self.piece_length = np.zeros(capacity)
        self.piece_face_length = np.zeros(capacity)
        self.piece_normal = np.zeros((capacity, d))

    @staticmethod
    def _surface(case, disc, name, regions, k):
        layout = disc.bodies[disc.body_index(name)]
        facets = surface_facets(layout.facets, layout.regions, regions,
                                f"{case.source}: contact[{k}].regions", name)
        facet_ids = facet_index(layout.facets, facets, f"contact[{k}]") + layout.facet_offset
        faces = np.flatnonzero(np.isin(disc.bface_facet, facet_ids))
        return Surface(np.unique(facets), facets, faces)

    # ------------------------------------------------------------------ per stage
    def stage(self, x, v, F, dt, stage_index):
        """Contact states and forces for the current stage (before the flux assembly)."""
        if stage_index == 1:
            # a node that touched in stage 1 stays a candidate in stage 2 (no chattering)
            nodes = self.surface_nodes
            self.was_active[nodes] = np.maximum(self.was_active[nodes], self.state[nodes])
        RS.reset_surface(self.surface_nodes, self.faces, self.state, self.force_acc,
                         self.tstar_n, self.face_velocity, self.cover, self.length_sum,
                         self.velocity_sum, self.traction_sum)
        self._geometry(x, F)
        for pair in self.pairs:
            fsum = pair.fsum[stage_index]
            fsum[:] = 0.0
            self._passes(pair, x, v, F, dt, True, fsum)
        RS.mark_contact_faces(self.faces, self.cover, self.face_active)

    def _geometry(self, x, F):
        disc = self.disc
        for pair in self.pairs:
            for s in pair.surfaces:
                surface_geometry(x, F, disc.node_material, disc.material_table, s.nodes,
                                 s.facets, self.normal_out, self.sig)

    def _passes(self, pair, x, v, F, dt, apply, fsum):
        """Search (and with ``apply`` the overlap and Riemann steps) of one contact; returns
        the smallest gap."""
        disc = self.disc
        if pair.wall_normal is not None:
            slave = pair.surfaces[0].nodes
            gmin = wall_gaps(x, slave, pair.wall_point, pair.wall_normal, self.gap,
                             self.normal)
            if apply:
                RS.wall_pass(v, F, self.sig, disc.node_material, disc.material_table, slave,
                             self.face_start, self.face_list, disc.bface_C,
                             self.face_velocity, self.cover, disc.node_length, self.gap,
                             self.normal, pair.wall_velocity, dt, pair.stick,
                             self.was_active, self.wall_faces, self.state, self.vstar,
                             self.xdot, self.tstar_n, self.force_acc, fsum, self.dim)
            return gmin
        gmin = np.inf
        for first, (slave, master) in enumerate(((0, 1), (1, 0))):
            slave_nodes = pair.surfaces[slave].nodes
            segs = pair.surfaces[master].facets
            bins = build_bins(x, segs, self.pad)
            g = find_partners(x, slave_nodes, self.normal_out, segs, *bins, self.pad,
                              self.partner, self.partner_xi, self.partner_dist, self.gap,
                              self.normal)
            gmin = min(gmin, g)
            if not apply:
                continue
            count = self._contact_pieces(x, v, dt, slave_nodes, segs, bins)
            self.length_sum[slave_nodes] = 0.0
            self.velocity_sum[slave_nodes] = 0.0
            self.traction_sum[slave_nodes] = 0.0
            RS.piece_states(v, self.sig, disc.node_material, disc.material_table, count,
                            self.piece_node, self.piece_face, self.piece_partner,
                            self.piece_length, self.piece_face_length, self.piece_normal, 0.5,
                            1.0 if first == 0 else -1.0, pair.stick, self.force_acc, fsum,
                            self.face_velocity, self.cover, self.length_sum,
                            self.velocity_sum, self.traction_sum, self.dim)
            RS.settle_nodes(slave_nodes, v, dt, 0.5, pair.stick, self.gap, self.normal,
                            self.length_sum, self.velocity_sum, self.traction_sum, self.state,
                            self.vstar, self.xdot, self.tstar_n, self.dim)
        return gmin

    def _contact_pieces(self, x, v, dt, slave_nodes, segs, bins):
        disc = self.disc
        while True:
            count = contact_pieces(x, v, slave_nodes, self.partner, self.partner_xi,
                                   self.partner_dist, self.gap, self.normal, self.was_active,
                                   disc.node_length, dt, self.face_start, self.face_list,
                                   disc.bface_others, segs, *bins, self.piece_node,
                                   self.piece_face, self.piece_partner, self.piece_length,
                                   self.piece_face_length, self.piece_normal)
            if count <= len(self.piece_node):
                return count
            self._pieces(2 * count)

    def apply(self, force, dF):
        disc = self.disc
        RS.apply_contact(self.surface_nodes, self.faces, disc.bface_node, disc.bface_C,
                         self.face_active, self.face_velocity, self.cover, self.state,
                         self.vstar, self.xdot, self.force_acc, disc.fixed_mask,
                         disc.fixed_value, force, dF)

    def end_step(self, x, v, F):
        """Remember who is in contact; measure the gaps at the new positions."""
        self.was_active[self.surface_nodes] = self.state[self.surface_nodes]
        self._geometry(x, F)
        scratch = np.zeros(self.disc.dim)
        for pair in self.pairs:
            g = self._passes(pair, x, v, F, 0.0, False, scratch)
            pair.gap = g if np.isfinite(g) else np.nan

    def history_columns(self):
        components = "xyz"[:self.disc.dim]
        return [f"contact{p.index}_{c}" for p in self.pairs
                for c in [f"f{k}" for k in components] + ["gap"]]

    def history_values(self):
        """Force on the first body (Runge-Kutta average of the two stages) and smallest gap."""
        out = []
        for pair in self.pairs:
            f = pair.flip * 0.5 * (pair.fsum[0] + pair.fsum[1])
            out += [*f, pair.gap]
        return out
