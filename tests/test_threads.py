"""The thread count of a run: [run] threads and --threads, validated, respected, given back."""

import json
import os
import subprocess
import sys

import numba
import pytest

import impactfv
from impactfv import InputError, load_case, run
from impactfv.backends import threads as T
from impactfv.scheme.stepper import FVStepper

from conftest import block_case, run_cli


def test_passive_waits_are_asked_for_before_the_threads_start():
    # impactfv's import sets them unless the environment has its own
    out = subprocess.run([sys.executable, "-c", "import os, impactfv; print(os.environ['OMP_WAIT_POLICY'], "
                          "os.environ['KMP_BLOCKTIME'])"], capture_output=True, text=True,
                         env={k: v for k, v in os.environ.items()
                              if k not in ("OMP_WAIT_POLICY", "KMP_BLOCKTIME")})
    assert out.stdout.split() == ["passive", "0"], out.stderr
    kept = subprocess.run([sys.executable, "-c", "import impactfv, os; "
                           "print(os.environ['OMP_WAIT_POLICY'])"], capture_output=True,
                          text=True, env=dict(os.environ, OMP_WAIT_POLICY="active"))
    assert kept.stdout.strip() == "active"


@pytest.mark.parametrize("value", [0, -1])
def test_threads_must_be_positive(value):
    with pytest.raises(InputError, match=r"run\.threads"):
        load_case(block_case(threads=value))


def test_cli_threads_must_be_a_positive_number(tmp_path):
    case = tmp_path / "case.toml"
    case.write_text("[run]\nend_time = 1e-7\n")
    for bad in ("0", "two", "-3"):
        out = run_cli("run", case, "--threads", bad, "-o", tmp_path / "out")
        assert out.returncode == 2
        assert "--threads" in out.stderr and len(out.stderr.strip().splitlines()) == 1


def test_more_threads_than_the_pool_is_an_input_error():
    case = load_case(block_case(threads=numba.config.NUMBA_NUM_THREADS + 1))
    with pytest.raises(InputError, match=r"run\.threads = \d+: numba's thread pool"):
        run(case)


def test_default_is_the_usable_cores_capped_by_the_pool():
    assert T.usable_cores() == len(os.sched_getaffinity(0))
    assert T.default_threads() == min(len(os.sched_getaffinity(0)),
                                      numba.config.NUMBA_NUM_THREADS)


SCRIPT = r"""
import json, sys, numba, impactfv
from impactfv.scheme.stepper import FVStepper
sys.path.insert(0, sys.argv[1])
from conftest import block_case
seen = []
step = FVStepper.step
def counting(self, dt, with_monitors=True):
    seen.append(numba.get_num_threads())
    return step(self, dt, with_monitors)
FVStepper.step = counting
numba.set_num_threads(2)
out = {}
for threads in (1, 2, None):
    seen.clear()
    impactfv.run(impactfv.load_case(block_case(end_time=3e-7, threads=threads)))
    out[str(threads)] = sorted(set(seen))
out["after"] = numba.get_num_threads()
print(json.dumps(out))
"""


def test_a_run_uses_the_thread_count_it_was_given_and_gives_the_caller_back_its_own():
    env = dict(os.environ, NUMBA_NUM_THREADS="2")
    proc = subprocess.run([sys.executable, "-c", SCRIPT, os.path.dirname(__file__)],
                          capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr
    seen = json.loads(proc.stdout.strip().splitlines()[-1])
    default = min(len(os.sched_getaffinity(0)), 2)
    assert seen == {"1": [1], "2": [2], "None": [default], "after": 2}


def test_cli_threads_reaches_the_run(tmp_path):
    # --threads is run.threads: with a pool of one thread, 2 is refused naming the key
    case = tmp_path / "case.toml"
    from conftest import material_toml
    case.write_text("[run]\nend_time = 1e-7\n" + material_toml() + """
[[body]]
name = "block"
material = "copper"
mesh = { generator = "rectangle", origin = [0.0, 0.0], size = [0.01, 0.004], divisions = [4, 2] }
""")
    env = dict(os.environ, NUMBA_NUM_THREADS="1")
    out = run_cli("run", case, "--threads", "2", "-o", tmp_path / "out", env=env)
    assert out.returncode == 2, out.stderr
    assert "run.threads = 2" in out.stderr and len(out.stderr.strip().splitlines()) == 1
    ok = run_cli("run", case, "--threads", "1", "-o", tmp_path / "out", env=env)
    assert ok.returncode == 0, ok.stderr
