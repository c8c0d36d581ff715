"""What the FV stepper shows of its state: history rows, the frames' point fields, each
body's fields, and checkpoints (FVOutputs, a part of scheme.stepper.FVStepper).

Everything here reads the state through ``_whole_state`` (all nodes; under MPI gathered
from every rank, parallel.stepper) or the owned rows, and never changes the step."""

from __future__ import annotations

import numpy as np

from ..backends import cpu as K
from ..backends.loops import StateValues


class FVOutputs:
    """The output views and checkpoints of scheme.stepper.FVStepper."""

    # ------------------------------------------------------------------ monitors and fields
    def history_columns(self) -> list[str]:
        components = "xyz"[:self.disc.dim]
        momentum = [f"momentum_{c}" for c in components]
        reactions = self.energy.columns(self.disc.dim)
        return (["kinetic_energy", "strain_energy", "total_energy", *momentum,
                 "external_work", "dissipated_energy", "integration_energy", "energy_balance",
                 *reactions]
                + (self.contact.history_columns() if self.contact is not None else []))

    def history_row(self) -> list[float]:
        m = self.disc
        monitors = self.known.monitors
        if monitors is None:     # not computed by the last stage: computed here
            self._host()
            monitors = self.monitor_buf
            K.monitors(self.v, self.F, m.node_material, m.material_table, m.volume,
                       m.body_start, monitors, self.dim)
        kinetic, strain, *momentum = self._sum(monitors).sum(axis=0)
        extra = self.contact.history_values() if self.contact is not None else []
        # the energy balance: what the bodies hold minus the work done on them plus what the
        # scheme dissipated (upwinding at fronts and boundaries, the contacts) minus what the
        # time stepping added; constant up to the third-order part of the time-integration
        # error
        e = self.energy
        balance = kinetic + strain - e.external_work + e.dissipated - e.integration
        return [kinetic, strain, kinetic + strain, *momentum, e.external_work, e.dissipated,
                e.integration, balance, *e.reaction.ravel(), *extra]

    def _whole_state(self):
        """(discretisation, v, F, x, contact status, contact normal traction) of all nodes:
        the outputs' view of the state (under MPI gathered from every rank)."""
        self._host()
        c = self.contact
        return (self.disc, self.v, self.F, self.x, None if c is None else c.state,
                None if c is None else c.tstar_n)

    def point_data(self, whole=None) -> dict[str, np.ndarray]:
        m, v, F, x, status, tstar_n = whole or self._whole_state()
        n = m.n_nodes
        pressure, von_mises, jac = np.empty(n), np.empty(n), np.empty(n)
        stress = np.empty((n, 3, 3))
        K.point_fields(np.ascontiguousarray(F), m.node_material, m.material_table, pressure,
                       von_mises, jac, stress, self.dim)
        data = {"velocity": v, "displacement": x - m.X, "pressure": pressure,
                "von_mises": von_mises, "stress": stress, "J": jac,
                "body": m.body_of_node.astype(np.int32)}
        if status is not None:
            data["contact_status"] = status.astype(np.int32)  # 0 open 1 stick 2 slip
            data["contact_pressure"] = -tstar_n
        return data

    def snapshot(self):
        """(reference points, cells, point data) of all bodies for a ParaView frame."""
        whole = self._whole_state()
        cells = np.concatenate([b.cells for b in whole[0].bodies])
        return whole[0].X, cells, self.point_data(whole)

    def body_fields(self) -> dict[str, dict[str, np.ndarray]]:
        """The point fields of each body (copies), plus its mesh and F."""
        whole = self._whole_state()
        m, _, F, x, status, _ = whole
        data = self.point_data(whole)
        data.pop("body")
        out = {}
        for b in m.bodies:
            s = slice(b.start, b.stop)
            fields = {key: np.array(value[s]) for key, value in data.items()}
            if status is not None:
                fields["contact_status"] = status[s].copy()
            cells = b.cells - b.start
            fields.update(reference_points=m.X[s].copy(), points=x[s].copy(),
                          cells=cells, F=F[s].copy())
            fields["triangles" if m.dim == 2 else "tetrahedra"] = cells
            out[b.name] = fields
        return out

    def summary(self) -> dict:
        return {"nodes": int(self.disc.n_nodes), "edges": int(self.disc.n_edges)}

    # ------------------------------------------------------------------ checkpoints
    def state_arrays(self) -> dict[str, np.ndarray]:
        """Everything a restart needs besides the case."""
        self._host()
        arrays = {"v": self.v, "F": self.F, "x": self.x, "time": np.array(self.time),
                  **self.energy.state()}
        if self.contact is not None:
            arrays["contact_memory"] = self.contact.memory
        if self.known.stress:
            # the stress the last stage computed for the next step (backends.cpu.rk_update_last):
            # the continued run uses it as the uninterrupted one does, to the last bit
            arrays["sigma"] = self.sigma
        return arrays

    def restore(self, arrays) -> None:
        """Continue from ``state_arrays`` of an earlier run of the same case."""
        for name in ("v", "F", "x"):
            target = getattr(self, name)
            if arrays[name].shape != target.shape:
                raise ValueError(f"{name} has shape {arrays[name].shape}, the case gives "
                                 f"{target.shape}")
            target[:] = arrays[name]
        self.state_changed()
        # (a checkpoint without it, or with a stress that is not finite: computed again)
        carried = arrays.get("sigma")
        if carried is not None and carried.shape == self.sigma.shape \
                and self.loops.carries_stress and np.all(np.isfinite(carried)):
            self.sigma[:] = carried
            if self.stress_reconstructed:
                self.loops.pack(slice(None))
            self.known = StateValues(stress=True)
        self.time = float(arrays["time"])
        self.energy.restore(arrays)
        self.loads.at(self.time)
        if self.contact is not None:
            self.contact.end_step(self.x, self.v, self.F, self.time)
            self.contact.restore_memory(arrays["contact_memory"])
