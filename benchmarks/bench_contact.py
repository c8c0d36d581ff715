"""What contact costs per step: the stack of examples/stack_impact.toml (a disc striking three
stacked blocks on a floor, 1,441 nodes) with its seven contacts, against the same bodies with
fewer contacts, without friction, and without contact.

    NUMBA_NUM_THREADS=1 python benchmarks/bench_contact.py
    NUMBA_NUM_THREADS=1 python benchmarks/bench_contact.py --steps 100 --repeats 3

Each variant runs to ``--start`` (default 100 us, when every interface of the stack is
pressed) and then times ``--steps`` steps (``stepper.step(dt)`` with dt from
``stable_dt()``), in CPU time (``time.process_time``), the fastest of ``--repeats`` blocks.
Printed: ms per step, the share above the run without contact, and the mean number of
nodes in contact over the timed steps. The variants differ in physics (without contact the
bodies pass through each other), so only the cost is comparable, not the states.
"""

from __future__ import annotations

import argparse
import copy
import os
import time
import tomllib

from impactfv import load_case
from impactfv.scheme.stepper import FVStepper

EXAMPLE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples",
                       "stack_impact.toml")


def variants(case):
    """(label, case) of each variant of the stack."""
    pairs = [["disc", "top"], ["top", "middle"], ["middle", "bottom"]]
    floor = case["contact"][-1]
    out = [("7 contacts (every pair, floor), Coulomb mu = 0.3 / 0.5: the example", case)]
    slip = copy.deepcopy(case)
    for c in slip["contact"]:
        c["model"] = "slip"
        c.pop("friction", None)
    out.append(("7 contacts, slip (no friction)", slip))
    neighbours = copy.deepcopy(case)
    neighbours["contact"] = [{"bodies": p, "model": "coulomb", "friction": 0.3} for p in pairs]
    neighbours["contact"].append(copy.deepcopy(floor))
    out.append(("4 contacts (touching neighbours, floor), Coulomb", neighbours))
    free = copy.deepcopy(case)
    free["contact"] = []
    out.append(("no contact", free))
    return out


def time_per_step(case, start, steps, repeats):
    """Fastest CPU ms per step over ``repeats`` blocks of ``steps`` steps after ``start``,
    and the mean number of nodes in contact over those steps."""
    stepper = FVStepper(load_case(case))
    t = 0.0
    while t < start:
        dt = stepper.stable_dt()
        stepper.step(dt)
        t += dt
    blocks = []
    touching = []
    for _ in range(repeats):
        spent = 0.0
        for _ in range(steps):
            dt = stepper.stable_dt()
            c0 = time.process_time()
            stepper.step(dt)
            spent += time.process_time() - c0
            if stepper.contact is not None:
                touching.append(int((stepper.contact.memory != 0).any(axis=0).sum()))
        blocks.append(1e3 * spent / steps)
    touching = sum(touching) / len(touching) if touching else 0.0
    return min(blocks), touching, stepper.disc.X.shape[0]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--start", type=float, default=100e-6, help="time to run first (s)")
    parser.add_argument("--steps", type=int, default=50, help="steps per timed block")
    parser.add_argument("--repeats", type=int, default=3, help="timed blocks")
    args = parser.parse_args(argv)
    with open(EXAMPLE, "rb") as f:
        case = tomllib.load(f)
    case.pop("output", None)
    rows = [(label, *time_per_step(c, args.start, args.steps, args.repeats))
            for label, c in variants(case)]
    base = rows[-1][1]
    print(f"stack of examples/stack_impact.toml, {rows[0][3]} nodes, one process, CPU time, "
          f"fastest of {args.repeats} x {args.steps} steps after {args.start * 1e6:.0f} us")
    print(f"{'variant':<66} {'ms/step':>8} {'over none':>10} {'in contact':>11}")
    for label, ms, touching, _ in rows:
        print(f"{label:<66} {ms:8.3f} {ms - base:+10.3f} {touching:11.0f}")


if __name__ == "__main__":
    main()
