"""The time loop: two-stage TVD Runge-Kutta with a CFL time step, monitors and output.

Data flows one way: case -> model arrays -> kernels -> monitors and writers. The loop body
calls compiled kernels only; nothing in it loops over nodes or edges in Python.
"""

from __future__ import annotations

import json
import math
import sys
import time as _time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import __version__
from .case import Case
from .errors import InputError, SimulationError
from .io.writers import SnapshotWriter, write_history_csv, write_summary
from .model import Model, build_model
from .scheme import kernels as K

HISTORY_COLUMNS = ("time", "dt", "kinetic_energy", "strain_energy", "total_energy",
                   "momentum_x", "momentum_y")
LIMITER_IDS = {"none": K.LIMITER_NONE, "barth_jespersen": K.LIMITER_BARTH_JESPERSEN,
               "venkatakrishnan": K.LIMITER_VENKATAKRISHNAN}


@dataclass
class RunResult:
    history: dict[str, np.ndarray]
    bodies: dict[str, dict[str, np.ndarray]]
    summary: dict
    output_dir: Path | None = None
    snapshots: list = field(default_factory=list)


class FVSolver:
    """State and work arrays of one finite-volume run, allocated once."""

    def __init__(self, case: Case, model: Model | None = None):
        self.case = case
        self.model = m = model if model is not None else build_model(case)
        n = m.n_nodes
        self.order = case.run.order
        self.limiter = LIMITER_IDS[case.run.limiter]
        self.cfl = case.run.cfl
        self.upwind_geometric = case.run.geometric_flux == "upwind"
        self.v = m.v0.copy()
        self.F = np.zeros((n, 4))
        self.F[:, 0] = self.F[:, 3] = 1.0
        self.x = m.X.copy()
        self.v0, self.F0, self.x0 = np.empty_like(self.v), np.empty_like(self.F), \
            np.empty_like(self.x)
        self.P = np.empty((n, 4))
        self.grad = np.zeros((n, 2, 2))
        self.vmin, self.vmax, self.phi = (np.empty((n, 2)) for _ in range(3))
        self.force = np.empty((n, 2))
        self.dF = np.empty((n, 4))
        self.monitor_buf = np.zeros((len(m.bodies), 4))
        self.dt = 0.0
        if case.contacts:
            from .contact import ContactSystem
            self.contact = ContactSystem(case, m)
            self.contact_state, self.contact_xdot = self.contact.state, self.contact.xdot
            self.hb_in_contact = self.contact.hb_active
        else:
            self.contact = None
            self.contact_state = np.zeros(n, np.int8)
            self.contact_xdot = np.zeros((n, 2))
            self.hb_in_contact = np.zeros(len(m.hb_node), bool)

    # -- one stage of rates
    def rates(self, stage=0):
        m = self.model
        K.compute_stress(self.F, m.node_mat, m.mat, self.P)
        if self.contact is not None:
            self.contact.stage(self.x, self.v, self.F, self.dt, stage)
        if self.order == 2:
            K.velocity_gradient(self.v, m.edges, m.C, m.edge_offsets, m.hb_node, m.hb_other,
                                m.hb_C, m.omega, self.grad, self.vmin, self.vmax)
            if self.limiter != K.LIMITER_NONE:
                K.limit_gradient(self.v, m.edges, m.half, m.edge_offsets, self.limiter,
                                 self.vmin, self.vmax, self.phi, self.grad)
        K.assemble_rates(self.v, self.F, self.P, self.grad, m.node_mat, m.mat, m.edges, m.C,
                         m.C_len, m.half, m.edge_offsets, m.hb_node, m.hb_other, m.hb_C, m.hb_bc, m.bc_fix,
                         m.bc_v, m.bc_t, self.order == 2, self.upwind_geometric,
                         self.hb_in_contact, self.force, self.dF)
        if self.contact is not None:
            self.contact.apply(self.force, self.dF)

    def stable_dt(self) -> float:
        m = self.model
        return self.cfl * K.stable_time_step(self.F, m.node_mat, m.mat, m.node_length)

    def step(self, dt: float):
        m = self.model
        self.v0[:] = self.v
        self.F0[:] = self.F
        self.x0[:] = self.x
        self.dt = dt
        for stage, alpha in enumerate((0.0, 0.5)):
            self.rates(stage)
            K.rk_update(alpha, dt, self.v0, self.F0, self.x0, self.v, self.F, self.x,
                        self.force, self.dF, self.contact_state, self.contact_xdot, m.node_mat, m.mat,
                        m.omega, m.fixed_mask, m.fixed_value)
        if self.contact is not None:
            self.contact.end_step(self.x, self.v, self.F)

    def energies(self) -> np.ndarray:
        m = self.model
        K.monitors(self.v, self.F, m.node_mat, m.mat, m.omega, m.body_start, self.monitor_buf)
        return self.monitor_buf.sum(axis=0)

    def check_state(self, step: int, t: float):
        bad = K.state_is_bad(self.v, self.F)
        if bad >= 0:
            m = self.model
            body = m.bodies[m.body_of_node[bad]]
            J = self.F[bad, 0] * self.F[bad, 3] - self.F[bad, 1] * self.F[bad, 2]
            what = "non-finite state" if not np.isfinite(J) or not np.all(
                np.isfinite(self.v[bad])) else f"collapsed control volume (J = {J:.3g})"
            raise SimulationError(
                f"{what} at step {step}, time {t:.6e} s, body {body.name!r}, node "
                f"{bad - body.start} (reference position {m.X[bad].tolist()}); try a smaller "
                "cfl or a finer mesh", step=step, time=t, body=body.name, node=bad - body.start)

    def body_fields(self) -> dict[str, dict[str, np.ndarray]]:
        """The point fields of each body (copies), plus its mesh and F."""
        m = self.model
        data = self.point_data()
        data.pop("body")
        out = {}
        for b in m.bodies:
            s = slice(b.start, b.stop)
            fields = {key: np.array(value[s]) for key, value in data.items()}
            if "contact_status" in fields:
                fields["contact_status"] = self.contact.state[s].copy()
            fields.update(reference_points=m.X[s].copy(), points=self.x[s].copy(),
                          triangles=b.triangles - b.start,
                          F=self.F[s].reshape(-1, 2, 2).copy())
            out[b.name] = fields
        return out

    def point_data(self) -> dict[str, np.ndarray]:
        m = self.model
        n = m.n_nodes
        pressure, vm, jac = np.empty(n), np.empty(n), np.empty(n)
        K.point_fields(self.F, m.node_mat, m.mat, pressure, vm, jac)
        data = {"velocity": self.v, "displacement": self.x - m.X, "pressure": pressure,
                "von_mises": vm, "J": jac, "body": m.body_of_node.astype(float)}
        if self.contact is not None:
            data["contact_status"] = self.contact.state.astype(float)  # 0 open 1 stick 2 slip
            data["contact_pressure"] = -self.contact.tstar_n
        return data


class History:
    """Preallocated, growing columns; one row per step."""

    def __init__(self, columns):
        self.columns = list(columns)
        self.data = {k: np.zeros(1024) for k in self.columns}
        self.n = 0

    def append(self, row):
        if self.n == len(self.data[self.columns[0]]):
            for k in self.columns:
                self.data[k] = np.concatenate([self.data[k], np.zeros(self.n)])
        for k, value in zip(self.columns, row):
            self.data[k][self.n] = value
        self.n += 1

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: self.data[k][:self.n].copy() for k in self.columns}


class Interrupted(Exception):
    """The run was stopped by a signal after writing a checkpoint; CLI exit 128 + signum."""

    def __init__(self, signum, checkpoint):
        super().__init__(f"interrupted by signal {signum}; checkpoint written to {checkpoint}")
        self.signum = signum
        self.checkpoint = checkpoint


def run(case: Case, output_dir=None, progress: bool | None = None, restart: bool = False,
        checkpoint_every: float | None = None, handle_signals: bool = False) -> RunResult:
    """Run a validated case. Writes files only when ``output_dir`` is given.

    ``progress``: show a progress bar (default: when standard error is a terminal).
    ``restart``: continue from the newest checkpoint in ``output_dir``.
    ``checkpoint_every``: write a checkpoint every so many seconds of simulated time.
    ``handle_signals``: on SIGINT/SIGTERM write a checkpoint and valid outputs, then raise
    :class:`Interrupted` (the CLI turns it into exit code 130 or 143).
    """
    if case.run.method != "fv":
        if restart or checkpoint_every:
            raise InputError(f"{case.source}: run.method: checkpoints and restart are "
                             f"available for method \"fv\" only, not {case.run.method!r}")
        from .fem.driver import run_fem_case
        return run_fem_case(case, output_dir, progress)
    if (restart or checkpoint_every or handle_signals) and output_dir is None:
        raise InputError("restart and checkpoints need an output folder")
    if checkpoint_every is not None and not (checkpoint_every >= 1e-9 * case.run.end_time and
                                             math.isfinite(checkpoint_every)):
        raise InputError(f"--checkpoint-every: expected a positive time of at least 1e-9 x "
                         f"end_time ({1e-9 * case.run.end_time:.3g} s), got {checkpoint_every}")
    wall_start = _time.perf_counter()
    solver = FVSolver(case)
    m = solver.model
    run_cfg = case.run
    end = run_cfg.end_time
    interval = run_cfg.output_interval or end / 10.0
    out = Path(output_dir) if output_dir is not None else None
    writer = SnapshotWriter(out, "fields") if out is not None else None
    contact = solver.contact
    history = History(HISTORY_COLUMNS + tuple(contact.history_columns() if contact else ()))
    if contact is not None:
        from .contact import find_overlaps
        overlaps = find_overlaps(case, m)
        if overlaps:
            raise InputError(f"{case.source}: {overlaps[0]}")
        contact.end_step(solver.x, solver.v, solver.F)  # initial gaps

    def record(t, dt):
        ke, se, px, py = solver.energies()
        extra = contact.history_values() if contact is not None else []
        history.append((t, dt, ke, se, ke + se, px, py, *extra))

    def snapshot(t):
        if writer is not None:
            writer.write(t, solver.x, np.concatenate([b.triangles for b in m.bodies]),
                         solver.point_data())

    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
    fingerprint = case_fingerprint(case)
    if restart:
        t, steps, next_output = load_checkpoint(out, fingerprint, solver, history, writer)
    else:
        t, steps = 0.0, 0
        record(0.0, 0.0)
        snapshot(0.0)
        next_output = interval
    next_checkpoint = _next_multiple(t, checkpoint_every) if checkpoint_every else math.inf
    bar = _progress_bar(progress, end)
    if bar is not None and t > 0:
        bar.update(t)
    status = "completed"
    stop = _SignalFlag(handle_signals)
    loop_start = _time.perf_counter()
    try:
        while t < end * (1 - 1e-12):
            dt = solver.stable_dt()
            if not (dt > 0 and math.isfinite(dt)):
                solver.check_state(steps, t)
                raise SimulationError(f"time step became {dt} at step {steps}, time {t:.6e} s",
                                      step=steps, time=t)
            target = min(next_output, end)
            if t + dt >= target * (1 - 1e-12):
                dt = target - t
            solver.step(dt)
            t = target if abs(t + dt - target) <= 1e-12 * end else t + dt
            steps += 1
            solver.check_state(steps, t)
            record(t, dt)
            if t >= next_output * (1 - 1e-12) or t >= end * (1 - 1e-12):
                snapshot(t)
                if out is not None:
                    write_history_csv(out / "history.csv", history.data, history.n)
                next_output = min(_next_multiple(t, interval), end) \
                    if t < end * (1 - 1e-12) else math.inf
            if t >= next_checkpoint * (1 - 1e-12):
                save_checkpoint(out, fingerprint, solver, history, writer, t, steps,
                                next_output)
                next_checkpoint = _next_multiple(t, checkpoint_every)
            if bar is not None:
                bar.update(t - bar.n)
            if stop.signum is not None:
                path = save_checkpoint(out, fingerprint, solver, history, writer, t, steps,
                                       next_output)
                _finish(out, history, solver, case, steps, t, wall_start, loop_start,
                        "interrupted")
                raise Interrupted(stop.signum, path)
            if steps >= run_cfg.max_steps:
                status = "stopped at max_steps"
                break
    except SimulationError:
        status = "failed"
        _finish(out, history, solver, case, steps, t, wall_start, loop_start, status)
        raise
    finally:
        stop.restore()
        if bar is not None:
            bar.close()
    summary = _finish(out, history, solver, case, steps, t, wall_start, loop_start, status)
    return RunResult(history.arrays(), solver.body_fields(), summary, out,
                     writer.entries if writer else [])


def _next_multiple(t, interval):
    """The first multiple of ``interval`` after ``t`` (computed, never stepped to)."""
    return (math.floor(t / interval * (1 + 1e-12)) + 1) * interval


class _SignalFlag:
    """Records SIGINT/SIGTERM so the loop can stop cleanly between two steps."""

    def __init__(self, active):
        import signal
        import threading

        self.signum = None
        self.previous = {}
        if active and threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self.previous[sig] = signal.signal(sig, self._handle)

    def _handle(self, signum, frame):
        self.signum = signum

    def restore(self):
        import signal
        for sig, handler in self.previous.items():
            signal.signal(sig, handler)
        self.previous = {}


def case_fingerprint(case: Case) -> str:
    """A hash of the validated case, so a checkpoint is never continued with another case."""
    import hashlib
    text = json.dumps(case.spec.model_dump(mode="python"), sort_keys=True,
                      default=lambda o: getattr(o, "__qualname__", type(o).__name__))
    return hashlib.sha256(text.encode()).hexdigest()


def save_checkpoint(out, fingerprint, solver, history, writer, t, steps, next_output) -> Path:
    """Atomic .npz checkpoint (no pickle) of everything the loop needs to continue."""
    import io as _io

    from .io.writers import _atomic_replace
    arrays = {"v": solver.v, "F": solver.F, "x": solver.x, "t": np.array(t),
              "steps": np.array(steps), "next_output": np.array(next_output),
              "fingerprint": np.array(fingerprint), "version": np.array(__version__),
              "history_columns": np.array(history.columns),
              "snapshot_times": np.array([e[0] for e in writer.entries], float),
              "snapshot_files": np.array([e[1] for e in writer.entries] or [""])}
    for k in history.columns:
        arrays["h_" + k] = history.data[k][:history.n]
    if solver.contact is not None:
        arrays["was_active"] = solver.contact.was_active
    folder = Path(out) / "checkpoints"
    path = folder / f"checkpoint_{steps:09d}.npz"

    def dump(fh):
        buf = _io.BytesIO()
        np.savez(buf, **arrays)
        fh.write(buf.getvalue())
    _atomic_replace(path, dump)
    return path


def load_checkpoint(out, fingerprint, solver, history, writer):
    folder = Path(out) / "checkpoints"
    files = sorted(folder.glob("checkpoint_*.npz")) if folder.is_dir() else []
    if not files:
        raise InputError(f"{folder}: no checkpoint to restart from")
    path = files[-1]
    try:
        with np.load(path, allow_pickle=False) as data:
            if str(data["fingerprint"]) != fingerprint:
                raise InputError(f"{path}: checkpoint was written for a different case")
            if list(data["history_columns"]) != history.columns:
                raise InputError(f"{path}: checkpoint history columns do not match the case")
            for name in ("v", "F", "x"):
                target = getattr(solver, name)
                if data[name].shape != target.shape:
                    raise InputError(f"{path}: checkpoint {name} has shape {data[name].shape}, "
                                     f"the case gives {target.shape}")
                target[:] = data[name]
            n = len(data["h_time"])
            for k in history.columns:
                history.data[k] = np.concatenate([data["h_" + k], np.zeros(max(n, 1024))])
            history.n = n
            times = data["snapshot_times"]
            files_ = [str(f) for f in data["snapshot_files"]][:len(times)]
            writer.entries = list(zip(map(float, times), files_))
            if solver.contact is not None:
                solver.contact.end_step(solver.x, solver.v, solver.F)
                solver.contact.was_active[:] = data["was_active"]
            return float(data["t"]), int(data["steps"]), float(data["next_output"])
    except (OSError, ValueError, KeyError) as exc:
        raise InputError(f"{path}: unreadable checkpoint ({exc})") from None


def _finish(out, history, solver, case, steps, t, wall_start, loop_start, status):
    m = solver.model
    loop_time = _time.perf_counter() - loop_start
    last = {k: float(history.data[k][history.n - 1]) for k in history.columns}
    summary = {
        "title": case.title, "version": __version__, "method": "fv", "status": status,
        "nodes": int(m.n_nodes), "edges": int(m.n_edges), "bodies": [b.name for b in m.bodies],
        "steps": int(steps), "end_time": float(t),
        "wall_time_s": _time.perf_counter() - wall_start, "time_loop_s": loop_time,
        "node_stage_updates_per_second": 2.0 * m.n_nodes * steps / loop_time if loop_time > 0
        else None,
        "final": last,
    }
    if out is not None:
        write_history_csv(out / "history.csv", history.data, history.n)
        write_summary(out / "summary.json", summary)
    return summary


def _progress_bar(progress, end):
    if progress is None:
        progress = sys.stderr.isatty()
    if not progress:
        return None
    from tqdm import tqdm
    return tqdm(total=end, unit="s", unit_scale=True, desc="simulated time",
                bar_format="{l_bar}{bar}| {n:.3e}/{total:.3e} s [{elapsed}<{remaining}]")
