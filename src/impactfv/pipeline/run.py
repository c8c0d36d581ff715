"""The time loop shared by every method.

A stepper (FV or FE) provides the physics of one step; this module owns everything around it:
the time step clipped to land on output instants, the history, the ParaView frames, the
checkpoints and restart, the summary, the progress bar and SIGINT/SIGTERM. Output instants
are the same whether files are written or not, so a run gives the same numbers with and
without an output folder.

A stepper has: ``method``, ``stages_per_step``, ``history_columns()``, ``history_row()``,
``stable_dt()``, ``step(dt, with_monitors)``, ``check(step, t)`` (raises SimulationError), ``snapshot()``
-> (points, cells, point data), ``body_fields()``, ``summary()``, ``state_arrays()`` and
``restore(arrays)``.
"""

from __future__ import annotations

import json
import math
import re
import time as _time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..version import __version__
from ..backends.threads import threads_problem, using_threads
from ..case import Case
from ..errors import InputError, SimulationError
from ..io.checkpoint import (RESTART_MAY_CHANGE, BadCheckpoint, case_description,
                             changed_keys, fingerprint_of, load_good_checkpoint,
                             save_checkpoint)
from ..io.folder import OutputFolder
from ..memory import estimate_case, memory_problem, resident_bytes
from ..io.writers import SnapshotWriter, write_history_csv, write_summary
from .history import History
from .progress import FIRST_STEP_NOTE, progress_bar
from .result import Interrupted, RunResult
from .signals import SignalFlag
from ..parallel.comm import world


DEFAULT_MAX_STEPS = 10_000_000


def step_count_problem(case: Case, dt: float, t: float = 0.0, steps_done: int = 0) -> str | None:
    """A message when the run would need more steps than the default cap (estimated from the
    stable time step ``dt`` at time ``t``, after ``steps_done`` steps) and ``run.max_steps``
    was not set; else None."""
    steps = steps_done + (case.run.end_time - t) / dt if dt > 0 else math.inf
    if case.run.max_steps is None and steps > DEFAULT_MAX_STEPS:
        return (f"run: about {steps:.3g} steps of {dt:.3g} s to end_time = "
                f"{case.run.end_time:.3g} s (cfl {case.run.cfl}), more than the "
                f"{DEFAULT_MAX_STEPS:,} allowed unless run.max_steps is set")
    return None


def expected_steps(case: Case, dt: float, t: float = 0.0, steps_done: int = 0) -> int:
    """The steps a run will take (history rows), from the stable time step ``dt``."""
    cap = case.run.max_steps or DEFAULT_MAX_STEPS
    remaining = (case.run.end_time - t) / dt if dt > 0 else math.inf
    return int(min(cap, steps_done + math.ceil(min(remaining, 1e18))))


def history_memory_problem(case: Case, dt: float, t: float = 0.0, steps_done: int = 0,
                           held: int = 0) -> str | None:
    """The memory check again, now that the number of history rows is known; ``held``:
    bytes the stepper has already taken since the first check."""
    problem = memory_problem(estimate_case(case, expected_steps(case, dt, t, steps_done)),
                             held=held)
    return f"the run {problem}" if problem else None


@dataclass
class Schedule:
    """When a run stops and when it writes: ``output_interval`` (default end_time / 10)
    between frames, a history row every ``history_every`` steps (and at the last step),
    the frames' point ``fields`` (None: all the stepper has), the newest
    ``keep_checkpoints`` checkpoints kept."""

    end_time: float
    output_interval: float | None = None
    max_steps: int = 10_000_000
    history_every: int = 1
    fields: tuple | None = None
    keep_checkpoints: int = 3

    @property
    def interval(self) -> float:
        return self.output_interval or self.end_time / 10.0


def run(case: Case, output_dir=None, progress: bool | None = None, restart: bool = False,
        checkpoint_every: float | None = None, handle_signals: bool = False,
        overwrite: bool = False) -> RunResult:
    """Run a validated case with its method. Writes files only when ``output_dir`` is given.

    ``progress``: show a progress bar (default: when standard error is a terminal).
    ``restart``: continue from the newest checkpoint in ``output_dir``.
    ``checkpoint_every``: write a checkpoint every so many seconds of simulated time.
    ``handle_signals``: on SIGINT/SIGTERM write a checkpoint and valid outputs, then raise
    :class:`Interrupted` (the CLI turns it into exit code 130 or 143).
    ``overwrite``: a fresh run may write into a folder that impactfv did not make or that
    holds checkpoints (io.folder.OutputFolder refuses both otherwise).
    """
    from ..geometry.penetration import find_overlaps
    from .methods import make_stepper

    if (problem := memory_problem(estimate_case(case))):
        raise InputError(f"{case.source}: the run {problem}")
    overlaps = find_overlaps(case) if case.contacts else []
    if overlaps:
        raise InputError(f"{case.source}: {overlaps[0]}")
    problem = threads_problem(case.run.threads)
    if problem:
        raise InputError(f"{case.source}: {problem}")
    threads = case.run.threads
    if threads is None and world() is not None:
        threads = 1         # one thread per rank under MPI unless run.threads says more
    # the thread count is set before the stepper is built (the edge blocks of the FV
    # kernels follow it) and given back when the run ends
    with using_threads(threads):
        return _run(case, output_dir, progress, restart, checkpoint_every, handle_signals,
                    make_stepper, overwrite)


def _run(case, output_dir, progress, restart, checkpoint_every, handle_signals, make_stepper,
         overwrite=False):
    wall_start = _time.perf_counter()
    resident = resident_bytes()
    stepper = make_stepper(case)
    held = resident_bytes() - resident
    output = case.output
    schedule = Schedule(case.run.end_time, case.run.output_interval,
                        case.run.max_steps or DEFAULT_MAX_STEPS, output.history_every,
                        None if output.fields is None else tuple(output.fields),
                        output.keep_checkpoints)

    def refuse(stepper, t, steps):
        dt = stepper.stable_dt()
        return step_count_problem(case, dt, t, steps) or \
            history_memory_problem(case, dt, t, steps, held)

    if not restart and (problem := refuse(stepper, 0.0, 0)):
        raise InputError(f"{case.source}: {problem}")
    return run_stepper(stepper, schedule, output_dir, progress=progress, restart=restart,
                       checkpoint_every=checkpoint_every, handle_signals=handle_signals,
                       title=case.title,
                       wall_start=wall_start, walls=case_walls(case),
                       contacts=case_contacts(case), description=case_description(case),
                       preflight=refuse, source=case.source, overwrite=overwrite)


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
                handle_signals: bool = False, title: str | None = None,
                wall_start: float | None = None, walls=(), contacts=None,
                description: dict | None = None, preflight=None,
                source: str = "", overwrite: bool = False) -> RunResult:
    """Run ``stepper`` to ``schedule.end_time``; see :func:`run` for the options. The output
    folder, if any, is locked for the run (io.folder.OutputFolder). ``walls``: rigid walls
    drawn in the frames (:func:`case_walls`); ``contacts``: described in the summary;
    ``description``: the case's key table (io.checkpoint.case_description), whose hash a
    checkpoint carries and with which a refused restart names what changed;
    ``preflight(stepper, t, steps)``: a reason to refuse a restarted run before it continues,
    or None. ``overwrite``: see :func:`run`. The options are checked before the folder is
    touched."""
    _check_run_options(output_dir, restart, checkpoint_every, handle_signals,
                       schedule.end_time)
    args = (stepper, schedule, output_dir, progress, restart, checkpoint_every, handle_signals,
            fingerprint_of(description or {}), title, wall_start, walls, contacts,
            description or {}, preflight, source)
    comm = getattr(stepper, "comm", None)
    if output_dir is None:
        return _run_stepper(*args)
    if comm is None:
        with OutputFolder(output_dir, fresh=not restart, overwrite=overwrite):
            return _run_stepper(*args)
    # under MPI the files are rank 0's (it holds the folder's lock, and tells the others
    # when it cannot); the others run the same loop without writing
    folder, refused = None, None
    if comm.Get_rank() == 0:
        folder = OutputFolder(output_dir, fresh=not restart, overwrite=overwrite)
        try:
            folder.__enter__()
        except InputError as exc:
            folder, refused = None, exc
    refused = comm.bcast(refused, root=0)
    if refused is not None:
        raise refused
    try:
        return _run_stepper(*args)
    finally:
        if folder is not None:
            folder.__exit__(None, None, None)


def _check_run_options(output_dir, restart, checkpoint_every, handle_signals, end):
    """Refuse options that cannot run, before anything on disk changes."""
    if (restart or checkpoint_every or handle_signals) and output_dir is None:
        raise InputError("restart and checkpoints need an output folder")
    if checkpoint_every is not None and not (checkpoint_every >= 1e-9 * end and
                                             math.isfinite(checkpoint_every)):
        raise InputError(f"--checkpoint-every: expected a positive time of at least 1e-9 x "
                         f"end_time ({1e-9 * end:.3g} s), got {checkpoint_every}")


def _run_stepper(stepper, schedule, output_dir, progress, restart, checkpoint_every,
                 handle_signals, fingerprint, title, wall_start, walls, contacts, description,
                 preflight, source) -> RunResult:
    end = schedule.end_time
    wall_start = _time.perf_counter() if wall_start is None else wall_start
    interval = schedule.interval
    out = Path(output_dir) if output_dir is not None else None
    comm = getattr(stepper, "comm", None)
    root = comm is None or comm.Get_rank() == 0      # the rank that writes the files
    if out is None:
        writer = None
    elif root:
        writer = SnapshotWriter(out, "fields", fields=schedule.fields, walls=walls)
    else:
        writer = _FrameCounter("fields")
    if not root:
        progress = False
    files = out if root else None
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
        # the checkpoint's own step is in its history, whatever history_every is
        if recorded[0] != steps:
            record(t, last_dt, steps)
        arrays = {"t": np.array(t), "steps": np.array(steps),
                  "next_output": np.array(next_output), "fingerprint": np.array(fingerprint),
                  "version": np.array(__version__), "method": np.array(stepper.method),
                  "case_description": np.array(json.dumps(description, sort_keys=True)),
                  "schedule": np.array([end, interval], float),
                  "history_columns": np.array(history.columns),
                  "snapshot_times": np.array([e[0] for e in writer.entries], float),
                  "snapshot_files": np.array([e[1] for e in writer.entries] or [""])}
        arrays.update({"h_" + k: history.data[k][:history.n] for k in history.columns})
        arrays.update({"state_" + k: a for k, a in stepper.state_arrays().items()})
        return save_checkpoint(out / "checkpoints", steps, arrays,
                               keep=schedule.keep_checkpoints) if root else None

    if files is not None:
        out.mkdir(parents=True, exist_ok=True)
    if restart:
        t, steps, next_output = _restart(out, fingerprint, description, stepper, history,
                                         writer, schedule, preflight, source, comm)
        if history.n and history.data["time"][history.n - 1] == t:
            recorded[0] = steps
    else:
        t, steps = 0.0, 0
        record(0.0, 0.0, 0)
        try:
            snapshot(0.0)
        except OSError as exc:
            raise SimulationError(f"{_write_failure(exc)} at the start") from None
        next_output = interval
    next_checkpoint = _next_multiple(t, checkpoint_every) if checkpoint_every else math.inf
    checkpointed = steps if restart else -1
    # a continued run's bar starts at its time: its first step is still the first update
    bar = progress_bar(progress, end, note=FIRST_STEP_NOTE, start_at=t)
    status = "completed"
    stop = SignalFlag(handle_signals)
    loop_start = _time.perf_counter()

    def finish(status, last_dt=None, reason=None):
        if last_dt is not None and recorded[0] != steps:
            record(t, last_dt, steps)      # the last step, whatever history_every is
        return _finish(files, history, stepper, title, steps, t, wall_start, loop_start,
                       status, contacts, reason)

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
            stepper.step(dt, with_monitors=(steps + 1) % every == 0)
            last_dt = dt
            stop.armed()       # the kernels are compiled: a signal now stops after a step
            t = target if abs(t + dt - target) <= 1e-12 * end else t + dt
            steps += 1
            stepper.check(steps, t)
            if steps % every == 0:
                record(t, dt, steps)
            if t >= next_output * (1 - 1e-12) or t >= end * (1 - 1e-12):
                snapshot(t)
                if files is not None:
                    write_history_csv(out / "history.csv", history.data, history.n)
                next_output = min(_next_multiple(t, interval), end) \
                    if t < end * (1 - 1e-12) else math.inf
            if t >= next_checkpoint * (1 - 1e-12):
                checkpoint(t, steps, next_output)
                checkpointed = steps
                next_checkpoint = _next_multiple(t, checkpoint_every)
            if bar is not None:
                bar.update(t - bar.n)
            if comm is not None:   # every rank stops after the same step
                stop.signum = comm.allreduce(stop.signum or 0, op=_mpi_max()) or None
            if stop.signum is not None:
                path = checkpoint(t, steps, next_output)
                finish("interrupted")
                raise Interrupted(stop.signum, path)
            if steps >= schedule.max_steps:
                status = "stopped at max_steps"
                break
        if checkpoint_every and checkpointed != steps:
            # the end is a checkpoint too: a finished run can be continued to a later end_time
            checkpoint(t, steps, next_output)
        # the last files are written while signals are still only noted: a signal now lets
        # them finish, and the run ends completed
        summary = finish(status, last_dt)
    except SimulationError as exc:
        finish("failed", reason=str(exc))
        raise
    except OSError as exc:
        # a full disk or a file-size limit: a failed run, which keeps what it could write
        reason = _write_failure(exc)
        try:
            finish("failed", reason=reason)
        except OSError:
            pass
        raise SimulationError(f"{reason} at step {steps}, time {t:.6e} s", step=steps,
                              time=t) from None
    finally:
        stop.restore()
        if bar is not None:
            bar.close()
    return RunResult(history.arrays(), stepper.body_fields(), summary, out,
                     writer.entries if writer else [])


def _write_failure(exc: OSError) -> str:
    return f"writing the outputs failed ({exc.strerror or exc}: {exc.filename})"


class _FrameCounter:
    """The frame bookkeeping of SnapshotWriter without the files (ranks other than 0)."""

    def __init__(self, stem):
        self.stem = stem
        self.entries = []

    def write(self, time, points, cells, point_data):
        self.entries.append((time, f"{self.stem}_{len(self.entries):04d}.vtu"))

    def write_collection(self):
        pass


def _mpi_max():
    from mpi4py import MPI
    return MPI.MAX


def _next_multiple(t, interval):
    """The first multiple of ``interval`` after ``t`` (computed, never stepped to)."""
    return (math.floor(t / interval * (1 + 1e-12)) + 1) * interval


def _restart(out, fingerprint, description, stepper, history, writer, schedule, preflight,
             source, comm=None):
    """Continue from the newest good checkpoint in ``out/checkpoints``: (t, steps,
    next_output). A truncated or corrupted newest checkpoint is skipped (with a warning) for
    the one before it; a checkpoint of another case is refused naming the changed keys."""
    expected = {k: (a.shape, a.dtype) for k, a in stepper.state_arrays().items()}

    def accept(path, data):
        try:
            written_for = str(data["fingerprint"])
        except (KeyError, ValueError):
            raise BadCheckpoint("no case fingerprint") from None
        if written_for != fingerprint:
            raise InputError(_different_case(path, data, description))
        problem = checkpoint_problem(data, expected, history.columns)
        if problem:
            raise BadCheckpoint(problem)

    if comm is None:
        path, data = load_good_checkpoint(out / "checkpoints", accept)
    else:   # rank 0 reads the checkpoint (and refuses it) for all
        loaded = None
        if comm.Get_rank() == 0:
            try:
                loaded = load_good_checkpoint(out / "checkpoints", accept)
            except InputError as exc:
                loaded = exc
        loaded = comm.bcast(loaded, root=0)
        if isinstance(loaded, InputError):
            raise loaded
        path, data = loaded
    t, steps = float(data["t"]), int(data["steps"])
    end, interval = schedule.end_time, schedule.interval
    where = f"{source}: " if source else ""
    if t > end * (1 + 1e-12):
        raise InputError(f"{where}run.end_time: {end:.6g} s is before the time of the "
                         f"checkpoint {path.name} ({t:.6g} s); set a later end_time to continue")
    stepper.restore({k[len("state_"):]: a for k, a in data.items() if k.startswith("state_")})
    if preflight is not None and (problem := preflight(stepper, t, steps)):
        raise InputError(f"{where}{problem}")
    history.load({k: data["h_" + k] for k in history.columns})
    times = data["snapshot_times"]
    files = [str(f) for f in data["snapshot_files"]][:len(times)]
    writer.entries = list(zip(map(float, times), files))
    # frames of the old run after the checkpoint would be mixed with the new ones: the new
    # run writes them again (under the same names when the schedule is unchanged)
    for frame in out.glob(f"{writer.stem}_*.vtu") if comm is None or comm.Get_rank() == 0 \
            else ():
        number = re.fullmatch(rf"{writer.stem}_(\d+)\.vtu", frame.name)
        if number and int(number.group(1)) >= len(files):
            frame.unlink(missing_ok=True)
    writer.write_collection()
    old_schedule = data["schedule"] if "schedule" in data else None
    if old_schedule is not None and np.array_equal(old_schedule, [end, interval]):
        next_output = float(data["next_output"])
    else:   # end_time or output_interval changed: the next output instant after t
        next_output = min(_next_multiple(t, interval), end) if t < end * (1 - 1e-12) \
            else math.inf
    return t, steps, next_output


def _different_case(path, data, description) -> str:
    try:
        old = json.loads(str(data["case_description"]))
    except (KeyError, ValueError):
        old = None
    allowed = ", ".join(RESTART_MAY_CHANGE)
    if not isinstance(old, dict) or not (changed := changed_keys(old, description)):
        return f"{path}: checkpoint was written for a different case"
    shown = ", ".join(changed[:4]) + (f" and {len(changed) - 4} more" if len(changed) > 4
                                     else "")
    return (f"{path}: checkpoint was written for a different case: changed {shown} (a "
            f"restart may change only {allowed} and --checkpoint-every)")


def checkpoint_problem(data, expected, columns) -> str | None:
    """Why the arrays of a checkpoint cannot be continued from, or None: every array a
    restart reads must be there with the right shape and type, the time finite and >= 0,
    the step count >= 0 and at most one history row per step (history_every thins them),
    the state finite."""
    def scalar(key, kinds):
        a = data.get(key)
        if a is None:
            return f"{key} is missing"
        if a.shape != () or a.dtype.kind not in kinds:
            return f"{key} is not a number"
        return None

    for key, kinds in (("t", "f"), ("steps", "iu"), ("next_output", "f")):
        if (problem := scalar(key, kinds)):
            return problem
    t, steps, next_output = float(data["t"]), int(data["steps"]), float(data["next_output"])
    if not (math.isfinite(t) and t >= 0):
        return f"time t = {t} is not a finite time >= 0"
    if steps < 0:
        return f"steps = {steps} is negative"
    if not next_output > t * (1 - 1e-12):
        return f"next_output = {next_output} is not after t = {t}"
    if "history_columns" not in data or [str(c) for c in data["history_columns"]] != columns:
        return "its history columns do not match the case"
    for k in columns:
        h = data.get("h_" + k)
        if h is None or h.ndim != 1 or h.dtype.kind != "f" or not 1 <= len(h) <= steps + 1:
            return (f"history column {k!r} does not have between 1 and one row per step "
                    f"({steps + 1})")
        if len(h) != len(data["h_time"]):
            return f"history column {k!r} is not as long as the times"
    times = data["h_time"]
    if not (np.all(np.isfinite(times)) and np.all(np.diff(times) >= 0) and times[-1] == t):
        return "its history times are not finite, increasing and ending at t"
    snap_t, snap_f = data.get("snapshot_times"), data.get("snapshot_files")
    if snap_t is None or snap_f is None or snap_t.ndim != 1 or snap_t.dtype.kind != "f" \
            or snap_f.ndim != 1 or snap_f.dtype.kind != "U" or len(snap_f) < len(snap_t):
        return "its list of snapshots is missing or malformed"
    if not (np.all(np.isfinite(snap_t)) and np.all(np.diff(snap_t) >= 0)
            and np.all(snap_t <= t * (1 + 1e-12))):
        return "its snapshot times are not finite, increasing and at most t"
    if [str(f) for f in snap_f[:len(snap_t)]] != [f"fields_{k:04d}.vtu"
                                                  for k in range(len(snap_t))]:
        return "its snapshot file names are not the run's own"
    for k, (shape, dtype) in expected.items():
        a = data.get("state_" + k)
        if a is None:
            return f"state array {k!r} is missing"
        if a.shape != shape or a.dtype.kind != dtype.kind:
            return (f"state array {k!r} has shape {a.shape} ({a.dtype}), the case gives "
                    f"{shape} ({dtype})")
        if a.dtype.kind == "f" and np.isnan(a).any():
            return f"state array {k!r} holds NaN"
        if k in ("v", "F", "x") and not np.all(np.isfinite(a)):
            return f"state array {k!r} is not finite"
    return None


def _finish(out, history, stepper, title, steps, t, wall_start, loop_start, status,
            contacts=None, reason=None):
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
    if reason is not None:
        summary["reason"] = reason          # why a failed run stopped
    if contacts is not None:
        summary["contacts"] = contacts
    if out is not None:
        write_history_csv(out / "history.csv", history.data, history.n)
        write_summary(out / "summary.json", summary)
    return summary
