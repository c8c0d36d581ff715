"""The whole time loop against the kernels alone, in CPU time, with a profile by kernel.

    python benchmarks/bench_loop.py                      # 2D, 100k nodes, 1 thread
    python benchmarks/bench_loop.py --dim 3 --nodes 97k --steps 5
    NUMBA_NUM_THREADS=1 python benchmarks/bench_loop.py --repeats 7

The case is the one of bench_throughput.py (neo-Hookean, nu = 0.495, order 2,
Barth-Jespersen, traction-free). One numba thread; every figure is CPU time of this process
(``time.process_time``), which a shared machine disturbs far less than wall-clock time
(the load of other processes still costs cache and memory bandwidth: repeat and compare the
spread). Three measurements, each the fastest of ``--repeats`` blocks of ``--steps`` steps
(the median and range are printed too):

* kernels only: ``stepper.step(dt)``, dt from ``stable_dt()`` outside the timing (what
  bench_throughput.py reports);
* full run: ``impactfv.pipeline.run_stepper`` on a fresh stepper of the same mesh, with a
  history row every step (``[output] history_every = 1``, the default) and no output folder:
  per step the time step, the step, the state check, the history row, the Python of the loop;
  each block is a whole run, so its per-step figure includes the run's one-off costs (the
  first state's monitors and time step, the first stage's stress, the fields of the result)
  spread over the block: 40 steps per block in 2D (4 in 3D) by default, as a run of a few
  hundred steps; those one-off costs are printed on their own (a 1-step run less one step);
* profile: the loop body of the run with every kernel of ``impactfv.backends.cpu``
  wrapped in a CPU-time timer; "outside kernels" is the rest (Python, copies, history).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from bench_throughput import KernelTimer, make_case, parse_size, side_for  # noqa: E402


class CPUKernelTimer(KernelTimer):
    def _wrap(self, name, fn):
        seconds, calls, clock = self.seconds, self.calls, time.process_time

        def timed(*args, **kwargs):
            t0 = clock()
            out = fn(*args, **kwargs)
            seconds[name] = seconds.get(name, 0.0) + (clock() - t0)
            calls[name] = calls.get(name, 0) + 1
            return out
        return timed


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--dim", type=int, default=2, choices=(2, 3))
    p.add_argument("--nodes", default=None, help="node count (default 100k in 2D, 97k in 3D)")
    p.add_argument("--steps", type=int, default=None, help="steps per block (40 2D, 4 3D)")
    p.add_argument("--repeats", type=int, default=5, help="blocks per measurement (5)")
    args = p.parse_args(argv)
    import numba

    import impactfv
    from impactfv.pipeline.run import Schedule, run_stepper
    from impactfv.backends import cpu as K
    from impactfv.scheme.stepper import FVStepper

    numba.set_num_threads(1)
    nodes = parse_size(args.nodes or ("100k" if args.dim == 2 else "97k"))
    steps = args.steps or (40 if args.dim == 2 else 4)
    case = impactfv.load_case(make_case(side_for(nodes, args.dim), 2, args.dim))
    s = FVStepper(case)
    n = s.disc.n_nodes
    for _ in range(3):
        s.step(s.stable_dt())
        s.check(0, 0.0)
        s.history_row()
    clock = time.process_time
    kernels = []
    for _ in range(args.repeats):
        total = 0.0
        for _ in range(steps):
            dt = s.stable_dt()
            t0 = clock()
            s.step(dt)
            total += clock() - t0
        kernels.append(total / steps)
    runs = []
    for _ in range(args.repeats):
        fresh = FVStepper(case, disc=s.disc)
        t0 = clock()
        run_stepper(fresh, Schedule(1.0, None, steps, 1, None))
        runs.append((clock() - t0) / steps)
    single = []
    for _ in range(args.repeats):
        fresh = FVStepper(case, disc=s.disc)
        t0 = clock()
        run_stepper(fresh, Schedule(1.0, None, 1, 1, None))
        single.append(clock() - t0)
    with CPUKernelTimer(K) as timer:
        t0 = clock()
        for i in range(steps):
            dt = s.stable_dt()
            s.step(dt)
            s.check(i, 0.0)
            s.history_row()
        loop = clock() - t0

    def line(label, xs):
        best = min(xs)
        return (f"{label:13s} {1e3 * best:8.2f} ms/step ({2 * n / best / 1e6:5.2f} M node-stage "
                f"updates/s); median {1e3 * statistics.median(xs):.2f}, range "
                f"{1e3 * min(xs):.2f}-{1e3 * max(xs):.2f} ms over {len(xs)} blocks")

    print(f"{args.dim}D, {n} nodes, order 2 (Barth-Jespersen), 1 thread, CPU time, "
          f"{steps} steps per block")
    print(line("kernels only", kernels))
    print(line("full run", runs))
    print(f"full run / kernels only = {min(runs) / min(kernels):.3f} (fastest blocks), "
          f"{statistics.median(runs) / statistics.median(kernels):.3f} (medians)")
    one_off = min(single) - min(runs)
    print(f"one-off costs of a run (a 1-step run less one step of the full run): "
          f"{1e3 * one_off:.2f} ms, {one_off / min(runs):.2f} steps' worth; per step without "
          f"them {1e3 * (min(runs) - one_off / steps):.2f} ms "
          f"({2 * n / (min(runs) - one_off / steps) / 1e6:.2f} M node-stage updates/s)")
    print("profile of the run's loop body (ms per step, share of the loop):")
    total = 0.0
    for name, sec in sorted(timer.seconds.items(), key=lambda kv: -kv[1]):
        total += sec
        print(f"  {name:26s} {1e3 * sec / steps:8.2f} {100 * sec / loop:5.1f}%  "
              f"({timer.calls[name] / steps:g} calls per step)")
    print(f"  {'outside kernels':26s} {1e3 * (loop - total) / steps:8.2f} "
          f"{100 * (loop - total) / loop:5.1f}%")
    print(f"  {'loop':26s} {1e3 * loop / steps:8.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
