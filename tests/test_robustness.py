"""Failing runs, interruption and restart, atomic outputs, fuzzed input (issue: robustness)."""

import copy
import math
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import meshio
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import material_toml, run_cli

from impactfv import InputError, SimulationError, load_case, run
from impactfv.mesh.core import Mesh, validate_and_orient
from impactfv.validation.bars import two_bars

FAILING = """
[run]
end_time = 2.0e-5
output_interval = 1.0e-6
cfl = 1.0
[[material]]
name = "soft"
density = 1000.0
youngs_modulus = 1.0e6
poisson_ratio = 0.3
[[body]]
name = "block"
material = "soft"
velocity = ["0", "3000*heaviside(x - 0.005)"]
mesh = { generator = "rectangle", origin = [0.0, 0.0], size = [0.01, 0.002], divisions = [20, 4] }
"""

BARS = """
[run]
end_time = 1.6e-5
output_interval = 2.0e-6
""" + material_toml() + """[[body]]
name = "left"
material = "copper"
velocity = [50.0, 0.0]
mesh = { generator = "rectangle", origin = [-0.0102, 0.0], size = [0.01, 0.001], divisions = [DIV] }
boundary = [{ region = "ymin", velocity = { y = 0.0 } }, { region = "ymax", velocity = { y = 0.0 } }]
[[body]]
name = "right"
material = "copper"
velocity = [-50.0, 0.0]
mesh = { generator = "rectangle", origin = [0.0002, 0.0], size = [0.01, 0.001], divisions = [DIV] }
boundary = [{ region = "ymin", velocity = { y = 0.0 } }, { region = "ymax", velocity = { y = 0.0 } }]
[[contact]]
bodies = ["left", "right"]
model = "stick"
"""


cli = run_cli


def assert_outputs_readable(folder: Path):
    rows = np.loadtxt(folder / "history.csv", delimiter=",", skiprows=1, ndmin=2)
    assert rows.shape[0] >= 1 and np.all(np.isfinite(rows[:, 0]))
    pvd = folder / "fields.pvd"
    if pvd.exists():
        for ds in ET.parse(pvd).getroot().iter("DataSet"):
            mesh = meshio.read(folder / ds.get("file"))
            assert np.all(np.isfinite(mesh.point_data["velocity"]))
    return rows


def test_failing_run_stops_with_location_and_keeps_outputs(tmp_path):
    case = tmp_path / "fail.toml"
    case.write_text(FAILING)
    proc = cli("run", case, "-o", tmp_path / "out", "--no-progress")
    assert proc.returncode == 3
    message = proc.stderr.strip().splitlines()
    assert len(message) == 1 and "Traceback" not in proc.stderr
    for word in ("step", "time", "body 'block'", "node"):
        assert word in message[0]
    rows = assert_outputs_readable(tmp_path / "out")
    assert rows.shape[0] >= 2  # the good steps before the failure are kept
    import json
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["status"] == "failed"


def test_failure_from_python_names_the_step():
    with pytest.raises(SimulationError) as info:
        run(load_case(_toml_dict(FAILING)))
    assert info.value.step >= 1 and info.value.body == "block"


def _toml_dict(text):
    import tomllib
    return tomllib.loads(text)


def test_restart_from_a_checkpoint_gives_the_same_result(tmp_path):
    case = _toml_dict(BARS.replace("DIV", "40, 4"))
    full = run(load_case(case), tmp_path / "full", checkpoint_every=4e-6)
    checkpoints = sorted((tmp_path / "full" / "checkpoints").glob("*.npz"))
    assert len(checkpoints) >= 3
    # a second run that "stopped" after its first checkpoint
    part = tmp_path / "part"
    (part / "checkpoints").mkdir(parents=True)
    import shutil
    shutil.copy(checkpoints[0], part / "checkpoints" / checkpoints[0].name)
    resumed = run(load_case(case), part, restart=True)
    for key, value in full.history.items():
        assert np.allclose(resumed.history[key], value, rtol=1e-12, atol=1e-300,
                           equal_nan=True), key
    for name in ("left", "right"):
        assert np.abs(resumed.bodies[name]["points"] - full.bodies[name]["points"]).max() \
            <= 1e-12 * 0.01


def test_restart_refuses_a_checkpoint_of_another_case(tmp_path):
    case = _toml_dict(BARS.replace("DIV", "20, 2"))
    run(load_case(case), tmp_path, checkpoint_every=4e-6)
    case["material"][0]["density"] = 9000.0
    with pytest.raises(InputError, match="different case"):
        run(load_case(case), tmp_path, restart=True)


@pytest.mark.parametrize("sig,code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_signal_writes_checkpoint_and_restart_finishes(tmp_path, sig, code):
    text = BARS.replace("DIV", "150, 15").replace("end_time = 1.6e-5", "end_time = 4.0e-5")
    case = tmp_path / "bars.toml"
    case.write_text(text)
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "impactfv.cli", "run", str(case), "-o",
                             str(out), "--no-progress"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while time.time() < deadline and not (out / "history.csv").exists():
        time.sleep(0.05)
    time.sleep(0.3)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    if proc.returncode == 0:
        pytest.skip("the run finished before the signal arrived")
    assert proc.returncode == code, err
    assert "checkpoint" in err and len(err.strip().splitlines()) == 1
    assert_outputs_readable(out)
    assert list((out / "checkpoints").glob("*.npz"))
    again = cli("run", case, "--restart", out, "--no-progress")
    assert again.returncode == 0, again.stderr
    rows = assert_outputs_readable(out)
    assert rows[-1, 0] == pytest.approx(4.0e-5, rel=1e-12)
    assert np.all(np.diff(rows[:, 0]) > 0)  # no step lost or repeated


def test_sigkill_leaves_every_file_readable(tmp_path):
    text = BARS.replace("DIV", "150, 15").replace("output_interval = 2.0e-6",
                                                   "output_interval = 2.0e-7")
    case = tmp_path / "bars.toml"
    case.write_text(text)
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "impactfv.cli", "run", str(case), "-o",
                             str(out), "--no-progress", "--checkpoint-every", "1e-6"])
    deadline = time.time() + 120
    while time.time() < deadline and len(list(out.glob("fields_*.vtu"))) < 4:
        time.sleep(0.02)
    proc.kill()
    proc.wait()
    assert_outputs_readable(out)
    for ckpt in (out / "checkpoints").glob("*.npz"):
        with np.load(ckpt, allow_pickle=False) as data:
            assert np.all(np.isfinite(data["state_v"]))


def test_mesh_checks_name_the_problem():
    pts = np.array([[0, 0], [1, 0], [0, 1], [1, 1], [5, 5]], float)
    with pytest.raises(InputError, match="belong to no triangle"):
        validate_and_orient(Mesh(pts, np.array([[0, 1, 2], [1, 3, 2]])), "m.msh")
    dup = np.array([[0, 0], [1, 0], [0, 1], [1, 0]], float)
    with pytest.raises(InputError, match="duplicated node"):
        validate_and_orient(Mesh(dup, np.array([[0, 1, 2], [3, 2, 0]])), "m.msh")
    fan = np.array([[0, 0], [1, 0], [0, 1], [0, -1], [1, 1]], float)
    with pytest.raises(InputError, match="more than two"):
        validate_and_orient(Mesh(fan, np.array([[0, 1, 2], [0, 1, 3], [0, 1, 4]])), "m.msh")
    square = np.array([[0, 0], [1, 0], [0, 1], [1, 1]], float)
    with pytest.raises(InputError, match="empty"):
        validate_and_orient(Mesh(square, np.array([[0, 1, 2], [1, 3, 2]]),
                                    {"left": np.zeros((0, 2), int)}), "m.msh")
    # clockwise triangles are accepted and turned counter-clockwise
    ok = validate_and_orient(Mesh(square, np.array([[0, 2, 1], [1, 2, 3]])), "m.msh")
    assert np.all(ok.triangle_areas() > 0)


# ------------------------------------------------------------------ fuzzed input

BASE = two_bars(divisions=(6, 2), end_time=2e-7)
VALUES = st.sampled_from([None, 0, -1, 1, 2, 0.5, 1e300, -1e-300, math.nan, math.inf, "x",
                          "sin(x)", "", [], [1.0], [1.0, 2.0], [1.0, 2.0, 3.0], {},
                          {"x": 1.0}, True, "copper", "left", "slip", "rectangle"])


def _paths(obj, prefix=()):
    yield prefix
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from _paths(v, prefix + (i,))


PATHS = [p for p in _paths(BASE) if p]


@settings(max_examples=120, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(st.lists(st.tuples(st.sampled_from(PATHS), VALUES, st.booleans()), min_size=1,
                max_size=3))
def test_fuzzed_cases_give_a_run_or_an_input_error(mutations):
    case = copy.deepcopy(BASE)
    for path, value, delete in mutations:
        parent = case
        try:
            for key in path[:-1]:
                parent = parent[key]
            if delete and isinstance(parent, dict):
                parent.pop(path[-1], None)
            else:
                parent[path[-1]] = value
        except (KeyError, IndexError, TypeError):
            continue
    try:
        result = run(load_case(case))
    except (InputError, SimulationError):
        return
    assert result.summary["status"] in ("completed", "stopped at max_steps")


@settings(max_examples=60, deadline=None)
@given(st.one_of(st.text(max_size=40), st.sampled_from(["x\x00", "(" * 300 + "x" + ")" * 300,
                                                         "1" * 400, "x**9e9", "1/0", "sin()"])))
def test_fuzzed_expressions_never_escape(text):
    case = copy.deepcopy(BASE)
    case["body"][0]["velocity"] = [text, "0"]
    case["run"]["end_time"] = 1e-9
    try:
        run(load_case(case))
    except (InputError, SimulationError):
        pass


COORD = st.one_of(st.floats(-1e-3, 1e-3), st.sampled_from([math.nan, math.inf, 0.0, 1e-3]))


@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(st.lists(st.tuples(COORD, COORD), min_size=0, max_size=9),
       st.lists(st.tuples(st.integers(-1, 9), st.integers(-1, 9), st.integers(-1, 9)),
                min_size=0, max_size=8))
def test_fuzzed_mesh_files_give_a_run_or_an_input_error(tmp_path_factory, points, triangles):
    folder = tmp_path_factory.mktemp("mesh")
    pts = np.array(points, float).reshape(-1, 2)
    tri = np.array(triangles, int).reshape(-1, 3)
    try:
        meshio.write(folder / "m.msh", meshio.Mesh(np.column_stack([pts, np.zeros(len(pts))]),
                                                   [("triangle", tri)]),
                     file_format="gmsh22", binary=False)
    except Exception:
        (folder / "m.msh").write_text("$MeshFormat\nnot a mesh\n")
    case = {"run": {"end_time": 1e-8},
            "material": [{"name": "m", "density": 1000.0, "youngs_modulus": 1e6,
                          "poisson_ratio": 0.3}],
            "body": [{"name": "b", "material": "m", "velocity": [1.0, 0.0],
                      "mesh": {"file": "m.msh"}}]}
    try:
        result = run(load_case(case, base_dir=folder))
    except (InputError, SimulationError):
        return
    assert result.summary["status"] == "completed"


def test_checkpoint_and_output_intervals_too_small_are_refused(tmp_path):
    case = _toml_dict(BARS.replace("DIV", "8, 2"))
    with pytest.raises(InputError, match="checkpoint-every"):
        run(load_case(case), tmp_path, checkpoint_every=1e-300)
    case["run"]["output_interval"] = 1e-300
    with pytest.raises(InputError, match="output_interval"):
        load_case(case)


@pytest.mark.parametrize("method", ["fem-t3", "fem-q4md"])
def test_finite_element_runs_restart_like_fv_runs(tmp_path, method):
    """One pipeline for every method: FE runs checkpoint and restart too, to the same result."""
    case = two_bars(divisions=(16, 2), end_time=1.2e-5)
    case["run"]["method"] = method
    full = run(load_case(case), tmp_path / "full", checkpoint_every=3e-6)
    checkpoints = sorted((tmp_path / "full" / "checkpoints").glob("*.npz"))
    assert len(checkpoints) >= 3
    part = tmp_path / "part"
    (part / "checkpoints").mkdir(parents=True)
    import shutil
    shutil.copy(checkpoints[1], part / "checkpoints" / checkpoints[1].name)
    resumed = run(load_case(case), part, restart=True)
    for key, value in full.history.items():
        assert np.allclose(resumed.history[key], value, rtol=1e-12, atol=1e-300,
                           equal_nan=True), key
