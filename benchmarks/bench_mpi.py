"""Runs over MPI ranks: strong scaling measured here, and a model of larger runs from
measured figures (docs/performance.md, "Over MPI ranks").

    python benchmarks/bench_mpi.py                     # all parts, 2D 100k and 3D 60k nodes
    python benchmarks/bench_mpi.py --nodes 50k --steps 100
    mpiexec -n 2 python benchmarks/bench_mpi.py --pingpong    # the network part alone

Four parts:

1. strong scaling: the same case (bench_throughput's free block: neo-Hookean nu = 0.495,
   order 2, Barth-Jespersen, one thread per rank) through ``impactfv run`` on 1 and 2 ranks;
   the figure is the summary's node-stage updates per second of the time loop;
2. the network: ping-pong latency and bandwidth between two ranks, and the latency of an
   8-byte allreduce (``mpiexec -n 2 ... --pingpong``);
3. the halo: for METIS partitions of 3D box meshes into 2..64 parts, the ghost nodes and
   neighbour ranks per rank, fitted as ghosts = c (N/P)^(2/3);
4. the model: per rank and stage, time = (N/P) / r + 2 m alpha + b g (N/P)^(2/3) / beta
   + k alpha_allreduce log2 P + (ghost work) g (N/P)^(2/3) / r, with r the one-rank rate in
   3D, m the neighbour ranks, b the bytes per ghost and stage (state v, F, x and the
   gradients), g the fitted ghost factor; with contact also the gathered surface (N^(2/3)
   nodes of 432 B per stage) and its contact stage on every rank; parallel efficiency =
   ((N/P)/r) / time, for 8 to 1024 ranks and 1M, 10M, 100M nodes.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from bench_throughput import make_case, parse_size, side_for  # noqa: E402


def mpiexec() -> str:
    import sysconfig
    found = next((str(f / "mpiexec") for f in (Path(sys.executable).parent,
                                               Path(sysconfig.get_path("scripts")))
                  if (f / "mpiexec").exists()), None) or shutil.which("mpiexec")
    if found is None:
        sys.exit("bench_mpi: no mpiexec (pip install '.[mpi]')")
    return found


def toml_of(case: dict) -> str:
    """The benchmark case as TOML (flat enough for a small writer)."""
    def value(v):
        if isinstance(v, str):
            return f'"{v}"'
        if isinstance(v, (list, tuple)):
            return "[" + ", ".join(value(x) for x in v) + "]"
        if isinstance(v, dict):
            return "{ " + ", ".join(f"{k} = {value(x)}" for k, x in v.items()) + " }"
        return repr(v)
    lines = [f'title = "{case["title"]}"', "[run]"]
    lines += [f"{k} = {value(v)}" for k, v in case["run"].items()]
    lines += ["[output]", "fields = []"]
    for key in ("material", "body"):
        for entry in case[key]:
            lines.append(f"[[{key}]]")
            lines += [f"{k} = {value(v)}" for k, v in entry.items()]
    return "\n".join(lines) + "\n"


def strong_scaling(nodes: int, steps: int, dim: int):
    side = side_for(nodes, dim)
    case = make_case(side, 2, dim)
    rates = {}
    with tempfile.TemporaryDirectory() as tmp:
        # end_time from the stable time step: about `steps` steps
        from impactfv import load_case
        from impactfv.scheme.stepper import FVStepper
        stepper = FVStepper(load_case(case))
        case["run"]["end_time"] = steps * stepper.stable_dt()
        case["run"]["output_interval"] = case["run"]["end_time"]
        path = Path(tmp) / "case.toml"
        path.write_text(toml_of(case))
        for ranks in (1, 2):
            cmd = [sys.executable, "-m", "impactfv.cli", "run", str(path), "-o",
                   str(Path(tmp) / f"r{ranks}"), "--no-progress"]
            if ranks > 1:
                cmd = [mpiexec(), "-n", str(ranks), *cmd]
            env = dict(os.environ, NUMBA_NUM_THREADS="1")
            subprocess.run(cmd, check=True, capture_output=True, env=env)   # compiles
            subprocess.run(cmd, check=True, capture_output=True, env=env)
            summary = json.loads((Path(tmp) / f"r{ranks}" / "summary.json").read_text())
            rates[ranks] = summary["node_stage_updates_per_second"]
            n = summary["nodes"]
    print(f"strong scaling, {dim}D, {n} nodes, {steps} steps, one thread per rank:")
    for ranks, rate in rates.items():
        print(f"  {ranks} rank(s): {rate / 1e6:6.2f} M node-stages/s "
              f"(speed-up {rate / rates[1]:.2f}, efficiency {rate / rates[1] / ranks:.2f})")
    return n, rates


def pingpong():
    """Run under mpiexec -n 2: latency, bandwidth, allreduce latency (printed by rank 0)."""
    import numpy as np
    from mpi4py import MPI
    comm = MPI.COMM_WORLD
    rank = comm.Get_rank()
    results = {}
    for size in (8, 1024, 65536, 1 << 20, 8 << 20):
        buf = np.zeros(size // 8)
        repeats = 200 if size <= 65536 else 20
        comm.Barrier()
        t0 = time.perf_counter()
        for _ in range(repeats):
            if rank == 0:
                comm.Send(buf, dest=1)
                comm.Recv(buf, source=1)
            elif rank == 1:
                comm.Recv(buf, source=0)
                comm.Send(buf, dest=0)
        results[size] = (time.perf_counter() - t0) / (2 * repeats)
    one, out = np.ones(1), np.empty(1)
    comm.Barrier()
    t0 = time.perf_counter()
    for _ in range(2000):
        comm.Allreduce(one, out)
    allreduce = (time.perf_counter() - t0) / 2000
    if rank == 0:
        latency = results[8]
        bandwidth = (8 << 20) / (results[8 << 20] - latency)
        print(json.dumps({"latency_s": latency, "bandwidth_Bps": bandwidth,
                          "allreduce_s": allreduce,
                          "one_way_s": {str(k): v for k, v in results.items()}}))


def network():
    out = subprocess.run([mpiexec(), "-n", "2", sys.executable, os.path.abspath(__file__),
                          "--pingpong"], check=True, capture_output=True, text=True,
                         env=dict(os.environ, NUMBA_NUM_THREADS="1"))
    figures = json.loads(out.stdout.strip().splitlines()[-1])
    print("network (2 ranks on this machine, shared memory):")
    for size, t in figures["one_way_s"].items():
        print(f"  one-way {int(size):>9d} B: {t * 1e6:9.2f} us")
    print(f"  latency {figures['latency_s'] * 1e6:.2f} us, bandwidth "
          f"{figures['bandwidth_Bps'] / 1e9:.2f} GB/s, "
          f"allreduce {figures['allreduce_s'] * 1e6:.2f} us")
    return figures


def halo_statistics(sides=(16, 26, 40)):
    import numpy as np
    from impactfv import load_case
    from impactfv.parallel.partition import local_part, partition_nodes
    from impactfv.scheme.discretisation import discretise
    rows = []
    print("halo of METIS partitions of 3D boxes (ghosts and neighbour ranks per rank):")
    for side in sides:
        disc = discretise(load_case(make_case(side, 2, 3)))
        for parts in (2, 4, 8, 16, 32, 64):
            owner = partition_nodes(disc, parts)
            ghosts, neighbours = [], []
            for r in range(parts):
                p = local_part(disc, owner, r, n_blocks=1)
                ghosts.append(len(p.nodes) - p.n_owned)
                neighbours.append(len(set(p.ghost_owner.tolist())))
            per_rank = disc.n_nodes / parts
            rows.append((per_rank, float(np.mean(ghosts)), float(np.mean(neighbours))))
            print(f"  {disc.n_nodes:7d} nodes / {parts:2d}: {per_rank:9.0f} per rank, "
                  f"{np.mean(ghosts):7.0f} ghosts (max {max(ghosts)}), "
                  f"{np.mean(neighbours):4.1f} neighbours (max {max(neighbours)})")
    per_rank = np.array([r[0] for r in rows])
    ghosts = np.array([r[1] for r in rows])
    g = float(np.exp(np.mean(np.log(ghosts / per_rank ** (2 / 3)))))
    m = float(np.mean([r[2] for r in rows if r[0] < 20000])) if any(
        r[0] < 20000 for r in rows) else float(np.mean([r[2] for r in rows]))
    print(f"  fit: ghosts = {g:.2f} (N/P)^(2/3); neighbour ranks about {m:.1f}")
    return g, m


def model(rate, g, neighbours, net):
    import math
    alpha, beta, allreduce = net["latency_s"], net["bandwidth_Bps"], net["allreduce_s"]
    # bytes per ghost and stage in 3D: v, F, x (15 doubles) and the gradients of v and the
    # stress (9 components x 3 directions)
    per_ghost = 8 * (15 + 27)
    # bytes per gathered contact-surface node and stage: x, v, F, sigma, gradients, the
    # prescribed velocity (3 + 3 + 9 + 9 + 27 + 3 doubles)
    per_surface = 8 * 54
    print(f"model: r = {rate / 1e6:.2f} M node-stages/s per rank (3D, measured), "
          f"{per_ghost} B per ghost and stage, {neighbours:.0f} neighbours, alpha = "
          f"{alpha * 1e6:.2f} us, beta = {beta / 1e9:.2f} GB/s, allreduce "
          f"{allreduce * 1e6:.2f} us x log2 P, 2 per stage; a ghost costs the work of an owned "
          "node (its stress and gradient are computed, its edges to owned nodes twice)")

    def efficiency(total, P, surface):
        local = total / P
        ghosts = g * local ** (2 / 3)
        useful = local / rate
        time = (local + ghosts) / rate + 2 * neighbours * alpha + per_ghost * ghosts / beta \
            + 2 * allreduce * max(1.0, math.log2(P))
        if surface:
            # a contact face of N^(2/3) nodes, gathered on every rank (allgather, log2 P
            # latency terms) and its contact stage computed on every rank (about the cost of
            # as many volume nodes)
            S = total ** (2 / 3)
            time += S * per_surface / beta + alpha * max(1.0, math.log2(P)) + S / rate
        return useful / time

    for surface in (False, True):
        print("  parallel efficiency" + (", with a contact face of N^(2/3) nodes" if surface
                                         else ", no contact") + ":")
        print("                 P=8    P=64   P=256  P=1024")
        for total in (1e6, 1e7, 1e8):
            cells = [efficiency(total, P, surface) for P in (8, 64, 256, 1024)]
            print(f"    {total:7.0e} nodes " + "  ".join(f"{c:5.2f}" for c in cells))


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--nodes", default="100k", help="2D strong-scaling mesh size")
    parser.add_argument("--nodes-3d", default="60k", help="3D strong-scaling mesh size")
    parser.add_argument("--steps", type=int, default=240)
    parser.add_argument("--pingpong", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.pingpong:
        return pingpong()
    strong_scaling(parse_size(args.nodes), args.steps, 2)
    n3, rates3 = strong_scaling(parse_size(args.nodes_3d), max(10, args.steps // 4), 3)
    net = network()
    g, m = halo_statistics()
    model(rates3[1], g, m, net)


if __name__ == "__main__":
    main()
