"""The finite-volume stepper: state and work arrays of one FV run, and one time step.

It plugs into the run pipeline (impactfv.pipeline) like the FE steppers do: the pipeline
owns the time loop, the output and checkpoint schedule and the files; the stepper owns the
physics of a step. Data flows one way: case -> Discretisation -> state -> kernels.
"""

from __future__ import annotations

import numpy as np

from ..backends.cpu import dim_tag
from ..case import Case
from ..errors import SimulationError
from ..io.fields import nodal_stress
from . import kernels as K
from .discretisation import Discretisation, discretise
from .limiters import IDS as LIMITER_IDS
from .limiters import NONE as LIMITER_NONE
from .time import STAGES


class FVStepper:
    """Upwind vertex-centred finite volumes (p-F), two-stage TVD Runge-Kutta."""

    method = "fv"
    stages_per_step = 2

    def __init__(self, case: Case, disc: Discretisation | None = None):
        self.case = case
        self.disc = m = disc if disc is not None else discretise(case)
        n, d = m.n_nodes, m.dim
        self.dim = dim_tag(d)
        self.order = case.run.order
        self.limiter = LIMITER_IDS[case.run.limiter]
        self.cfl = case.run.cfl
        self.upwind_geometric = case.run.geometric_flux == "upwind"
        # the upwind geometric flux needs the reconstructed tractions to be second order
        self.stress_reconstructed = self.order == 2 and self.upwind_geometric
        # state
        self.v = m.v0.copy()
        self.F = np.zeros((n, d, d))
        for i in range(d):
            self.F[:, i, i] = 1.0
        self.x = m.X.copy()
        # work arrays, allocated once
        self.v0, self.F0, self.x0 = (np.empty_like(a) for a in (self.v, self.F, self.x))
        self.sigma = np.empty((n, d, d))  # Cauchy stress
        ncomp = d + d * (d + 1) // 2 if self.stress_reconstructed else d
        self.components = dim_tag(ncomp)
        self.U = np.empty((n, ncomp)) if self.stress_reconstructed else self.v
        self.grad = np.zeros((n, ncomp, d))
        self.vmin, self.vmax = (np.empty((n, ncomp)) for _ in range(2))
        self.force = np.empty((n, d))
        self.dF = np.empty((n, d, d))
        self.monitor_buf = np.zeros((len(m.bodies), 2 + d))
        self.dt = 0.0
        if case.contacts:
            from ..contact.driver import ContactSystem
            self.contact = ContactSystem(case, m)
            self.contact_state, self.contact_xdot = self.contact.state, self.contact.xdot
            self.face_contact_weight = self.contact.face_weight
            self.contact.end_step(self.x, self.v, self.F)  # initial gaps
        else:
            self.contact = None
            self.contact_state = np.zeros(n, np.int8)
            self.contact_xdot = np.zeros((n, d))
            self.face_contact_weight = np.zeros(len(m.bface_node))

    @property
    def body_names(self) -> list[str]:
        return [b.name for b in self.disc.bodies]

    # ------------------------------------------------------------------ one step
    def rates(self, stage=0):
        """Momentum and deformation-gradient rates (force, dF = Omega dF/dt) of the current
        state."""
        m = self.disc
        K.compute_stress(self.F, m.node_material, m.material_table, self.sigma, self.dim)
        if self.stress_reconstructed:
            K.pack_velocity_and_stress(self.v, self.sigma, self.U, self.dim)
        if self.order == 2:
            K.gradient(self.U, m.node_edge_start, m.node_neighbour, m.node_C, m.bface_start,
                       m.bface_others, m.bface_C, m.closure, m.volume, self.grad, self.vmin, self.vmax,
                       self.dim, self.components)
            if self.limiter != LIMITER_NONE:
                K.limit_gradient(self.U, m.node_edge_start, m.node_half, self.limiter,
                                 self.vmin, self.vmax, self.grad, self.dim, self.components)
        if self.contact is not None:
            self.contact.stage(self.x, self.v, self.F, self.sigma, self.grad, self.order == 2,
                               self.dt, stage)
        K.assemble_rates(self.v, self.F, self.sigma, self.grad, m.node_material, m.material_table,
                         m.edges, m.C, m.C_len, m.half, m.edge_offsets, m.bface_node,
                         m.bface_others, m.bface_C, m.bface_bc, m.closure, m.bc_fixed,
                         m.bc_velocity, m.bc_traction, m.fixed_mask, m.fixed_value,
                         self.order == 2,
                         self.stress_reconstructed, self.upwind_geometric,
                         self.face_contact_weight, self.force, self.dF, self.dim)
        if self.contact is not None:
            self.contact.apply(self.force, self.dF)

    def stable_dt(self) -> float:
        m = self.disc
        return self.cfl * K.stable_time_step(self.F, m.node_material, m.material_table,
                                             m.node_length, self.dim)

    def step(self, dt: float):
        m = self.disc
        self.v0[:] = self.v
        self.F0[:] = self.F
        self.x0[:] = self.x
        self.dt = dt
        for stage, alpha in enumerate(STAGES):
            self.rates(stage)
            K.rk_update(alpha, dt, self.v0, self.F0, self.x0, self.v, self.F, self.x,
                        self.force, self.dF, self.contact_state, self.contact_xdot,
                        m.node_material, m.material_table, m.volume, m.fixed_mask,
                        m.fixed_value, self.dim)
        if self.contact is not None:
            self.contact.end_step(self.x, self.v, self.F)

    def check(self, step: int, t: float):
        """Raise SimulationError naming the first node with a non-finite state or J <= 0."""
        bad = K.state_is_bad(self.v, self.F, self.dim)
        if bad < 0:
            return
        m = self.disc
        body = m.bodies[m.body_of_node[bad]]
        with np.errstate(invalid="ignore"):
            J = float(np.linalg.det(self.F[bad]))
        what = "non-finite state" if not np.isfinite(J) or not np.all(
            np.isfinite(self.v[bad])) else f"collapsed control volume (J = {J:.3g})"
        raise SimulationError(
            f"{what} at step {step}, time {t:.6e} s, body {body.name!r}, node "
            f"{bad - body.start} (reference position {m.X[bad].tolist()}); try a smaller "
            "cfl or a finer mesh", step=step, time=t, body=body.name, node=bad - body.start)

    # ------------------------------------------------------------------ monitors and fields
    def history_columns(self) -> list[str]:
        momentum = [f"momentum_{c}" for c in "xyz"[:self.disc.dim]]
        return (["kinetic_energy", "strain_energy", "total_energy", *momentum]
                + (self.contact.history_columns() if self.contact is not None else []))

    def history_row(self) -> list[float]:
        m = self.disc
        K.monitors(self.v, self.F, m.node_material, m.material_table, m.volume, m.body_start,
                   self.monitor_buf, self.dim)
        kinetic, strain, *momentum = self.monitor_buf.sum(axis=0)
        extra = self.contact.history_values() if self.contact is not None else []
        return [kinetic, strain, kinetic + strain, *momentum, *extra]

    def point_data(self) -> dict[str, np.ndarray]:
        m = self.disc
        n = m.n_nodes
        pressure, von_mises, jac = np.empty(n), np.empty(n), np.empty(n)
        K.point_fields(self.F, m.node_material, m.material_table, pressure, von_mises, jac,
                       self.dim)
        data = {"velocity": self.v, "displacement": self.x - m.X, "pressure": pressure,
                "von_mises": von_mises,
                "stress": nodal_stress(self.F, m.node_material, m.material_table), "J": jac,
                "body": m.body_of_node.astype(np.int32)}
        if self.contact is not None:
            data["contact_status"] = self.contact.state.astype(np.int32)  # 0 open 1 stick 2 slip
            data["contact_pressure"] = -self.contact.tstar_n
        return data

    def snapshot(self):
        """(reference points, cells, point data) of all bodies for a ParaView frame."""
        cells = np.concatenate([b.cells for b in self.disc.bodies])
        return self.disc.X, cells, self.point_data()

    def body_fields(self) -> dict[str, dict[str, np.ndarray]]:
        """The point fields of each body (copies), plus its mesh and F."""
        m = self.disc
        data = self.point_data()
        data.pop("body")
        out = {}
        for b in m.bodies:
            s = slice(b.start, b.stop)
            fields = {key: np.array(value[s]) for key, value in data.items()}
            if "contact_status" in fields:
                fields["contact_status"] = self.contact.state[s].copy()
            fields.update(reference_points=m.X[s].copy(), points=self.x[s].copy(),
                          triangles=b.cells - b.start, F=self.F[s].copy())
            out[b.name] = fields
        return out

    def summary(self) -> dict:
        return {"nodes": int(self.disc.n_nodes), "edges": int(self.disc.n_edges)}

    # ------------------------------------------------------------------ checkpoints
    def state_arrays(self) -> dict[str, np.ndarray]:
        """Everything a restart needs besides the case."""
        arrays = {"v": self.v, "F": self.F, "x": self.x}
        if self.contact is not None:
            arrays["contact_memory"] = self.contact.memory
        return arrays

    def restore(self, arrays) -> None:
        """Continue from ``state_arrays`` of an earlier run of the same case."""
        for name in ("v", "F", "x"):
            target = getattr(self, name)
            if arrays[name].shape != target.shape:
                raise ValueError(f"{name} has shape {arrays[name].shape}, the case gives "
                                 f"{target.shape}")
            target[:] = arrays[name]
        if self.contact is not None:
            self.contact.end_step(self.x, self.v, self.F)
            self.contact.memory[:] = arrays["contact_memory"]
