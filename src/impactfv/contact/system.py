"""Contact surfaces of a case and the per-stage contact computation.

Each [[contact]] pairs two bodies (both treated alike: nodes of each are checked against
the segments of the other, and each pass contributes half the force) or one body and a
rigid wall. Active contact nodes take the Riemann contact velocity in their F equation and
their positions, and the Riemann traction in their momentum equation, in place of the free
boundary flux of their contact half-edges.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from . import kernels as CK


class _Surface:
    def __init__(self, nodes, segs, hb):
        self.nodes = nodes
        self.segs = segs
        self.hb = hb


class ContactSystem:
    def __init__(self, case, model):
        n = model.n_nodes
        self.model = model
        self.pairs = []
        contact_hb = []
        for k, spec in enumerate(case.contacts):
            # passes run in body order whatever the order in the case, so that swapping the
            # names in `bodies` gives bit-identical results; `flip` restores the sign
            names = sorted(spec.bodies, key=model.body_index)
            surfaces = [self._surface(model, name, spec.regions, k) for name in names]
            contact_hb += [s.hb for s in surfaces]
            entry = {"spec": spec, "surfaces": surfaces, "stick": spec.model == "stick",
                     "fsum": np.zeros((2, 2)), "gap": np.nan,
                     "flip": -1.0 if names[0] != spec.bodies[0] else 1.0}
            if spec.wall is not None:
                nw = np.array(spec.wall.normal, float)
                entry["p0"] = np.array(spec.wall.point, float)
                entry["nw"] = nw / np.linalg.norm(nw)
                entry["wall_v"] = np.array(spec.wall.velocity, float)
            self.pairs.append(entry)
        all_segs = np.concatenate([s.segs for p in self.pairs for s in p["surfaces"]])
        lengths = np.linalg.norm(model.X[all_segs[:, 1]] - model.X[all_segs[:, 0]], axis=1)
        self.pad = 2.0 * lengths.max()
        self.surface_nodes = np.unique(np.concatenate(
            [s.nodes for p in self.pairs for s in p["surfaces"]]))
        self.contact_hb = np.unique(np.concatenate(contact_hb))
        self.hb_active = np.zeros(len(model.hb_node), bool)
        self.vhb = np.zeros((len(model.hb_node), 2))  # overlap-weighted v* per half-edge
        self.cover = np.zeros(len(model.hb_node))     # fraction of each half-edge in contact
        # contact half-edges of each node (CSR over all nodes)
        owners = model.hb_node[self.contact_hb]
        order = np.argsort(owners, kind="stable")
        self.hb_list = self.contact_hb[order]
        self.hb_start = np.zeros(n + 1, np.int64)
        np.add.at(self.hb_start, owners + 1, 1)
        self.hb_start = np.cumsum(self.hb_start)
        self.state = np.zeros(n, np.int8)
        self.was_active = np.zeros(n, np.int8)
        self.vstar = np.zeros((n, 2))
        self.xdot = np.zeros((n, 2))  # velocity moving the positions of contact nodes
        self.tstar_n = np.zeros(n)
        self.force_acc = np.zeros((n, 2))
        self.nrm = np.zeros((n, 2))
        self.sig = np.zeros((n, 3))
        self.stage_index = 0

    @staticmethod
    def _surface(model, name, regions, k):
        ib = model.body_index(name)
        layout = model.bodies[ib]
        if regions is None:
            segs = layout.boundary_edges
        else:
            found = [layout.regions[r] for r in regions if r in layout.regions]
            if not found:
                raise InputError(f"contact[{k}].regions: body {name!r} has none of "
                                 f"{', '.join(regions)} (it has: "
                                 f"{', '.join(sorted(layout.regions)) or 'none'})")
            segs = np.unique(np.concatenate(found), axis=0)
        index = {(int(a), int(b)): i for i, (a, b) in enumerate(layout.boundary_edges)}
        edge_ids = np.array([index[(int(a), int(b))] for a, b in segs]) + layout.boundary_offset
        hb = np.flatnonzero(np.isin(model.hb_edge, edge_ids))
        return _Surface(np.unique(segs), np.ascontiguousarray(segs, dtype=np.int64), hb)

    # ------------------------------------------------------------------ per stage
    def stage(self, x, v, F, dt, stage_index):
        """Contact states and forces for the current stage (before the flux assembly)."""
        if stage_index == 1:
            # a node that touched in stage 1 stays a candidate in stage 2 (no chattering)
            nodes = self.surface_nodes
            self.was_active[nodes] = np.maximum(self.was_active[nodes], self.state[nodes])
        CK.reset_surface(self.surface_nodes, self.contact_hb, self.state, self.force_acc,
                         self.tstar_n, self.vhb, self.cover)
        self._geometry(x, F)
        for pair in self.pairs:
            fsum = pair["fsum"][stage_index]
            fsum[:] = 0.0
            self._passes(pair, x, v, F, dt, True, fsum)
        CK.mark_contact_halfedges(self.contact_hb, self.cover, self.hb_active)

    def _geometry(self, x, F):
        m = self.model
        for pair in self.pairs:
            for s in pair["surfaces"]:
                CK.surface_geometry(x, F, m.node_mat, m.mat, s.nodes, s.segs, self.nrm,
                                    self.sig)

    def _passes(self, pair, x, v, F, dt, apply, fsum):
        m = self.model
        surfaces = pair["surfaces"]
        if "nw" in pair:
            return CK.wall_pass(x, v, F, self.sig, m.node_mat, m.mat, surfaces[0].nodes,
                                self.hb_start, self.hb_list, m.hb_C, self.vhb, self.cover,
                                m.node_length, pair["p0"], pair["nw"], pair["wall_v"], dt,
                                pair["stick"], self.was_active, apply, self.state, self.vstar,
                                self.xdot, self.tstar_n, self.force_acc, fsum)
        gmin = np.inf
        for slave, master, first in ((0, 1, True), (1, 0, False)):
            segs = surfaces[master].segs
            bins = CK.build_bins(x, segs, self.pad)
            g = CK.contact_pass(x, v, F, self.sig, m.node_mat, m.mat, surfaces[slave].nodes,
                                self.nrm, self.hb_start, self.hb_list, m.hb_other, self.vhb,
                                self.cover, m.node_length, segs, *bins, self.pad, dt, 0.5, first,
                                pair["stick"], self.was_active, apply, self.state, self.vstar,
                                self.xdot, self.tstar_n, self.force_acc, fsum)
            gmin = min(gmin, g)
        return gmin

    def apply(self, force, dF):
        m = self.model
        CK.apply_contact(self.surface_nodes, self.contact_hb, m.hb_node, m.hb_C, self.hb_active,
                         self.vhb, self.cover, self.state, self.vstar, self.xdot, self.force_acc, m.fixed_mask,
                         m.fixed_value, force, dF)

    def end_step(self, x, v, F):
        """Remember who is in contact; measure the gaps at the new positions."""
        self.was_active[self.surface_nodes] = self.state[self.surface_nodes]
        self._geometry(x, F)
        scratch = np.zeros(2)
        for pair in self.pairs:
            g = self._passes(pair, x, v, F, 0.0, False, scratch)
            pair["gap"] = g if np.isfinite(g) else np.nan

    def history_columns(self):
        return [f"contact{k}_{c}" for k in range(len(self.pairs)) for c in ("fx", "fy", "gap")]

    def history_values(self):
        """Force on the first body (Runge-Kutta average of the two stages) and smallest gap."""
        out = []
        for pair in self.pairs:
            f = pair["flip"] * 0.5 * (pair["fsum"][0] + pair["fsum"][1])
            out += [f[0], f[1], pair["gap"]]
        return out
