"""Throughput of the CUDA backend (``[run] backend = "cuda"``) on an NVIDIA GPU.

    python benchmarks/bench_cuda.py                  # 2D 1M and 4M nodes, 3D 1M nodes
    python benchmarks/bench_cuda.py --dims 2 --sizes 1M,4M,16M --steps 40
    python benchmarks/bench_cuda.py --json results/bench_cuda.json

The case is bench_throughput.py's free block (neo-Hookean copper, nu = 0.495, order 2 with
Barth-Jespersen, traction-free, "alternate" triangles or the box's tetrahedra) built with
``backend = "cuda"``. For each dimension and size it reports:

* node-stage updates per second = nodes x 2 Runge-Kutta stages x steps / seconds spent in
  ``stepper.step(dt)`` (the GPU's work is finished when a step returns: the last stage
  copies the next time step back), fastest of ``--repeats`` blocks, after warm-up steps
  (the kernels' compilation is reported separately);
* that rate times the bytes a node-stage must move (docs/performance.md, "A GPU backend":
  about 1,310 in 2D and 3,130 in 3D), against the device-to-device copy bandwidth measured
  here (bytes read plus bytes written): the fraction of the memory-bound ceiling reached;
* the time per step split by kernel (each launch synchronised and timed on the host, in a
  second pass) and "other": the host's part (launch overhead, small copies, Python);
* GPU memory per node (the device's used memory before and after the stepper is built) and
  the host's setup time (mesh, dual, stepper).

Needs numba-cuda and a CUDA GPU (not the simulator: it would take hours).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_throughput import make_case, parse_size, side_for  # noqa: E402

#: bytes a node-stage must move, counting every array once (docs/performance.md)
MODEL_BYTES = {2: 1310, 3: 3130}


def copy_bandwidth(cuda, nbytes: int = 2 << 30, repeats: int = 10) -> float:
    """Device-to-device copy bandwidth, bytes read plus written per second (best of
    ``repeats``)."""
    import numpy as np
    a = cuda.device_array(nbytes // 8, dtype=np.float64)
    b = cuda.device_array_like(a)
    b.copy_to_device(a)
    cuda.synchronize()
    best = float("inf")
    for _ in range(repeats):
        start, stop = cuda.event(), cuda.event()
        start.record()
        b.copy_to_device(a)
        stop.record()
        stop.synchronize()
        best = min(best, start.elapsed_time(stop) / 1e3)
    del a, b
    return 2.0 * nbytes / best


class TimedKernels:
    """A stand-in for a backends.cuda kernels namespace whose launches are synchronised and
    timed on the host."""

    def __init__(self, cuda, namespace, seconds):
        self._cuda, self._ns, self._seconds = cuda, namespace, seconds

    def __getattr__(self, name):
        kernel = getattr(self._ns, name)
        cuda, seconds = self._cuda, self._seconds

        class Launcher:
            def __getitem__(self, config):
                launch = kernel[config]

                def run(*args):
                    cuda.synchronize()
                    t0 = time.perf_counter()
                    launch(*args)
                    cuda.synchronize()
                    seconds[name] = seconds.get(name, 0.0) + time.perf_counter() - t0
                return run
        return Launcher()


def used_device_memory(cuda) -> int:
    try:
        free, total = cuda.current_context().get_memory_info()
    except AttributeError:      # the simulator
        return 0
    return total - free


def one_size(cuda, dim: int, nodes: int, steps: int, repeats: int) -> dict:
    import numpy as np

    import impactfv
    from impactfv.scheme.stepper import FVStepper

    side = side_for(nodes, dim)
    case_dict = make_case(side, 2, dim)
    case_dict["run"]["backend"] = "cuda"
    used0 = used_device_memory(cuda)
    t0 = time.perf_counter()
    solver = FVStepper(impactfv.load_case(case_dict))
    setup = time.perf_counter() - t0
    cuda.synchronize()
    used1 = used_device_memory(cuda)
    n = solver.disc.n_nodes
    for _ in range(3):
        solver.step(solver.stable_dt())
    blocks = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(steps):
            solver.step(solver.stable_dt())
        blocks.append((time.perf_counter() - t0) / steps)
    step_s = min(blocks)
    # the split by kernel, in a pass of its own (the synchronisations cost a little)
    seconds = {}
    dev = solver.loops
    plain = dev.k
    dev.k = TimedKernels(cuda, plain, seconds)
    t0 = time.perf_counter()
    for _ in range(steps):
        solver.step(solver.stable_dt())
    split_step = (time.perf_counter() - t0) / steps
    dev.k = plain
    solver._host()
    finite = all(bool(np.isfinite(a).all()) for a in (solver.v, solver.F, solver.x))
    rate = 2.0 * n / step_s
    per_kernel = {k: s / steps for k, s in sorted(seconds.items(), key=lambda kv: -kv[1])}
    return {"dim": dim, "nodes": n, "edges": int(solver.disc.n_edges), "steps": steps,
            "setup_s": setup, "step_s": step_s, "step_s_blocks": blocks,
            "node_stage_updates_per_s": rate,
            "model_bytes_per_node_stage": MODEL_BYTES[dim],
            "effective_bandwidth_Bps": rate * MODEL_BYTES[dim],
            "device_bytes_per_node": (used1 - used0) / n,
            "split_step_s": split_step, "split_s_per_step": per_kernel,
            "split_other_s_per_step": split_step - sum(per_kernel.values()),
            "state_finite": finite}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dims", default="2,3")
    parser.add_argument("--sizes", default="1M,4M", help="2D node counts, e.g. 1M,4M")
    parser.add_argument("--sizes-3d", default="1M",
                        help="3D node counts (the host builds a 1M-node box in about a "
                             "minute)")
    parser.add_argument("--steps", type=int, default=30)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", default=None)
    parser.add_argument("--allow-simulator", action="store_true",
                        help="run under numba-cuda's simulator (a smoke test of this script "
                             "on tiny sizes; its figures mean nothing)")
    args = parser.parse_args(argv)

    from numba import cuda
    if os.environ.get("NUMBA_ENABLE_CUDASIM") == "1" and not args.allow_simulator:
        print("bench_cuda: refusing to run under the simulator", file=sys.stderr)
        return 2
    if not cuda.is_available():
        print("bench_cuda: no CUDA GPU here", file=sys.stderr)
        return 2
    import impactfv
    from impactfv.scheme.stepper import FVStepper

    gpu = cuda.get_current_device()
    name = getattr(gpu, "name", b"the simulator")
    info = {"gpu": name.decode() if isinstance(name, bytes) else str(name),
            "compute_capability": list(getattr(gpu, "compute_capability", ()))}
    try:
        import numba
        import numba_cuda
        info.update(numba=numba.__version__, numba_cuda=numba_cuda.__version__)
    except (ImportError, AttributeError):
        pass
    simulated = os.environ.get("NUMBA_ENABLE_CUDASIM") == "1"
    bandwidth = copy_bandwidth(cuda, 1 << 20, 2) if simulated else copy_bandwidth(cuda)
    info["copy_bandwidth_Bps"] = bandwidth
    print(f"{info}", flush=True)
    results = []
    for dim in (int(d) for d in args.dims.split(",")):
        # compile the kernels on a tiny case (not cached on disk: every process compiles)
        t0 = time.perf_counter()
        tiny_case = make_case(8 if dim == 2 else 4, 2, dim)
        tiny_case["run"]["backend"] = "cuda"
        tiny = FVStepper(impactfv.load_case(tiny_case))
        for _ in range(2):
            tiny.step(tiny.stable_dt())
        compile_s = time.perf_counter() - t0
        print(f"{dim}D: kernels compiled and run on a tiny case in {compile_s:.1f} s",
              flush=True)
        for size in (args.sizes if dim == 2 else args.sizes_3d).split(","):
            r = one_size(cuda, dim, parse_size(size), args.steps, args.repeats)
            r["compile_s"] = compile_s
            r["fraction_of_copy_bandwidth"] = r["effective_bandwidth_Bps"] / bandwidth
            results.append(r)
            split = ", ".join(f"{k} {1e3 * s:.3f}" for k, s in r["split_s_per_step"].items())
            print(f"{dim}D {r['nodes']:>9,d} nodes: {1e3 * r['step_s']:.3f} ms/step, "
                  f"{r['node_stage_updates_per_s'] / 1e9:.3f} G node-stage/s, "
                  f"{r['effective_bandwidth_Bps'] / 1e12:.2f} TB/s by the model = "
                  f"{r['fraction_of_copy_bandwidth']:.2f} of the copy bandwidth, "
                  f"{r['device_bytes_per_node']:.0f} B/node on the GPU, setup "
                  f"{r['setup_s']:.1f} s, finite {r['state_finite']}\n"
                  f"    ms per step: {split}, other "
                  f"{1e3 * r['split_other_s_per_step']:.3f} (step with the split "
                  f"{1e3 * r['split_step_s']:.3f})", flush=True)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"machine": info, "results": results}, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
