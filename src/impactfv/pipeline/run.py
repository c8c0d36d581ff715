"""The time loop shared by every method.

A stepper (FV or FE) provides the physics of one step; this module owns everything around it:
the time step clipped to land on output instants, the history, the ParaView frames, the
checkpoints and restart, the summary, the progress bar and SIGINT/SIGTERM. Output instants
are the same whether files are written or not, so a run gives the same numbers with and
without an output folder.

A stepper has: ``method``, ``stages_per_step``, ``history_columns()``, ``history_row()``,
``stable_dt()``, ``step(dt)``, ``check(step, t)`` (raises SimulationError), ``snapshot()``
-> (points, cells, point data), ``body_fields()``, ``summary()``, ``state_arrays()`` and
``restore(arrays)``.
"""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..version import __version__
from ..backends.threads import threads_problem, using_threads
from ..case import Case
from ..errors import InputError, SimulationError
from ..io.checkpoint import case_fingerprint, load_newest_checkpoint, save_checkpoint
from ..io.folder import OutputFolder
from ..io.writers import SnapshotWriter, write_history_csv, write_summary
from .history import History
from .progress import progress_bar
from .result import Interrupted, RunResult
from .signals import SignalFlag


DEFAULT_MAX_STEPS = 10_000_000


def step_count_problem(case: Case, dt: float) -> str | None:
    """A message when the run would need more steps than the default cap (estimated from the
    first stable time step ``dt``) and ``run.max_steps`` was not set; else None."""
    steps = case.run.end_time / dt if dt > 0 else math.inf
    if case.run.max_steps is None and steps > DEFAULT_MAX_STEPS:
        return (f"run: about {steps:.3g} steps of {dt:.3g} s to end_time = "
                f"{case.run.end_time:.3g} s (cfl {case.run.cfl}), more than the "
                f"{DEFAULT_MAX_STEPS:,} allowed unless run.max_steps is set")
    return None


@dataclass
class Schedule:
    """When a run stops and when it writes: ``output_interval`` (default end_time / 10)
    between frames, a history row every ``history_every`` steps (and at the last step),
    the frames' point ``fields`` (None: all the stepper has)."""

    end_time: float
    output_interval: float | None = None
    max_steps: int = 10_000_000
    history_every: int = 1
    fields: tuple | None = None

    @property
    def interval(self) -> float:
        return self.output_interval or self.end_time / 10.0


def run(case: Case, output_dir=None, progress: bool | None = None, restart: bool = False,
        checkpoint_every: float | None = None, handle_signals: bool = False) -> RunResult:
    """Run a validated case with its method. Writes files only when ``output_dir`` is given.

    ``progress``: show a progress bar (default: when standard error is a terminal).
    ``restart``: continue from the newest checkpoint in ``output_dir``.
    ``checkpoint_every``: write a checkpoint every so many seconds of simulated time.
    ``handle_signals``: on SIGINT/SIGTERM write a checkpoint and valid outputs, then raise
    :class:`Interrupted` (the CLI turns it into exit code 130 or 143).
    """
    from ..geometry.penetration import find_overlaps
    from .methods import make_stepper

    overlaps = find_overlaps(case) if case.contacts else []
    if overlaps:
        raise InputError(f"{case.source}: {overlaps[0]}")
    problem = threads_problem(case.run.threads)
    if problem:
        raise InputError(f"{case.source}: {problem}")
    # the thread count is set before the stepper is built (the edge blocks of the FV
    # kernels follow it) and given back when the run ends
    with using_threads(case.run.threads):
        return _run(case, output_dir, progress, restart, checkpoint_every, handle_signals,
                    make_stepper)


def _run(case, output_dir, progress, restart, checkpoint_every, handle_signals, make_stepper):
    wall_start = _time.perf_counter()
    stepper = make_stepper(case)
    output = case.output
    schedule = Schedule(case.run.end_time, case.run.output_interval,
                        case.run.max_steps or DEFAULT_MAX_STEPS, output.history_every,
                        None if output.fields is None else tuple(output.fields))
    if not restart:
        problem = step_count_problem(case, stepper.stable_dt())
        if problem:
            raise InputError(f"{case.source}: {problem}")
    return run_stepper(stepper, schedule, output_dir, progress=progress, restart=restart,
                       checkpoint_every=checkpoint_every, handle_signals=handle_signals,
                       fingerprint=case_fingerprint(case), title=case.title,
                       wall_start=wall_start, walls=case_walls(case),
                       contacts=case_contacts(case))


def case_walls(case) -> list:
    """The rigid walls of a case as (point, normal, velocity, size) for the output frames:
    a patch centred on the bodies' projection, as long as their extent along it plus half
    (the walls are drawn in walls.pvd)."""
    walls = [c.wall for c in case.contacts if c.wall is not None]
    if not walls:
        return []
    X = np.concatenate([b.mesh.points for b in case.bodies])
    out = []
    for w in walls:
        point, normal = np.asarray(w.point, float), np.asarray(w.normal, float)
        centre = X.mean(axis=0)
        centre = centre - np.dot(centre - point, normal) * normal
        size = 1.5 * float(np.max(np.ptp(X, axis=0)))
        out.append((centre, normal, np.asarray(w.velocity, float), size))
    return out


def case_contacts(case) -> list:
    """What each contact joins, for summary.json: {"bodies": [...], "wall": bool}."""
    return [{"bodies": list(c.bodies), "wall": c.wall is not None, "model": c.model}
            for c in case.contacts]


def run_stepper(stepper, schedule: Schedule, output_dir=None, progress: bool | None = None,
                restart: bool = False, checkpoint_every: float | None = None,
                handle_signals: bool = False, fingerprint: str = "", title: str | None = None,
                wall_start: float | None = None, walls=(), contacts=None) -> RunResult:
    """Run ``stepper`` to ``schedule.end_time``; see :func:`run` for the options. The output
    folder, if any, is locked for the run (io.folder.OutputFolder). ``walls``: rigid walls
    drawn in the frames (:func:`case_walls`); ``contacts``: described in the summary."""
    args = (stepper, schedule, output_dir, progress, restart, checkpoint_every, handle_signals,
            fingerprint, title, wall_start, walls, contacts)
    if output_dir is None:
        return _run_stepper(*args)
    with OutputFolder(output_dir, fresh=not restart):
        return _run_stepper(*args)


def _run_stepper(stepper, schedule, output_dir, progress, restart, checkpoint_every,
                 handle_signals, fingerprint, title, wall_start, walls, contacts) -> RunResult:
    if (restart or checkpoint_every or handle_signals) and output_dir is None:
        raise InputError("restart and checkpoints need an output folder")
    end = schedule.end_time
    if checkpoint_every is not None and not (checkpoint_every >= 1e-9 * end and
                                             math.isfinite(checkpoint_every)):
        raise InputError(f"--checkpoint-every: expected a positive time of at least 1e-9 x "
                         f"end_time ({1e-9 * end:.3g} s), got {checkpoint_every}")
    wall_start = _time.perf_counter() if wall_start is None else wall_start
    interval = schedule.interval
    out = Path(output_dir) if output_dir is not None else None
    writer = SnapshotWriter(out, "fields", fields=schedule.fields, walls=walls) \
        if out is not None else None
    history = History(["time", "dt", *stepper.history_columns()])
    every = max(int(schedule.history_every), 1)
    recorded = [-1]

    def record(t, dt, step):
        history.append((t, dt, *stepper.history_row()))
        recorded[0] = step

    def snapshot(t):
        if writer is not None:
            writer.write(t, *stepper.snapshot())

    def checkpoint(t, steps, next_output) -> Path:
        arrays = {"t": np.array(t), "steps": np.array(steps),
                  "next_output": np.array(next_output), "fingerprint": np.array(fingerprint),
                  "version": np.array(__version__), "method": np.array(stepper.method),
                  "history_columns": np.array(history.columns),
                  "snapshot_times": np.array([e[0] for e in writer.entries], float),
                  "snapshot_files": np.array([e[1] for e in writer.entries] or [""])}
        arrays.update({"h_" + k: history.data[k][:history.n] for k in history.columns})
        arrays.update({"state_" + k: a for k, a in stepper.state_arrays().items()})
        return save_checkpoint(out / "checkpoints", steps, arrays)

    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
    if restart:
        t, steps, next_output = _restart(out, fingerprint, stepper, history, writer)
        if history.n and history.data["time"][history.n - 1] == t:
            recorded[0] = steps
    else:
        t, steps = 0.0, 0
        record(0.0, 0.0, 0)
        snapshot(0.0)
        next_output = interval
    next_checkpoint = _next_multiple(t, checkpoint_every) if checkpoint_every else math.inf
    bar = progress_bar(progress, end)
    if bar is not None and t > 0:
        bar.update(t)
    status = "completed"
    stop = SignalFlag(handle_signals)
    loop_start = _time.perf_counter()

    def finish(status, last_dt=None):
        if last_dt is not None and recorded[0] != steps:
            record(t, last_dt, steps)      # the last step, whatever history_every is
        return _finish(out, history, stepper, title, steps, t, wall_start, loop_start, status,
                       contacts)

    last_dt = None
    try:
        while t < end * (1 - 1e-12):
            dt = stepper.stable_dt()
            if not (dt > 0 and math.isfinite(dt)):
                stepper.check(steps, t)
                raise SimulationError(f"time step became {dt} at step {steps}, time {t:.6e} s",
                                      step=steps, time=t)
            target = min(next_output, end)
            if t + dt >= target * (1 - 1e-12):
                dt = target - t
            # a stepper that computes its monitors inside the step does so only when a
            # history row follows it (the last step records one whatever history_every is,
            # and computes its monitors then)
            stepper.history_due = (steps + 1) % every == 0
            stepper.step(dt)
            last_dt = dt
            t = target if abs(t + dt - target) <= 1e-12 * end else t + dt
            steps += 1
            stepper.check(steps, t)
            if steps % every == 0:
                record(t, dt, steps)
            if t >= next_output * (1 - 1e-12) or t >= end * (1 - 1e-12):
                snapshot(t)
                if out is not None:
                    write_history_csv(out / "history.csv", history.data, history.n)
                next_output = min(_next_multiple(t, interval), end) \
                    if t < end * (1 - 1e-12) else math.inf
            if t >= next_checkpoint * (1 - 1e-12):
                checkpoint(t, steps, next_output)
                next_checkpoint = _next_multiple(t, checkpoint_every)
            if bar is not None:
                bar.update(t - bar.n)
            if stop.signum is not None:
                if recorded[0] != steps:
                    record(t, dt, steps)
                path = checkpoint(t, steps, next_output)
                finish("interrupted")
                raise Interrupted(stop.signum, path)
            if steps >= schedule.max_steps:
                status = "stopped at max_steps"
                break
    except SimulationError:
        finish("failed")
        raise
    finally:
        stop.restore()
        if bar is not None:
            bar.close()
    summary = finish(status, last_dt)
    return RunResult(history.arrays(), stepper.body_fields(), summary, out,
                     writer.entries if writer else [])


def _next_multiple(t, interval):
    """The first multiple of ``interval`` after ``t`` (computed, never stepped to)."""
    return (math.floor(t / interval * (1 + 1e-12)) + 1) * interval


def _restart(out, fingerprint, stepper, history, writer):
    path, data = load_newest_checkpoint(out / "checkpoints")
    try:
        if str(data["fingerprint"]) != fingerprint:
            raise InputError(f"{path}: checkpoint was written for a different case")
        if list(data["history_columns"]) != history.columns:
            raise InputError(f"{path}: checkpoint history columns do not match the case")
        stepper.restore({k[len("state_"):]: a for k, a in data.items()
                         if k.startswith("state_")})
        history.load({k: data["h_" + k] for k in history.columns})
        times = data["snapshot_times"]
        files = [str(f) for f in data["snapshot_files"]][:len(times)]
        writer.entries = list(zip(map(float, times), files))
        return float(data["t"]), int(data["steps"]), float(data["next_output"])
    except (KeyError, ValueError) as exc:
        raise InputError(f"{path}: unreadable checkpoint ({exc})") from None


def _finish(out, history, stepper, title, steps, t, wall_start, loop_start, status,
            contacts=None):
    loop_time = _time.perf_counter() - loop_start
    info = stepper.summary()
    summary = {
        "title": title, "version": __version__, "method": stepper.method, "status": status,
        **info, "bodies": list(stepper.body_names), "steps": int(steps), "end_time": float(t),
        "wall_time_s": _time.perf_counter() - wall_start, "time_loop_s": loop_time,
        "node_stage_updates_per_second":
            stepper.stages_per_step * info["nodes"] * steps / loop_time if loop_time > 0
            else None,
        "final": history.last(),
    }
    if contacts is not None:
        summary["contacts"] = contacts
    if out is not None:
        write_history_csv(out / "history.csv", history.data, history.n)
        write_summary(out / "summary.json", summary)
    return summary
