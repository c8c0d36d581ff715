"""The contact driver: the contact surfaces of a case and one Runge-Kutta stage of contact.

Each [[contact]] pairs two bodies (both treated alike: the nodes of each are checked against
the segments of the other, each pass contributing half the force) or one body and a rigid
wall. Per stage: search -> overlap -> Riemann step -> assembly. Contact nodes take the
contact velocity in their F equation and their motion, and the Riemann traction in their
momentum equation, in place of the free boundary flux of their faces, for the part of the
face and of the step they are in contact (docs/contact.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..compiled import dim_tag
from ..geometry.bins import build_bins
from ..geometry.surfaces import surface_facets
from ..mesh.edges import facet_index
from . import riemann_step as RS
from .overlap import (ContactFaces, Discretisation, Pieces, boundary_straightness,
                      closing_fractions, contact_pieces)
from .search import (BESIDE_IS_OPEN, BESIDE_MEASURED, BESIDE_OFFSET, Bins, Partners, Skip,
                     find_partners, forget_partners, near_each_other, surface_normals,
                     wall_gaps)

#: self-contact: a facet whose plane a node lies behind, deeper than this fraction of the
#: facet's length, is the body's own other side across a wall, not a partner (with the
#: reference configuration's test of search.closest_facet, which this enables)
SELF_CONTACT_DEEPEST = 0.5


class ContactStage(NamedTuple):
    """What one contact stage decides for the bodies' equations (ContactSystem.stage): per
    node its contact mode (OPEN 0, STICK 1, SLIP 2; the smoothness switch leaves the edges
    of nodes in contact) and the velocity that moves it (complete after ContactSystem.apply),
    per dual boundary face the part of face and step in contact (the free boundary flux
    keeps the rest), and the nodes whose reconstruction gradients the stage drops."""

    state: np.ndarray
    xdot: np.ndarray
    face_weight: np.ndarray
    first_order: np.ndarray

    @classmethod
    def none(cls, n_nodes, n_faces, dim):
        """No contact: every node open, every face free."""
        return cls(np.zeros(n_nodes, np.int8), np.zeros((n_nodes, dim)), np.zeros(n_faces),
                   np.zeros(0, np.int64))


@dataclass
class Surface:
    """The contact surface of one body in one contact."""

    nodes: np.ndarray          # its nodes
    facets: np.ndarray         # its boundary facets (segments in 2D, triangles in 3D)
    faces: np.ndarray          # the dual boundary faces on them
    facet_faces: np.ndarray    # per facet, the dual faces of its d nodes on it


@dataclass
class Pair:
    """One [[contact]]: two surfaces in body order, or one surface and a wall."""

    index: int
    surfaces: list
    friction: float                 # Coulomb coefficient: 0 slip, inf stick
    flip: float                     # -1 when the case names the bodies in reverse order
    wall_point: np.ndarray = None
    wall_normal: np.ndarray = None  # out of the wall
    wall_velocity: np.ndarray = None
    gap: float = np.nan
    fsum: np.ndarray = None         # force on the first body, per stage
    self_contact: bool = False      # one surface against itself
    skip: tuple = None              # (CSR) the neighbours a self-contact node cannot touch
    # per node, for this contact alone (a node may touch several partners): its contact
    # mode in this stage, whether it was in contact at the end of the previous step, and
    # the fraction of this step it spends in contact
    nodes: np.ndarray = None
    state: np.ndarray = None
    memory: np.ndarray = None
    phi: np.ndarray = None


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
                        spec.friction_coefficient, -1.0 if names[0] != spec.bodies[0] else 1.0,
                        fsum=np.zeros((2, d)))
            if spec.wall is not None:
                normal = np.array(spec.wall.normal, float)
                pair.wall_point = np.array(spec.wall.point, float)
                pair.wall_normal = normal / np.linalg.norm(normal)
                pair.wall_velocity = np.array(spec.wall.velocity, float)
            pair.self_contact = bool(spec.self_contact)
            pair.nodes = np.unique(np.concatenate([s.nodes for s in pair.surfaces]))
            pair.state = np.zeros(n, np.int8)
            pair.memory = np.zeros(n, np.int8)
            pair.phi = np.zeros(n)
            self.pairs.append(pair)
        surfaces = [s for p in self.pairs for s in p.surfaces]
        all_facets = np.concatenate([s.facets for s in surfaces])
        lengths = max(np.linalg.norm(disc.X[all_facets[:, (k + 1) % d]]
                                     - disc.X[all_facets[:, k]], axis=1).max()
                      for k in range(d if d == 3 else 1))
        # search radius: a node farther than two facets from the partner cannot touch it
        # within a step (it moves far less than a facet per step at any stable time step)
        self.pad = 2.0 * lengths
        self.surface_nodes = np.unique(np.concatenate([s.nodes for s in surfaces]))
        self.faces = np.unique(np.concatenate([s.faces for s in surfaces]))
        # a self-contact surface does not touch itself next to a node: the nodes that share a
        # facet with it (CSR over all nodes; empty for the contacts between two bodies)
        self.no_skip = Skip(np.zeros(n + 1, np.int64), np.zeros(0, np.int64))
        for pair in self.pairs:
            if pair.self_contact:
                pair.skip = Skip(*self._neighbours(pair.surfaces[0].facets, n))
        h = len(disc.bface_node)
        self.face_weight = np.zeros(h)         # fraction of each face and step in contact
        self.face_velocity = np.zeros((h, d))  # contact velocity per face, times face_weight
        # contact faces of each node (CSR over all nodes)
        owners = disc.bface_node[self.faces]
        self.face_list = self.faces[np.argsort(owners, kind="stable")]
        self.face_start = np.concatenate([[0], np.cumsum(np.bincount(owners, minlength=n))])
        self.straightness = boundary_straightness(disc.X, disc.bface_node, disc.bface_others)
        # nodes all of whose boundary faces are contact faces (not the ends of a contact face)
        self.flat = np.diff(self.face_start) == np.bincount(disc.bface_node, minlength=n)
        self.flat &= np.diff(self.face_start) > 0
        self.time = 0.0                         # time of the current stage
        self.state = np.zeros(n, np.int8)       # OPEN, STICK or SLIP (the highest of the
                                                # node's contacts)
        self.xdot = np.zeros((n, d))            # velocity moving the positions of contact nodes
        self.tstar_n = np.zeros(n)
        self.force_acc = np.zeros((n, d))
        self.normal_out = np.zeros((n, d))      # outward surface normal
        # search results of the current pass
        self.partner = np.full(n, -1, np.int64)
        self.partner_w = np.zeros((n, d))      # barycentric weights of the closest point
        self.partner_dist = np.zeros(n)
        self.gap = np.zeros(n)
        self.normal = np.zeros((n, d))          # contact normal, from the node into the partner
        # per-node sums of the Riemann step
        self.length_sum = np.zeros(n)
        self.motion_sum = np.zeros((n, d))
        self.traction_sum = np.zeros(n)
        # corners that follow the partner's surface in this stage (riemann_step.mark_followers)
        self.follower = np.zeros(n, np.bool_)
        self.follow_nodes = np.zeros((n, d), np.int64)
        self.follow_w = np.zeros((n, d))
        self.follow_normal = np.zeros((n, d))
        self.follow_phi = np.zeros(n)
        self._pieces(4 * len(self.faces) + 16)
        # the slave nodes and master facets of a pass that are near each other
        self.slave_near = np.zeros(n, np.int64)
        self.facets_near = np.zeros(max(len(s.facets) for s in surfaces), np.int64)
        self.wall_face_buffer = np.zeros(max(int(np.diff(self.face_start).max()), 1), np.int64)
        self._bundles()

    def _bundles(self):
        """The arrays the compiled passes take, bundled once (the same array objects: what
        the passes write lands in the attributes above); the pieces' bundle is made with
        their arrays (_pieces)."""
        disc = self.disc
        self.disc_arrays = Discretisation(disc.X, disc.bface_C, disc.bface_others,
                                          disc.node_material, disc.material_table)
        self.contact_faces = ContactFaces(self.face_start, self.face_list, self.face_weight,
                                          self.face_velocity)
        self.found = Partners(self.partner, self.partner_w, self.partner_dist, self.gap,
                              self.normal)
        self.sums = RS.NodeSums(self.force_acc, self.length_sum, self.motion_sum,
                                self.traction_sum)

    #: how far along its surface a self-contact node is blind to its own facets: three rings
    #: of facets reach beyond the search radius (two facet lengths) along a flat or convex
    #: surface, so that a node near an edge or corner of the body does not take the facets
    #: round that corner for a partner
    SELF_CONTACT_RINGS = 3

    @classmethod
    def _neighbours(cls, facets, n):
        """Per node, the nodes within SELF_CONTACT_RINGS facets of it on its surface, itself
        included (CSR)."""
        import scipy.sparse as sp

        d = facets.shape[1]
        a = np.concatenate([facets[:, i] for i in range(d) for j in range(d)])
        b = np.concatenate([facets[:, j] for i in range(d) for j in range(d)])
        ring = sp.csr_matrix((np.ones(len(a), np.int8), (a, b)), shape=(n, n))
        reach = ring
        for _ in range(cls.SELF_CONTACT_RINGS - 1):
            reach = (reach @ ring).astype(bool).astype(np.int8)
        reach = reach.tocsr()
        reach.sort_indices()
        return (np.asarray(reach.indptr, np.int64),
                np.ascontiguousarray(reach.indices, dtype=np.int64))

    def _pieces(self, capacity):
        d = self.disc.dim
        self.piece_node = np.zeros(capacity, np.int64)
        self.piece_face = np.zeros(capacity, np.int64)
        self.piece_partner = np.zeros(capacity, np.int64)
        self.piece_segment = np.zeros(capacity, np.int64)
        self.piece_length = np.zeros(capacity)
        self.piece_face_length = np.zeros(capacity)
        self.piece_normal = np.zeros((capacity, d))
        self.pieces = Pieces(self.piece_node, self.piece_face, self.piece_partner,
                             self.piece_segment, self.piece_length, self.piece_face_length,
                             self.piece_normal)

    @staticmethod
    def _surface(case, disc, name, regions, k):
        layout = disc.bodies[disc.body_index(name)]
        facets = surface_facets(layout.facets, layout.regions, regions,
                                f"{case.source}: contact[{k}].regions", name)
        facet_ids = facet_index(layout.facets, facets, f"contact[{k}]") + layout.facet_offset
        faces = np.flatnonzero(np.isin(disc.bface_facet, facet_ids))
        # the d dual faces on each facet, in the order of the facet's nodes
        facet_faces = np.full(facets.shape, -1, np.int64)
        row = np.full(disc.bface_facet.max() + 1, -1, np.int64)
        row[facet_ids] = np.arange(len(facet_ids))
        k = row[disc.bface_facet[faces]]
        position = np.argmax(facets[k] == disc.bface_node[faces][:, None], axis=1)
        facet_faces[k, position] = faces
        return Surface(np.unique(facets), facets, faces, facet_faces)

    # ------------------------------------------------------------------ per stage
    def stage(self, x, v, F, sigma, dt, stage_index, time=0.0) -> ContactStage:
        """Contact states and forces for the current stage, from the state's velocities and
        stresses (before the flux assembly). Which nodes touch during the step, and when, is
        decided in the first stage and kept in the second. ``time`` is the stage's time
        (where moving walls are). The arrays of the result are the system's own, rewritten
        by the next stage."""
        self.time = time
        RS.reset_surface(self.surface_nodes, self.faces, self.state, self.force_acc,
                         self.tstar_n, self.face_weight, self.face_velocity, self.length_sum,
                         self.motion_sum, self.traction_sum)
        if not self._finite(x):
            return self._result()
        self._geometry(x)
        self.follower[self.surface_nodes] = False
        for pair in self.pairs:
            fsum = pair.fsum[stage_index]
            fsum[:] = 0.0
            pair.state[pair.nodes] = 0
            self._passes(pair, x, v, F, sigma, dt, stage_index, fsum)
            self.state[pair.nodes] = np.maximum(self.state[pair.nodes], pair.state[pair.nodes])
        RS.settle_nodes(self.surface_nodes, self.faces, v, self.length_sum, self.motion_sum,
                        self.traction_sum, self.face_weight, self.face_velocity, self.xdot,
                        self.tstar_n)
        # corners pressing into a face move with it (docs/contact.md, step 6)
        RS.follow_partner_surfaces(self.surface_nodes, self.follower, self.follow_nodes,
                                   self.follow_w, self.follow_normal, self.follow_phi,
                                   self.state, v, self.xdot, self.face_start, self.face_list,
                                   self.face_weight, self.face_velocity)
        return self._result()

    def _result(self) -> ContactStage:
        # nodes in contact inside a contact face (every boundary face of theirs on a contact
        # surface) are not reconstructed: their one-sided boundary gradient ignores the
        # partner and makes their velocity ring after the first touch; corner nodes keep
        # theirs (the free side's: zeroing it made the corners drift, docs/contact.md)
        nodes = self.surface_nodes
        first_order = nodes[(self.state[nodes] != RS.OPEN) & self.flat[nodes]]
        return ContactStage(self.state, self.xdot, self.face_weight, first_order)

    def _finite(self, x):
        """A blown-up state (reported by the stepper's check after the step) has no contact
        geometry: the search is skipped rather than run on non-finite positions."""
        return bool(np.isfinite(x[self.surface_nodes]).all())

    def _geometry(self, x):
        for pair in self.pairs:
            for s in pair.surfaces:
                surface_normals(x, s.nodes, s.facets, self.normal_out)

    def _passes(self, pair, x, v, F, sigma, dt, stage_index, fsum):
        """Search, and from a stage on (stage_index >= 0) the overlap and Riemann steps, of
        one contact; returns the smallest gap."""
        apply = stage_index >= 0
        # (sigma is None after the step, when only the gaps are measured)
        state = RS.State(x, v, F, sigma)
        contact = RS.Contact(pair.phi, pair.state, fsum, pair.friction)
        if pair.wall_normal is not None:
            return self._wall_pass(pair, state, contact, dt, stage_index)
        gmin = np.inf
        # two bodies: each one's nodes against the other's facets, half the force each;
        # self-contact: the surface against itself once, which finds both sides of every
        # touching part (so also half the force each)
        passes = ((0, 0),) if pair.self_contact else ((0, 1), (1, 0))
        skip = pair.skip if pair.self_contact else self.no_skip
        for first, (slave, master) in enumerate(passes):
            slave_nodes = pair.surfaces[slave].nodes
            surface = pair.surfaces[master]
            # only the parts of the two surfaces within the search radius of each other
            n_near, n_facets = near_each_other(x, slave_nodes, surface.facets, self.pad,
                                               self.slave_near, self.facets_near)
            forget_partners(slave_nodes, self.partner)
            if n_near == 0 or n_facets == 0:
                if apply and stage_index == 0:   # no partner: phi from the memory alone
                    closing_fractions(x, v, slave_nodes, self.found, surface.facets,
                                      pair.memory, dt, pair.phi)
                continue
            near = self.slave_near[:n_near]
            chosen = self.facets_near[:n_facets]
            segs = surface.facets[chosen]
            segment_faces = surface.facet_faces[chosen]
            bins = Bins(*build_bins(x, segs, self.pad))
            g = find_partners(x, self.disc.X, near, self.normal_out, segs, bins, self.pad,
                              self.found, skip, self._beside(pair, apply),
                              SELF_CONTACT_DEEPEST if pair.self_contact else 0.0)
            gmin = min(gmin, g)
            if not apply:
                continue
            if stage_index == 0:
                closing_fractions(x, v, slave_nodes, self.found, segs, pair.memory, dt,
                                  pair.phi)
            if not pair.self_contact:
                RS.mark_followers(near, self.found, pair.phi, segs, self.straightness,
                                  self.follower, self.follow_nodes, self.follow_w,
                                  self.follow_normal, self.follow_phi)
            count = self._contact_pieces(x, near, segs, bins, skip, pair.phi,
                                         SELF_CONTACT_DEEPEST if pair.self_contact else 0.0)
            RS.piece_states(self.disc_arrays, state, segs, segment_faces, self.pieces, count,
                            contact, 0.5, 1.0 if first == 0 else -1.0, self.contact_faces,
                            self.sums, self.dim)
        return gmin

    def _wall_pass(self, pair, state, contact, dt, stage_index):
        """The gaps to a wall, and from a stage on the wall's contact; returns the smallest
        gap."""
        slave = pair.surfaces[0].nodes
        # a moving wall translates rigidly with its velocity
        point = pair.wall_point + pair.wall_velocity * self.time
        gmin = wall_gaps(state.x, slave, point, pair.wall_normal, self.gap, self.normal)
        if stage_index >= 0:
            if stage_index == 0:
                RS.wall_fractions(state.v, slave, self.gap, self.normal, pair.wall_velocity,
                                  pair.memory, dt, pair.phi)
            RS.wall_pass(self.disc_arrays, state, slave, self.normal, pair.wall_velocity,
                         contact, self.wall_face_buffer, self.contact_faces, self.sums,
                         self.dim)
        return gmin

    def _beside(self, pair, stage):
        """What the gap of a node beside its partner facet is (search.find_partners)."""
        if self.disc.dim == 3 or pair.self_contact:
            return BESIDE_IS_OPEN
        return BESIDE_OFFSET if stage else BESIDE_MEASURED

    def _contact_pieces(self, x, slave_nodes, segs, bins, skip, phi, deepest):
        """The pieces of the slave nodes against the facets segs (with their Bins; ``skip``:
        a self-contact's Skip, or no_skip) into self.pieces, grown until they fit; returns
        their number (overlap.contact_pieces)."""
        while True:
            count = contact_pieces(x, self.disc_arrays, slave_nodes, self.found, phi,
                                   self.contact_faces, self.straightness, segs, bins,
                                   self.pieces, skip, self.pad, deepest)
            if count <= len(self.piece_node):
                return count
            self._pieces(2 * count)

    def apply(self, force, dF, fixed_value):
        """Add the stage's contact forces to force and its contact faces' terms to dF, and
        give the velocity components prescribed by a boundary condition to the contact
        velocity of the nodes in contact (riemann_step.apply_contact)."""
        disc = self.disc
        RS.apply_contact(self.surface_nodes, self.faces, disc.bface_node, disc.bface_C,
                         self.face_weight, self.face_velocity, self.state, self.xdot,
                         self.force_acc, disc.fixed_mask, fixed_value, force, dF)

    def wall_power(self, stage_index) -> float:
        """Power of the walls' forces on the bodies in this stage: F . v_wall (zero for walls
        at rest; contact between bodies does no external work)."""
        return float(sum(pair.fsum[stage_index] @ pair.wall_velocity for pair in self.pairs
                         if pair.wall_normal is not None))

    @property
    def memory(self) -> np.ndarray:
        """Who was in contact at the end of the step, per contact (contacts x nodes)."""
        return np.stack([pair.memory for pair in self.pairs])

    def restore_memory(self, memory):
        for pair, row in zip(self.pairs, np.atleast_2d(memory)):
            pair.memory[:] = row

    def end_step(self, x, v, F, time=0.0):
        """Remember who is in contact; measure the gaps at the new positions."""
        self.time = time
        for pair in self.pairs:
            pair.memory[pair.nodes] = pair.state[pair.nodes]
        if not self._finite(x):
            return
        self._geometry(x)
        scratch = np.zeros(self.disc.dim)
        for pair in self.pairs:
            g = self._passes(pair, x, v, F, None, 0.0, -1, scratch)
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
