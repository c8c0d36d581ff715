"""Throughput of the finite-volume time loop: node-stage updates per second.

    python benchmarks/bench_throughput.py                       # default sizes, 1 and 2 threads
    python benchmarks/bench_throughput.py --sizes 10k,100k,1M --threads 1,2 --steps 20
    python benchmarks/bench_throughput.py --json results/bench.json

One neo-Hookean square body (density 8930, E 585e6, nu 0.495, velocity
["10*sin(300*x)", "5*cos(300*y)"], traction-free edges, "alternate" rectangle mesh) is
built with ``impactfv.load_case(dict)`` and ``impactfv.scheme.stepper.FVStepper(case)``. For each size,
order 2 (Barth-Jespersen) and order 1, and each numba thread count, the script reports:

* node-stage updates per second = nodes x 2 RK stages x steps / seconds spent in
  ``stepper.step(dt)`` (after warm-up steps, so numba compilation is excluded);
* the time per step split by kernel (stress_and_fields or compute_stress, limited_gradient,
  assemble_rates, relax_towards_positions, rk_update and rk_update_last inside ``step``;
  stable_time_step, state_is_bad and monitors, which ``impactfv.run`` calls outside it only
  when the last stage did not give them). The split is taken in a second pass in
  which every kernel of ``impactfv.backends.cpu`` is temporarily replaced by a timing
  wrapper, so it follows whatever arguments the stepper passes; "other" is step time not
  spent in a kernel (array copies, Python);
* peak resident memory (ru_maxrss) per node. Each size runs in a fresh subprocess, so sizes
  do not pollute each other; the figure is (peak - baseline) / nodes, where the baseline is
  the peak after imports and the warm-up on a tiny case;
* the ratio of time per step between sizes about 4x apart (node ratio within 3.4 .. 4.6),
  which is 4.0 for perfectly linear scaling. The default sizes include such pairs
  (25k -> 100k and 250k -> 1M).

Sizes are node counts (k = 1e3, M = 1e6); the mesh is the nearest square n x n grid of
nodes. ``--steps`` defaults to a size-dependent count (6 .. 300) that keeps each block to
about a second; ``--repeats`` blocks (default 3) are run per configuration and pass, and the
fastest block is reported (per-step minimum and median are in the JSON and the table).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import resource
import subprocess
import sys
import time

DEFAULT_SIZES = "10k,25k,100k,250k,1M"
KERNELS_IN_STEP = ("stress_and_fields", "compute_stress", "pack_velocity_and_stress",
                   "limited_gradient", "assemble_rates", "relax_towards_positions",
                   "rk_update", "rk_update_last", "smallest_time_step_of_candidates")
KERNELS_PER_STEP = ("stable_time_step", "state_is_bad", "monitors")


# ------------------------------------------------------------------------------ the case

def make_case(nodes_per_side: int, order: int, dim: int = 2) -> dict:
    n = nodes_per_side - 1
    if dim == 2:
        mesh = {"generator": "rectangle", "origin": [0.0, 0.0], "size": [0.1, 0.1],
                "divisions": [n, n], "pattern": "alternate"}
        velocity = ["10*sin(300*x)", "5*cos(300*y)"]
    else:
        mesh = {"generator": "box", "origin": [0.0] * 3, "size": [0.1] * 3,
                "divisions": [n] * 3}
        velocity = ["10*sin(300*x)", "5*cos(300*y)", "3*sin(200*z)"]
    return {
        "title": f"throughput benchmark {nodes_per_side}^{dim} nodes",
        "run": {"end_time": 1.0, "cfl": 0.4, "order": order,
                "limiter": "barth_jespersen" if order == 2 else "none"},
        "material": [{"name": "copper", "model": "neo_hookean", "density": 8930.0,
                      "youngs_modulus": 585e6, "poisson_ratio": 0.495}],
        "body": [{"name": "block", "material": "copper", "velocity": velocity,
                  "mesh": mesh}],
    }


def parse_size(text: str) -> int:
    text = text.strip().lower()
    scale = 1
    if text.endswith("k"):
        scale, text = 1_000, text[:-1]
    elif text.endswith("m"):
        scale, text = 1_000_000, text[:-1]
    return int(round(float(text) * scale))


def side_for(nodes: int, dim: int = 2) -> int:
    return max(3, int(round(nodes ** (1.0 / dim))))


def auto_steps(nodes: int) -> int:
    return int(max(6, min(300, round(2e6 / nodes))))


def busy_cpu_seconds() -> float | None:
    """CPU seconds all processes of the machine have used (from /proc/stat), or None."""
    try:
        with open("/proc/stat") as fh:
            fields = fh.readline().split()[1:]
    except OSError:
        return None
    ticks = [int(f) for f in fields]
    idle = ticks[3] + (ticks[4] if len(ticks) > 4 else 0)  # idle + iowait
    busy = sum(ticks[:8]) - idle  # user nice system idle iowait irq softirq steal
    return busy / os.sysconf("SC_CLK_TCK")


def children_cpu_seconds() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def maxrss_bytes() -> int:
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return rss if sys.platform == "darwin" else rss * 1024


def current_rss_bytes() -> int:
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except OSError:
        return 0


# ------------------------------------------------------------------------------ timing

class KernelTimer:
    """Replace every kernel of ``impactfv.backends.cpu`` by a timing wrapper, then restore.

    Only the loops defined in backends/cpu.py are wrapped (not the loop bodies and point
    functions they compile), and only after a warm-up, so no compilation happens while they are wrapped.
    """

    def __init__(self, module):
        self.module = module
        self.seconds: dict[str, float] = {}
        self.calls: dict[str, int] = {}
        self._saved = {}

    def __enter__(self):
        for name, obj in list(vars(self.module).items()):
            py = getattr(obj, "py_func", None)
            if py is None or name.startswith("_") or py.__module__ != self.module.__name__:
                continue
            self._saved[name] = obj
            self.module.__dict__[name] = self._wrap(name, obj)
        return self

    def _wrap(self, name, fn):
        seconds, calls, clock = self.seconds, self.calls, time.perf_counter

        def timed(*args, **kwargs):
            t0 = clock()
            out = fn(*args, **kwargs)
            seconds[name] = seconds.get(name, 0.0) + (clock() - t0)
            calls[name] = calls.get(name, 0) + 1
            return out
        return timed

    def __exit__(self, *exc):
        for name, obj in self._saved.items():
            self.module.__dict__[name] = obj
        self._saved.clear()


def warm_up(solver, steps: int = 3):
    """Compile / load from the numba cache and touch every array."""
    for _ in range(steps):
        solver.step(solver.stable_dt())
        solver.check(0, 0.0)
        solver.history_row()


def throughput_block(solver, steps: int) -> list[float]:
    """Seconds of each of ``steps`` stepper.step(dt) calls (stable_dt outside the timing)."""
    times = []
    for _ in range(steps):
        dt = solver.stable_dt()
        t0 = time.perf_counter()
        solver.step(dt)
        times.append(time.perf_counter() - t0)
    solver.check(steps, 0.0)
    return times


def breakdown_block(solver, steps: int, K) -> dict:
    """The loop body of impactfv.run (stable_dt, step, check, monitors) with every
    kernel wrapped by a timer."""
    with KernelTimer(K) as timer:
        step_total = 0.0
        t_loop = time.perf_counter()
        for i in range(steps):
            dt = solver.stable_dt()
            t0 = time.perf_counter()
            solver.step(dt)
            step_total += time.perf_counter() - t0
            solver.check(i, 0.0)
            solver.history_row()
        loop_total = time.perf_counter() - t_loop
    return {"loop": loop_total, "step": step_total, "seconds": dict(timer.seconds),
            "calls": dict(timer.calls)}


def summarize(n: int, steps: int, blocks: list[list[float]], breakdowns: list[dict]) -> dict:
    """Keep the fastest block of each pass (robust to bursts of load from other processes)."""
    means = [sum(b) / steps for b in blocks]
    mean = min(means)
    all_steps = sorted(t for b in blocks for t in b)
    best = min(breakdowns, key=lambda d: d["loop"])
    per_kernel = {k: best["seconds"][k] / steps for k in sorted(best["seconds"])}
    in_step = sum(v for k, v in per_kernel.items() if k not in KERNELS_PER_STEP)
    return {
        "steps": steps,
        "repeats": len(blocks),
        "step_s_mean": mean,
        "step_s_block_means": means,
        "step_s_median": all_steps[len(all_steps) // 2],
        "step_s_min": all_steps[0],
        "node_stage_updates_per_s": 2.0 * n / mean,
        "breakdown_s_per_step": per_kernel,
        "breakdown_calls_per_step": {k: best["calls"][k] / steps for k in sorted(best["calls"])},
        "breakdown_step_s": best["step"] / steps,
        "breakdown_other_in_step_s": best["step"] / steps - in_step,
        "breakdown_loop_s": best["loop"] / steps,
    }


def worker(nodes_requested: int, threads: list[int], steps: int | None, orders: list[int],
           repeats: int, dim: int = 2):
    """Runs in a fresh subprocess for one size; prints one JSON object on stdout."""
    import numba
    import numpy as np

    import impactfv
    from impactfv.backends import cpu as K
    from impactfv.scheme.stepper import FVStepper

    # warm-up on a tiny case: loads every kernel from the numba cache (or compiles it)
    for order in orders:
        tiny = FVStepper(impactfv.load_case(make_case(8 if dim == 2 else 4, order, dim)))
        for t in threads:
            numba.set_num_threads(t)
            for _ in range(2):
                tiny.step(tiny.stable_dt())
            tiny.check(0, 0.0)
            tiny.history_row()
    del tiny
    baseline = maxrss_bytes()
    baseline_now = current_rss_bytes()

    side = side_for(nodes_requested, dim)
    t0 = time.perf_counter()
    case = impactfv.load_case(make_case(side, orders[0], dim))
    t1 = time.perf_counter()
    solver = FVStepper(case)
    t2 = time.perf_counter()
    model = solver.disc
    n = model.n_nodes
    steps = steps or auto_steps(n)
    rss_after_setup = current_rss_bytes()
    rss_running = 0
    arrays = sum(a.nbytes for a in vars(model).values() if isinstance(a, np.ndarray))
    runs = []
    for order in orders:
        # one solver (fresh state, shared model) per thread count; the blocks of the thread
        # counts are interleaved so that a burst of outside load hits them alike
        case.run = case.run.model_copy(update={
            "order": order, "limiter": "barth_jespersen" if order == 2 else "none"})
        solvers = {t: FVStepper(case, disc=model) for t in threads}
        for t in threads:
            numba.set_num_threads(t)
            warm_up(solvers[t])
        blocks = {t: [] for t in threads}
        breakdowns = {t: [] for t in threads}
        for _ in range(repeats):
            for t in threads:
                numba.set_num_threads(t)
                blocks[t].append(throughput_block(solvers[t], steps))
        for _ in range(repeats):
            for t in threads:
                numba.set_num_threads(t)
                breakdowns[t].append(breakdown_block(solvers[t], steps, K))
        for t in threads:
            res = summarize(n, steps, blocks[t], breakdowns[t])
            res.update(order=order, threads=t, nodes=n)
            runs.append(res)
        owned = {id(a): a for a in vars(solvers[threads[0]]).values()
                 if isinstance(a, np.ndarray) and a.base is None}  # xdot is v
        solver_arrays = sum(a.nbytes for a in owned.values())
        # resident set with one solver alive
        rss_running = max(rss_running,
                          current_rss_bytes() - (len(solvers) - 1) * solver_arrays)
        del solvers
    peak = maxrss_bytes()
    print(json.dumps({
        "nodes": n, "edges": int(model.n_edges), "side": side, "steps": steps,
        "setup_s": {"load_case": t1 - t0, "build_model_and_solver": t2 - t1},
        "memory": {"baseline_peak_bytes": baseline, "peak_bytes": peak,
                   "peak_bytes_per_node": (peak - baseline) / n,
                   "resident_bytes_per_node": (rss_running - baseline_now) / n,
                   "resident_after_setup_bytes_per_node": (rss_after_setup - baseline_now) / n,
                   "model_and_solver_arrays_bytes_per_node": (arrays + solver_arrays) / n},
        "threading_layer": numba.threading_layer(),
        "runs": runs,
    }))


# ------------------------------------------------------------------------------ driver

def fmt_n(n: int) -> str:
    return f"{n / 1e6:.2f}M" if n >= 1e6 else f"{n / 1e3:.1f}k"


def machine() -> dict:
    info = {"nproc": os.cpu_count(), "cpu": platform.processor() or platform.machine(),
            "python": platform.python_version()}
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    info["cpu"] = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    try:
        import numba
        import numpy
        info.update(numba=numba.__version__, numpy=numpy.__version__)
    except ImportError:
        pass
    return info


def report(results: list[dict], info: dict) -> str:
    out = []
    out.append(f"machine: {info.get('cpu')}, {info.get('nproc')} CPUs, python "
               f"{info.get('python')}, numba {info.get('numba')}, numpy {info.get('numpy')}, "
               f"threading layer {results[0].get('threading_layer') if results else '?'}")
    out.append("")
    out.append("Throughput (time in solver.step only, fastest block of --repeats; "
               "node-stage updates = nodes x 2 x steps)")
    out.append(f"{'nodes':>9} {'edges':>9} {'order':>5} {'thr':>3} {'steps':>5} "
               f"{'ms/step':>9} {'median ms':>9} {'min ms':>9} {'ns/node-stage':>13} "
               f"{'M upd/s':>8}")
    for r in results:
        for run in r["runs"]:
            ms = 1e3 * run["step_s_mean"]
            out.append(f"{fmt_n(r['nodes']):>9} {r['edges']:>9} {run['order']:>5} "
                       f"{run['threads']:>3} {run['steps']:>5} {ms:>9.3f} "
                       f"{1e3 * run['step_s_median']:>9.3f} {1e3 * run['step_s_min']:>9.3f} "
                       f"{1e9 / run['node_stage_updates_per_s']:>13.1f} "
                       f"{run['node_stage_updates_per_s'] / 1e6:>8.2f}")
    out.append("")
    names = []
    for r in results:
        for run in r["runs"]:
            for k in run["breakdown_s_per_step"]:
                if k not in names:
                    names.append(k)
    order_key = {k: i for i, k in enumerate(KERNELS_IN_STEP + KERNELS_PER_STEP)}
    names.sort(key=lambda k: order_key.get(k, len(order_key)))
    in_step = [k for k in names if k not in KERNELS_PER_STEP]
    outside = [k for k in names if k in KERNELS_PER_STEP]
    short = {"stress_and_fields": "stress", "compute_stress": "stress",
             "pack_velocity_and_stress": "pack", "limited_gradient": "grad+limit",
             "assemble_rates": "assemble", "relax_towards_positions": "relax",
             "rk_update": "rk_upd", "rk_update_last": "rk_last",
             "smallest_time_step_of_candidates": "dt_cand",
             "stable_time_step": "stable_dt", "state_is_bad": "check", "monitors": "monitors"}
    out.append("Breakdown, ms per step (% of the run-loop step = step + stable_dt + check + "
               "monitors; fastest block of --repeats, kernels timed through wrappers);")
    out.append("kernels left of '|' run inside solver.step, once per RK stage (2x per step); "
               "'other' = rest of step (array copies, Python)")
    head = f"{'nodes':>9} {'ord':>3} {'thr':>3} "
    head += "".join(f"{short.get(k, k[:12]):>15}" for k in in_step)
    head += f"{'other':>15}{'step':>9} |"
    head += "".join(f"{short.get(k, k[:12]):>15}" for k in outside)
    head += f"{'loop':>9}"
    out.append(head)
    for r in results:
        for run in r["runs"]:
            b = run["breakdown_s_per_step"]
            loop = run["breakdown_loop_s"]

            def cell(s):
                return f"{1e3 * s:>8.3f} ({100 * s / loop:>2.0f}%)"
            line = f"{fmt_n(r['nodes']):>9} {run['order']:>3} {run['threads']:>3} "
            line += "".join(cell(b.get(k, 0.0)) for k in in_step)
            line += cell(run["breakdown_other_in_step_s"])
            line += f"{1e3 * run['breakdown_step_s']:>9.3f} |"
            line += "".join(cell(b.get(k, 0.0)) for k in outside)
            line += f"{1e3 * loop:>9.3f}"
            out.append(line)
    out.append("")
    out.append("Memory and setup (each size in a fresh process; per node = (peak ru_maxrss - "
               "baseline after imports and warm-up) / nodes)")
    out.append("  resident B/node: RSS while stepping minus baseline; arrays B/node: nbytes of "
               "the model and solver arrays")
    out.append(f"{'nodes':>9} {'baseline MiB':>12} {'peak MiB':>9} {'peak B/node':>11} "
               f"{'resident B/node':>15} {'arrays B/node':>13} {'load_case s':>11} "
               f"{'model+solver s':>14}")
    for r in results:
        m = r["memory"]
        out.append(f"{fmt_n(r['nodes']):>9} {m['baseline_peak_bytes'] / 2**20:>12.0f} "
                   f"{m['peak_bytes'] / 2**20:>9.0f} {m['peak_bytes_per_node']:>11.0f} "
                   f"{m['resident_bytes_per_node']:>15.0f} "
                   f"{m['model_and_solver_arrays_bytes_per_node']:>13.0f} "
                   f"{r['setup_s']['load_case']:>11.2f} "
                   f"{r['setup_s']['build_model_and_solver']:>14.2f}")
    out.append("")
    foreign = [(r["nodes"], r.get("foreign_cpu_cores")) for r in results]
    if all(f is not None for _, f in foreign):
        out.append("CPU used by other processes during each size (cores, averaged over its "
                   "run; 0 = quiet machine): "
                   + ", ".join(f"{fmt_n(n)} {f:.2f}" for n, f in foreign))
        if any(f > 0.1 for _, f in foreign):
            out.append("WARNING: the machine was not quiet; timings (2-thread ones most) are "
                       "inflated. Re-run when nothing else is running.")
        out.append("")
    out.append("Scaling: time per step at ~4x the nodes / time per step (4.00 = linear; "
               "normalised to exactly 4x)")
    pairs = scaling_pairs(results)
    if not pairs:
        out.append("  (no two sizes about 4x apart; add e.g. --sizes 25k,100k,250k,1M)")
    for p in pairs:
        out.append(f"  {fmt_n(p['from']):>8} -> {fmt_n(p['to']):>8} (x{p['node_ratio']:.2f}) "
                   f"order {p['order']} threads {p['threads']}: step time ratio "
                   f"{p['time_ratio']:.2f}, per 4x {p['time_ratio_per_4x']:.2f}")
    return "\n".join(out)


def scaling_pairs(results: list[dict]) -> list[dict]:
    pairs = []
    for i, a in enumerate(results):
        for b in results[i + 1:]:
            ratio = b["nodes"] / a["nodes"]
            if not 3.4 <= ratio <= 4.6:
                continue
            for ra in a["runs"]:
                for rb in b["runs"]:
                    if (ra["order"], ra["threads"]) != (rb["order"], rb["threads"]):
                        continue
                    tr = rb["step_s_mean"] / ra["step_s_mean"]
                    pairs.append({"from": a["nodes"], "to": b["nodes"], "node_ratio": ratio,
                                  "order": ra["order"], "threads": ra["threads"],
                                  "time_ratio": tr, "time_ratio_per_4x": tr * 4.0 / ratio})
    return pairs


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", default=DEFAULT_SIZES,
                   help=f"node counts, comma separated (default {DEFAULT_SIZES})")
    p.add_argument("--threads", default="1,2", help="numba thread counts (default 1,2)")
    p.add_argument("--steps", type=int, default=None,
                   help="timed steps per configuration (default: 6 .. 300 by size)")
    p.add_argument("--repeats", type=int, default=3,
                   help="blocks of --steps steps per configuration; the fastest is kept "
                        "(default 3)")
    p.add_argument("--orders", default="2,1", help="spatial orders (default 2,1)")
    p.add_argument("--json", help="also write all measurements to this JSON file")
    p.add_argument("--dim", type=int, default=2, choices=(2, 3),
                   help="2: a square of triangles (default); 3: a cube of tetrahedra")
    p.add_argument("--worker", type=int, help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    threads = [int(t) for t in args.threads.split(",") if t.strip()]
    orders = [int(o) for o in args.orders.split(",") if o.strip()]
    if args.worker is not None:
        worker(args.worker, threads, args.steps, orders, args.repeats, args.dim)
        return 0
    sizes = sorted(parse_size(s) for s in args.sizes.split(",") if s.strip())
    info = machine()
    results = []
    t_all = time.perf_counter()
    for nodes in sizes:
        t0 = time.perf_counter()
        cmd = [sys.executable, os.path.abspath(__file__), "--worker", str(nodes),
               "--threads", args.threads, "--orders", args.orders,
               "--repeats", str(args.repeats), "--dim", str(args.dim)]
        if args.steps:
            cmd += ["--steps", str(args.steps)]
        busy0, own0 = busy_cpu_seconds(), children_cpu_seconds()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        busy1, own1 = busy_cpu_seconds(), children_cpu_seconds()
        if proc.returncode != 0:
            sys.stderr.write(proc.stderr)
            print(f"size {nodes}: worker failed (exit {proc.returncode})", file=sys.stderr)
            return 1
        res = json.loads(proc.stdout.strip().splitlines()[-1])
        # CPU used by other processes while this size ran, in cores (0 on a quiet machine)
        res["foreign_cpu_cores"] = None if busy0 is None else \
            max(0.0, (busy1 - busy0) - (own1 - own0)) / wall
        results.append(res)
        best = max(r["node_stage_updates_per_s"] for r in res["runs"])
        foreign = res["foreign_cpu_cores"]
        print(f"[{fmt_n(res['nodes'])} nodes done in {wall:.0f} s, "
              f"best {best / 1e6:.2f} M node-stage updates/s"
              + (f", other processes used {foreign:.2f} cores" if foreign is not None else "")
              + "]", file=sys.stderr, flush=True)
    print(report(results, info))
    print(f"\n(total benchmark time {time.perf_counter() - t_all:.0f} s)")
    if args.json:
        os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
        with open(args.json, "w") as fh:
            json.dump({"machine": info, "results": results,
                       "scaling": scaling_pairs(results)}, fh, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
