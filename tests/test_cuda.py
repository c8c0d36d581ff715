"""The CUDA backend (backends/cuda.py) against the CPU backend: under numba-cuda's
simulator everywhere, and on the device where an NVIDIA GPU is present.

The simulator (NUMBA_ENABLE_CUDASIM=1, set before numba.cuda is imported, hence the
subprocesses) runs the same kernels thread by thread in Python, so the cases are tiny; on a
GPU, larger cases are added whose launches span many thread blocks. The cases, and why the
backends agree to 1e-10 relative on them, are in tests/cuda_cases.py. The comparisons skip
when numba-cuda is not installed; the refusals are checked either way.
"""

import importlib.util
import json
import os
import subprocess
import sys

import pytest

from conftest import material_toml, run_cli

HAVE_NUMBA_CUDA = importlib.util.find_spec("numba_cuda") is not None
needs_numba_cuda = pytest.mark.skipif(not HAVE_NUMBA_CUDA, reason="numba-cuda not installed")
SIM = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")

CASES = os.path.join(os.path.dirname(__file__), "cuda_cases.py")
EXPECTED = {"2d_two_bars_coulomb", "2d_wall_stick_gravity", "3d_wall_slip",
            "2d_order2_bj_clamp_traction", "2d_order2_bj_umuscl", "2d_order1_central",
            "3d_order2_venkatakrishnan"}
LARGER = {"2d_order2_bj_clamp_traction_larger", "2d_two_bars_coulomb_larger",
          "3d_order2_bj_larger", "3d_wall_slip_larger"}


def _worst_differences(env, *args):
    proc = subprocess.run([sys.executable, CASES, "both", *args], capture_output=True,
                          text=True, env=env, timeout=1800)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


@needs_numba_cuda
def test_cuda_kernels_give_the_cpu_results():
    worst = _worst_differences(SIM)
    assert set(worst) == EXPECTED
    for name, err in worst.items():
        assert err <= 1e-10, (name, err)


def _gpu_present() -> bool:
    if not HAVE_NUMBA_CUDA or os.environ.get("NUMBA_ENABLE_CUDASIM") == "1":
        return False
    from numba import cuda
    return cuda.is_available()


@needs_numba_cuda
def test_cuda_kernels_give_the_cpu_results_on_a_gpu():
    # the same on a real device, with larger cases spanning many thread blocks (skips on
    # machines without an NVIDIA GPU, CI's among them)
    if not _gpu_present():
        pytest.skip("no CUDA GPU here: the simulator test checks the kernels")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_ENABLE_CUDASIM"}
    worst = _worst_differences(env, "--larger")
    assert set(worst) == EXPECTED | LARGER
    for name, err in worst.items():
        assert err <= 1e-10, (name, err)


def _case(tmp_path, extra=""):
    path = tmp_path / "case.toml"
    path.write_text("[run]\nend_time = 1e-7\n" + extra + material_toml() + """
[[body]]
name = "block"
material = "copper"
mesh = { generator = "rectangle", origin = [0.0, 0.0], size = [0.01, 0.004], divisions = [4, 2] }
""")
    return path


def _one_line_error(out, *words):
    assert out.returncode == 2, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr
    for word in words:
        assert word in lines[0], lines[0]


def test_cuda_without_numba_cuda_or_a_gpu_is_a_one_line_input_error(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_ENABLE_CUDASIM"}
    if HAVE_NUMBA_CUDA:
        from numba import cuda
        if cuda.is_available():
            pytest.skip("a CUDA GPU is present: backend cuda runs")
    out = run_cli("run", _case(tmp_path), "--backend", "cuda", "-o", tmp_path / "out", env=env)
    _one_line_error(out, 'run.backend = "cuda"',
                    "no usable CUDA GPU" if HAVE_NUMBA_CUDA else "numba-cuda")


def test_backend_is_validated(tmp_path):
    out = run_cli("run", _case(tmp_path), "--set", "run.backend=opencl", "-o", tmp_path / "o")
    _one_line_error(out, "run.backend")
    out = run_cli("run", _case(tmp_path), "--backend", "opencl", "-o", tmp_path / "o")
    assert out.returncode == 2 and "--backend" in out.stderr


@needs_numba_cuda
def test_cuda_refuses_what_it_does_not_run(tmp_path):
    # under the simulator a "GPU" is there; the FE methods are refused by name
    fe = run_cli("run", _case(tmp_path, 'method = "fem-t3"\n'), "--backend", "cuda", "-o",
                 tmp_path / "fe", env=SIM)
    _one_line_error(fe, 'run.backend = "cuda"', "fem-t3")
