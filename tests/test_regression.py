"""Regression against stored values: kernel rewrites (ordering, threading, fusion) must not
change results beyond round-off. Regenerate tests/data/regression.json only on purpose:
    python tests/test_regression.py --store [case ...]
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from impactfv import load_case, run
from impactfv.validation.bars import two_bars
from impactfv.validation.standing_wave import case_dict

DATA = Path(__file__).parent / "data" / "regression.json"


def cases():
    wave = case_dict(12, order=2, limiter="barth_jespersen", end_fraction=0.05)
    bars = two_bars(divisions=(30, 4), divisions_right=(24, 5), end_time=1.2e-5,
                    model="slip", rollers=False, tangential=5.0)
    out = {"standing_wave": wave, "bars": bars}
    for method in ("fem-t3", "fem-q4md"):
        # free sides: with roller sides and matching meshes the T3 contact chooses between
        # two equally near segments by round-off, which is no regression to pin down
        fe = two_bars(divisions=(30, 4), end_time=1.2e-5, model="slip", rollers=False,
                      tangential=3.0)
        fe["run"]["method"] = method
        out[method] = fe
    return out


def fingerprint(result):
    out = {}
    for name, body in sorted(result.bodies.items()):
        for key in ("points", "velocity", "pressure"):
            values = np.asarray(body[key], float)
            out[f"{name}.{key}.sum"] = float(values.sum())
            out[f"{name}.{key}.norm"] = float(np.linalg.norm(values))
            out[f"{name}.{key}.first"] = values.ravel()[:3].tolist()
    for key in ("time", "total_energy", "kinetic_energy"):
        out[f"history.{key}.last"] = float(result.history[key][-1])
    out["steps"] = int(result.summary["steps"])
    return out


def compute(threads=None):
    out = {}
    for name, case in cases().items():
        if threads is not None:
            case["run"]["threads"] = threads
        out[name] = fingerprint(run(load_case(case)))
    return out


def test_results_match_stored_values():
    check(compute(threads=1))


def test_two_threads_match_stored_values():
    """The same cases with two numba threads (a pool of two, in a subprocess: the tests'
    own pool has one thread): other edge blocks and reduction orders, the same values."""
    env = dict(os.environ, NUMBA_NUM_THREADS="2")
    proc = subprocess.run([sys.executable, __file__, "--print", "--threads", "2"],
                          capture_output=True, text=True, env=env, timeout=900)
    assert proc.returncode == 0, proc.stderr
    now = json.loads(proc.stdout.strip().splitlines()[-1])
    assert now.pop("threads_in_run") == 2
    check(now)


def check(now):
    stored = json.loads(DATA.read_text())
    for case, values in stored.items():
        assert now[case]["steps"] == values["steps"], case
        for key, ref in values.items():
            got = np.asarray(now[case][key], float)
            ref = np.asarray(ref, float)
            # compare against the size of the whole field (a sum or a few entries can be
            # near zero by symmetry or far from the action)
            field = key.rsplit(".", 1)[0]
            scale = values.get(field + ".norm", np.abs(ref).max())
            scale = max(float(scale), float(np.abs(ref).max()), 1e-30)
            assert np.allclose(got, ref, rtol=1e-9, atol=1e-9 * scale), (case, key, got, ref)


if __name__ == "__main__" and "--print" in sys.argv:
    # the fingerprints as one JSON line (test_two_threads_match_stored_values), and the
    # numba thread count the runs used
    import numba

    from impactfv.scheme.stepper import FVStepper

    threads = int(sys.argv[sys.argv.index("--threads") + 1])
    seen = set()
    step = FVStepper.step

    def counting_step(self, dt, with_monitors=True):
        seen.add(numba.get_num_threads())
        return step(self, dt, with_monitors)

    FVStepper.step = counting_step
    out = compute(threads=threads)
    out["threads_in_run"] = seen.pop() if len(seen) == 1 else sorted(seen)
    print(json.dumps(out))

if __name__ == "__main__" and "--store" in sys.argv:
    # --store NAME ... stores only the named cases (the others keep their stored values)
    names = sys.argv[sys.argv.index("--store") + 1:]
    stored = json.loads(DATA.read_text()) if DATA.exists() else {}
    stored.update({k: v for k, v in compute().items() if not names or k in names})
    DATA.write_text(json.dumps(stored, indent=1) + "\n")
