"""The CUDA backend (backends/cuda.py) against the CPU backend, under numba-cuda's simulator.

The simulator (NUMBA_ENABLE_CUDASIM=1, set before numba.cuda is imported, hence the
subprocesses) runs the same kernels thread by thread in Python, so the cases are tiny. The
comparisons skip when numba-cuda is not installed; the refusals are checked either way.

The two backends round differently (the CPU kernels contract a * b + c into fused
multiply-adds, the simulator does not; a GPU contracts on its own), so the 1e-10 relative
agreement is asked of quantities the state determines to better than that: the cases strain
by 1e-3 to 1e-2 (at a strain e the stress is known from F ~ I only to round-off / e and the
strain energy to round-off / e^2, relative), and the columns that are round-off about zero
(the external work of a free body, the energy balance) are compared relative to the energy
the bodies hold; every other column on its own scale.
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

COMPARE = r"""
import copy, json, sys
import numpy as np
import impactfv
sys.path.insert(0, sys.argv[1])
from conftest import block_case

def box(order, limiter, flux):
    return {"run": {"end_time": 2.5e-7, "order": order, "limiter": limiter,
                    "geometric_flux": flux},
            "material": [{"name": "soft", "model": "neo_hookean", "density": 1000.0,
                          "youngs_modulus": 1e6, "poisson_ratio": 0.45}],
            "body": [{"name": "block", "material": "soft",
                      "velocity": ["300*sin(90*x)", "200*cos(80*y)", "100*z"],
                      "mesh": {"generator": "box", "origin": [0.0, 0.0, 0.0],
                               "size": [0.01, 0.01, 0.01], "divisions": [2, 2, 2]},
                      "boundary": [{"region": "zmin", "velocity": {"z": 0.0}}]}]}

SOFT = [{"name": "soft", "model": "neo_hookean", "density": 1000.0, "youngs_modulus": 1e6,
         "poisson_ratio": 0.45}]

def bar(name, origin, velocity, divisions=(4, 2)):
    return {"name": name, "material": "soft", "velocity": velocity,
            "mesh": {"generator": "rectangle", "origin": origin, "size": [0.004, 0.002],
                     "divisions": list(divisions)}}

def cube(name, origin, velocity):
    return {"name": name, "material": "soft", "velocity": velocity,
            "mesh": {"generator": "box", "origin": origin, "size": [0.004, 0.004, 0.004],
                     "divisions": [2, 2, 2]}}

cases = {
    # two bars meeting off-centre with non-matching meshes and sliding (Coulomb friction)
    "2d_two_bars_coulomb": {
        "run": {"end_time": 6e-5, "output_interval": 6e-5}, "material": SOFT,
        "body": [bar("left", [-0.0041, 0.0], [10.0, 2.0]),
                 bar("right", [0.0001, 0.0005], [-8.0, -1.0], (3, 2))],
        "contact": [{"bodies": ["left", "right"], "model": "coulomb", "friction": 0.2}]},
    # a block sticking to a moving wall under gravity (the body force on the device too)
    "2d_wall_stick_gravity": {
        "run": {"end_time": 6e-5, "output_interval": 6e-5}, "material": SOFT,
        "body": [dict(bar("block", [0.00005, 0.0], [-10.0, "3*y"]),
                      body_force=[0.0, -9.81e4])],
        "contact": [{"bodies": ["block"], "model": "stick",
                     "wall": {"point": [0.0, 0.0], "normal": [1.0, 0.0],
                              "velocity": [1.0, 0.0]}}]},
    # an oblique cube sliding on a wall in 3D
    "3d_wall_slip": {
        "run": {"end_time": 4e-5, "output_interval": 4e-5}, "material": SOFT,
        "body": [cube("block", [0.00005, 0.0, 0.0], [-10.0, 4.0, "100*x"])],
        "contact": [{"bodies": ["block"], "model": "slip",
                     "wall": {"point": [0.0, 0.0, 0.0], "normal": [1.0, 0.0, 0.0]}}]},
    "2d_order2_bj_clamp_traction": block_case(
        divisions=(5, 3), velocity=("10*sin(300*x)", "5*cos(300*y)"), end_time=2e-7,
        boundary=[{"region": "xmin", "velocity": {"x": 0.0, "y": "2e6*t"}},
                  {"region": "ymax", "traction": ["1e6*t/1e-7", -2e6]}]),
    "2d_order2_bj_umuscl": block_case(
        divisions=(5, 3), velocity=("10*sin(300*x)", "5*cos(300*y)"), end_time=2e-7,
        boundary=[{"region": "xmin", "velocity": {"x": 0.0, "y": "2e6*t"}}]),
    "2d_order1_central": block_case(divisions=(5, 3), velocity=("5e4*y", "-2e4*x"),
                                    end_time=2e-7, order=1, limiter="none",
                                    geometric_flux="central"),
    "3d_order2_venkatakrishnan": box(2, "venkatakrishnan", "upwind"),
}
cases["2d_order2_bj_umuscl"]["run"]["muscl_chi"] = 0.6
for name in ("2d_order2_bj_umuscl", "3d_order2_venkatakrishnan"):
    cases[name]["run"]["compatibility_time"] = 30.0
ABOUT_ZERO = {"external_work", "energy_balance", "integration_energy"}  # on the energy scale
worst = {}
for name, case in cases.items():
    results = {}
    for backend in ("cpu", "cuda"):
        c = copy.deepcopy(case)
        c["run"]["backend"] = backend
        results[backend] = impactfv.run(impactfv.load_case(c))
    cpu, gpu = results["cpu"], results["cuda"]
    assert cpu.summary["steps"] == gpu.summary["steps"] >= 3
    err = 0.0
    for body in cpu.bodies:
        for key in ("velocity", "points", "pressure", "F", "stress"):
            a, b = np.asarray(cpu.bodies[body][key]), np.asarray(gpu.bodies[body][key])
            err = max(err, float(np.abs(a - b).max() / np.abs(a).max()))
    energy_scale = np.abs(cpu.history["total_energy"]).max()
    momentum_scale = max(np.abs(cpu.history[k]).max() for k in cpu.history
                         if k.startswith("momentum"))
    force_scale = max([np.abs(cpu.history[k]).max() for k in cpu.history
                       if k.startswith("contact") and not k.endswith("gap")] + [0.0])
    for key, values in cpu.history.items():
        a, b = np.asarray(values), np.asarray(gpu.history[key])
        if key in ABOUT_ZERO:
            scale = energy_scale
        elif key.startswith("momentum"):
            # a component that is round-off about zero, on the scale of the others
            scale = momentum_scale
        elif key.startswith("contact") and not key.endswith("gap"):
            # the contact force on the scale of its largest component
            scale = force_scale
        else:
            scale = np.abs(a).max()
        if scale > 0:
            err = max(err, float(np.abs(a - b).max() / scale))
    if "contact" in case:
        # the cases touch: the comparison is of contact, not of free flight
        assert force_scale > 0, name
    worst[name] = err
print(json.dumps(worst))
"""


@needs_numba_cuda
def test_cuda_kernels_give_the_cpu_results():
    proc = subprocess.run([sys.executable, "-c", COMPARE, os.path.dirname(__file__)],
                          capture_output=True, text=True, env=SIM, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    worst = json.loads(proc.stdout.strip().splitlines()[-1])
    assert set(worst) == {"2d_two_bars_coulomb", "2d_wall_stick_gravity", "3d_wall_slip",
                          "2d_order2_bj_clamp_traction", "2d_order2_bj_umuscl",
                          "2d_order1_central",
                          "3d_order2_venkatakrishnan"}
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
