"""What a hostile or careless user tries, through the CLI as they would run it: every bad
input gives exit 2 and one line naming the key or file, never a traceback, and nothing on
disk is lost (docs/failures.md)."""

import json
import os
import stat

import pytest
from conftest import material_toml, run_cli

BAR = """title = "bar"
[run]
end_time = {end_time}
{run_extra}
""" + material_toml() + """[[body]]
name = "bar"
material = "copper"
velocity = [{vx}, 0.0]
mesh = {{ generator = "rectangle", origin = [0.0, 0.0], size = [0.004, 0.001], divisions = [8, 2] }}
"""


def write_case(tmp_path, name="case.toml", end_time="2e-7", run_extra="", vx="1.0", extra=""):
    path = tmp_path / name
    path.write_text(BAR.format(end_time=end_time, run_extra=run_extra, vx=vx) + extra)
    return path


def assert_input_error(proc, *words):
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("impactfv: error: "), proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    for word in words:
        assert word in lines[0], (word, lines[0])
    return lines[0]


# -------------------------------------------------------------- class 1: expressions

@pytest.mark.parametrize("expression,words", [
    ("0*maximum(x, 1000*x, x)", ["maximum() takes 2 arguments, got 3"]),
    ("sin(x, x)", ["sin() takes 1 argument, got 2"]),
    ("minimum(x)", ["minimum() takes 2 arguments, got 1"]),
    ("-" * 900 + "x", ["nested", "at most 50"]),
    ("sin(" * 60 + "x" + ")" * 60, ["nested", "at most 50"]),
    ("-" * 2000 + "x", ["characters", "at most 1000"]),
    ("+".join(["x"] * 600), ["characters", "at most 1000"]),
], ids=["out-argument", "extra-argument", "missing-argument", "minus-chain", "deep-calls",
        "long-minus-chain", "long-sum"])
def test_expressions_cannot_reach_numpy_arguments_or_exhaust_the_stack(tmp_path, expression,
                                                                        words):
    path = write_case(tmp_path, vx=f'"{expression}"')
    for command in ("check", "run"):
        proc = run_cli(command, path, "-o", tmp_path / "out") if command == "run" else \
            run_cli(command, path)
        assert_input_error(proc, "body[0].velocity.x", *words)
    assert not (tmp_path / "out" / "history.csv").exists()


def test_two_argument_functions_still_work(tmp_path):
    path = write_case(tmp_path, vx='"maximum(x, 0.001) + arctan2(y, 1.0)"')
    proc = run_cli("run", path, "-o", tmp_path / "out", "--no-progress")
    assert proc.returncode == 0, proc.stderr


@pytest.mark.parametrize("expression", ["100*((-8)**(1/3) + 0*x)", "(-1)**0.5 * 10 + x",
                                        "(-2.0)**x"])
def test_an_expression_with_complex_values_is_refused_not_cut_to_its_real_part(tmp_path,
                                                                               expression):
    """Python floats give (-8) ** (1/3) = 1 + 1.73j; its real part must not silently
    become the velocity."""
    path = write_case(tmp_path, vx=f'"{expression}"')
    for args in (("check", path), ("run", path, "-o", tmp_path / "out")):
        assert_input_error(run_cli(*args), "body[0].velocity", "non-finite")
    assert not (tmp_path / "out" / "history.csv").exists()


# -------------------------------------------------------------- class 7: small holes

@pytest.mark.parametrize("run_extra,key", [("order = true", "run.order"),
                                           ("cfl = false", "run.cfl"),
                                           ("max_steps = true", "run.max_steps")])
def test_booleans_are_not_numbers(tmp_path, run_extra, key):
    proc = run_cli("check", write_case(tmp_path, run_extra=run_extra))
    assert_input_error(proc, key, "boolean")


def test_boolean_inside_a_list_is_refused(tmp_path):
    path = tmp_path / "case.toml"
    path.write_text(write_case(tmp_path).read_text().replace("divisions = [8, 2]",
                                                             "divisions = [8, true]"))
    assert_input_error(run_cli("check", path), "body[0].mesh.divisions[1]", "boolean")


def test_title_with_terminal_escape_codes_is_refused(tmp_path):
    path = tmp_path / "case.toml"
    path.write_text(write_case(tmp_path).read_text().replace(
        'title = "bar"', 'title = "bar\\u001b[2J\\u001b[31mred"'))
    line = assert_input_error(run_cli("check", path), "title", "control characters")
    assert "\x1b" not in line


def test_file_name_with_a_newline_stays_on_one_line(tmp_path):
    proc = run_cli("check", tmp_path / "bad\nname\x1b[31m.toml")
    line = assert_input_error(proc, "case file not found", "bad\\nname\\x1b[31m.toml")
    assert "\x1b" not in line


def test_tiny_wall_normal_still_stops_the_body(tmp_path):
    """A wall normal of length 1e-170 is a valid direction: the wall must stop the bar."""
    wall = """[[contact]]
bodies = ["bar"]
wall = { point = [0.0041, 0.0], normal = [-1e-170, 0.0] }
"""
    path = write_case(tmp_path, end_time="8e-6", vx="50.0", extra=wall)
    proc = run_cli("run", path, "-o", tmp_path / "out", "--no-progress")
    assert proc.returncode == 0, proc.stderr
    lines = (tmp_path / "out" / "history.csv").read_text().splitlines()
    header = lines[0].split(",")
    column = {k: [float(row.split(",")[i]) for row in lines[1:]] for i, k in enumerate(header)}
    px, gap = column["momentum_x"], column["contact0_gap"]
    assert px[-1] < 0.5 * px[0]                 # the wall pushed back
    assert min(gap) > -0.01 * 0.0005            # and nothing passed through it


# -------------------------------------------------------------- class 9: file permissions

@pytest.mark.parametrize("umask", [0o022, 0o077])
def test_output_files_follow_the_umask(tmp_path, umask):
    path = write_case(tmp_path)
    out = tmp_path / "out"
    proc = run_cli("run", path, "-o", out, "--no-progress", "--checkpoint-every", "1e-7",
                   preexec_fn=lambda: os.umask(umask))
    assert proc.returncode == 0, proc.stderr
    files = [p for p in out.rglob("*") if p.is_file()]
    names = {p.name for p in files}
    assert {"history.csv", "summary.json", "fields.pvd", "fields_0000.vtu"} <= names
    assert any(p.suffix == ".npz" for p in files)
    for p in files:
        assert stat.S_IMODE(p.stat().st_mode) == 0o666 & ~umask, p


# -------------------------------------------------------------- class 5 and 10: check and run agree

@pytest.mark.parametrize("end_time,run_extra", [("2e-7", "cfl = 1e-300"),
                                                ("1e300", ""),
                                                ("5e-324", "")])
def test_runs_that_cannot_finish_are_refused_before_they_start(tmp_path, end_time, run_extra):
    path = write_case(tmp_path, end_time=end_time, run_extra=run_extra)
    if end_time == "5e-324":
        assert_input_error(run_cli("check", path), "run.end_time", "greater than or equal")
        assert_input_error(run_cli("run", path, "-o", tmp_path / "out"), "run.end_time")
        return
    check = run_cli("check", path)
    assert "PROBLEM" in check.stdout
    assert_input_error(check, "steps", "max_steps")
    proc = run_cli("run", path, "-o", tmp_path / "out", "--no-progress")
    assert_input_error(proc, "steps", "max_steps")
    assert not (tmp_path / "out" / "history.csv").exists()


def test_an_explicit_max_steps_lets_a_long_run_stop_early(tmp_path):
    path = write_case(tmp_path, end_time="1e300", run_extra="max_steps = 5")
    proc = run_cli("run", path, "-o", tmp_path / "out", "--no-progress")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert (summary["status"], summary["steps"]) == ("stopped at max_steps", 5)


# -------------------------------------------------------------- class 6: exit 2, not 1

@pytest.mark.parametrize("old,new", [("youngs_modulus = 585000000.0", "youngs_modulus = 1.7e308"),
                                     ("density = 8930.0", "density = 1e-320")])
def test_extreme_but_finite_material_numbers(tmp_path, old, new):
    path = tmp_path / "case.toml"
    text = write_case(tmp_path).read_text()
    assert old in text
    path.write_text(text.replace(old, new))
    for args in (("check", path), ("run", path, "-o", tmp_path / "out")):
        assert_input_error(run_cli(*args), "material[0]", "wave speed")


def test_unreadable_case_file_is_an_input_error(tmp_path, monkeypatch):
    from pathlib import Path

    from impactfv import InputError, load_case

    path = write_case(tmp_path)

    def refuse(self, *args, **kwargs):
        raise PermissionError(13, "Permission denied")
    monkeypatch.setattr(Path, "read_text", refuse)
    with pytest.raises(InputError, match="cannot read the case file .Permission denied"):
        load_case(path)


def test_output_piped_into_a_reader_that_stops(tmp_path):
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-m", "impactfv.cli", "check",
                             str(write_case(tmp_path))],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()                       # like `impactfv check case.toml | head -0`
    err = proc.stderr.read().decode()
    assert proc.wait() == 141 and "Traceback" not in err and err == ""


# -------------------------------------------------------------- class 4: meshes that are not bodies

def mesh_case(tmp_path, mesh_name):
    path = tmp_path / "case.toml"
    path.write_text(write_case(tmp_path).read_text().replace(
        'mesh = { generator = "rectangle", origin = [0.0, 0.0], size = [0.004, 0.001], '
        'divisions = [8, 2] }', f'mesh = {{ file = "{mesh_name}" }}'))
    return path


@pytest.mark.parametrize("flip", [False, True])
def test_folded_mesh_is_refused(tmp_path, flip):
    import meshio
    import numpy as np

    # a unit square of two triangles, plus a third triangle on edge (0, 1) folded back over
    # the first (its apex inside it): the edge has both its triangles on one side
    points = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.6, 0.3]], float) * 1e-3
    cells = np.array([[0, 1, 2], [0, 2, 3], [1, 0, 4] if flip else [0, 1, 4]])
    meshio.write(tmp_path / "folded.vtu", meshio.Mesh(points, [("triangle", cells)]))
    path = mesh_case(tmp_path, "folded.vtu")
    for args in (("check", path), ("run", path, "-o", tmp_path / "out")):
        assert_input_error(run_cli(*args), "folded.vtu", "folds over itself", "edge (0, 1)")


@pytest.mark.parametrize("content", [b"garbage", b"<?xml version='1.0'?><VTKFile>",
                                     b"\x00\x01\x02" * 100])
def test_malformed_vtu_mesh_is_an_input_error(tmp_path, content):
    (tmp_path / "bad.vtu").write_bytes(content)
    path = mesh_case(tmp_path, "bad.vtu")
    assert_input_error(run_cli("check", path), "bad.vtu", "cannot read mesh")


# -------------------------------------------------------------- class 2: one run per folder

def test_a_second_run_into_a_busy_folder_is_refused(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / ".impactfv.lock").write_text(f"{os.getpid()}\n")    # a live process holds it
    (out / "history.csv").write_text("precious\n")
    proc = run_cli("run", write_case(tmp_path), "-o", out, "--no-progress")
    assert_input_error(proc, str(out), "another impactfv run")
    assert (out / "history.csv").read_text() == "precious\n"   # nothing touched
    assert (out / ".impactfv.lock").exists()


def test_a_lock_left_by_a_dead_process_is_taken_over(tmp_path):
    import subprocess
    import sys

    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    out = tmp_path / "out"
    out.mkdir()
    (out / ".impactfv.lock").write_text(f"{dead.pid}\n")
    proc = run_cli("run", write_case(tmp_path), "-o", out, "--no-progress")
    assert proc.returncode == 0, proc.stderr
    assert not (out / ".impactfv.lock").exists()               # released at the end


def test_a_new_run_leaves_no_files_of_the_old_one(tmp_path):
    out = tmp_path / "out"
    first = write_case(tmp_path, name="first.toml", end_time="4e-7",
                       run_extra="output_interval = 2e-8")
    assert run_cli("run", first, "-o", out, "--no-progress", "--checkpoint-every",
                   "1e-7").returncode == 0
    assert len(list(out.glob("fields_*.vtu"))) == 21
    (out / ".history.csv.abc.tmp").write_text("half written by a killed run")
    second = write_case(tmp_path, name="second.toml", end_time="2e-7")
    # over checkpoints --restart could continue: only with --overwrite (tests/
    # test_output_folder.py)
    assert run_cli("run", second, "-o", out, "--no-progress").returncode == 2
    assert run_cli("run", second, "-o", out, "--no-progress", "--overwrite").returncode == 0
    frames = sorted(p.name for p in out.glob("fields_*.vtu"))
    pvd = (out / "fields.pvd").read_text()
    assert frames == [f"fields_{k:04d}.vtu" for k in range(11)]
    assert all(name in pvd for name in frames)
    assert not list(out.glob("checkpoints/*.npz"))              # the old run's are gone
    assert not list(out.glob(".*.tmp"))
    summary = json.loads((out / "summary.json").read_text())
    assert summary["end_time"] == pytest.approx(2e-7)


# -------------------------------------------------------------- class 8: signals at any moment

def _start_cli(*args, env=None):
    import subprocess
    import sys

    return subprocess.Popen([sys.executable, "-m", "impactfv.cli", *map(str, args)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)


def _assert_prompt_signal_exit(proc, sig, code, out=None):
    import signal
    import subprocess
    import time

    sent = time.monotonic()
    proc.send_signal(sig)
    try:
        stdout, stderr = proc.communicate(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        pytest.fail(f"{signal.Signals(sig).name}: no exit within 10 s")
    waited = time.monotonic() - sent
    assert proc.returncode == code, (proc.returncode, stderr)
    assert waited < 5.0, waited
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and f"interrupted by {signal.Signals(sig).name}" in lines[0], stderr
    assert "Traceback" not in stdout + stderr
    if out is not None:
        assert not (out / ".impactfv.lock").exists()        # the folder is free again


@pytest.mark.parametrize("command", ["run", "check"])
@pytest.mark.parametrize("sig,code", [("SIGINT", 130), ("SIGTERM", 143)])
def test_a_signal_during_the_imports_gives_the_exit_code(tmp_path, command, sig, code):
    import signal
    import time

    path = write_case(tmp_path)
    args = ("run", path, "-o", tmp_path / "out", "--no-progress") if command == "run" else \
        ("check", path)
    proc = _start_cli(*args)
    time.sleep(0.2)
    assert proc.poll() is None                               # still importing
    _assert_prompt_signal_exit(proc, getattr(signal, sig), code)


@pytest.mark.parametrize("sig,code", [("SIGINT", 130), ("SIGTERM", 143)])
def test_a_signal_during_numba_compilation_gives_the_exit_code_promptly(tmp_path, sig, code):
    """A cold compile cache: the kernels take tens of seconds to compile; a signal in that
    time must still end the run within seconds."""
    import signal
    import time

    cache = tmp_path / "numba-cache"
    cache.mkdir()
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    out = tmp_path / "out"
    proc = _start_cli("run", write_case(tmp_path), "-o", out, "--no-progress", env=env)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not any(p.is_file() for p in cache.rglob("*")):
        time.sleep(0.05)          # the first compiled kernel written: compilation under way
    assert proc.poll() is None
    assert any(p.is_file() for p in cache.rglob("*"))
    _assert_prompt_signal_exit(proc, getattr(signal, sig), code, out)
    assert not (out / "history.csv").exists()                 # no time step was taken


def test_sigterm_two_seconds_after_a_cold_start(tmp_path):
    import signal
    import time

    cache = tmp_path / "numba-cache"
    cache.mkdir()
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    proc = _start_cli("run", write_case(tmp_path), "-o", tmp_path / "out", "--no-progress",
                      env=env)
    time.sleep(2.0)
    assert proc.poll() is None
    _assert_prompt_signal_exit(proc, signal.SIGTERM, 143, tmp_path / "out")


# -------------------------------------------------------------- class 3: restart trusts nothing

def _history(folder):
    import numpy as np

    return np.loadtxt(folder / "history.csv", delimiter=",", skiprows=1, ndmin=2)


def _strict_json(path):
    def refuse(name):
        raise ValueError(f"{path}: not strict JSON ({name})")
    return json.loads(path.read_text(), parse_constant=refuse)


def _frames_consistent(out):
    """fields.pvd lists exactly the frames on disk, each readable, times increasing."""
    import xml.etree.ElementTree as ET

    import meshio
    import numpy as np

    listed = [(float(d.get("timestep")), d.get("file"))
              for d in ET.parse(out / "fields.pvd").getroot().iter("DataSet")]
    assert sorted(p.name for p in out.glob("fields_*.vtu")) == [f for _, f in listed]
    assert np.all(np.diff([t for t, _ in listed]) > 0)
    for _, name in listed:
        assert np.all(np.isfinite(meshio.read(out / name).point_data["velocity"]))
    return listed


RESTART_RUN = 'output_interval = 5e-8'


def _checkpointed_run(tmp_path, end_time="4e-7", every="1e-7", name="case.toml"):
    # every checkpoint kept, so that the tests can pick the one to continue from
    path = write_case(tmp_path, name=name, end_time=end_time, run_extra=RESTART_RUN,
                      vx='"50*sin(3000*x)"', extra="\n[output]\nkeep_checkpoints = 100\n")
    out = tmp_path / "out"
    proc = run_cli("run", path, "-o", out, "--no-progress", "--checkpoint-every", every)
    assert proc.returncode == 0, proc.stderr
    return path, out


def _snapshot_of(out):
    return {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}


def test_restart_refuses_a_changed_mesh_file_with_the_same_node_count(tmp_path):
    import meshio
    import numpy as np

    from impactfv.mesh.generators import rectangle

    mesh = rectangle((0.0, 0.0), (0.004, 0.001), (8, 2))
    meshio.write(tmp_path / "bar.vtu", meshio.Mesh(mesh.points, [("triangle", mesh.cells)]))
    path = mesh_case(tmp_path, "bar.vtu")
    out = tmp_path / "out"
    assert run_cli("run", path, "-o", out, "--no-progress", "--checkpoint-every",
                   "1e-7").returncode == 0
    before = _snapshot_of(out)
    moved = mesh.points.copy()
    interior = np.flatnonzero((moved[:, 0] > 0) & (moved[:, 0] < 0.004) & (moved[:, 1] > 0)
                              & (moved[:, 1] < 0.001))[0]
    moved[interior] += 2e-5                    # same nodes, same triangles, one node moved
    meshio.write(tmp_path / "bar.vtu", meshio.Mesh(moved, [("triangle", mesh.cells)]))
    proc = run_cli("run", path, "--restart", out, "--no-progress")
    assert_input_error(proc, "checkpoint", "different case", "body[0].mesh")
    assert _snapshot_of(out) == before         # nothing on disk touched


@pytest.mark.parametrize("change,key", [
    (("cfl = 0.4", "cfl = 0.3"), "run.cfl"),
    (("density = 8930.0", "density = 9000.0"), "material[0].density"),
    (("divisions = [8, 2]", "divisions = [4, 4]"), "body[0].mesh.divisions"),
])
def test_restart_names_the_key_that_changed(tmp_path, change, key):
    path = write_case(tmp_path, run_extra="cfl = 0.4")
    out = tmp_path / "out"
    assert run_cli("run", path, "-o", out, "--no-progress", "--checkpoint-every",
                   "1e-7").returncode == 0
    before = _snapshot_of(out)
    text = path.read_text()
    assert change[0] in text
    path.write_text(text.replace(*change))
    line = assert_input_error(run_cli("run", path, "--restart", out, "--no-progress"),
                              "different case", key, "run.end_time")
    assert line.count("changed") == 1
    assert _snapshot_of(out) == before


def test_restart_continues_a_finished_run_to_a_later_end_time(tmp_path):
    """end_time may change on a restart: the continued run gives the same numbers as one
    run straight to the later end time."""
    import numpy as np

    path, out = _checkpointed_run(tmp_path, end_time="2e-7")
    straight = write_case(tmp_path, name="straight.toml", end_time="4e-7",
                          run_extra=RESTART_RUN, vx='"50*sin(3000*x)"')
    assert run_cli("run", straight, "-o", tmp_path / "straight", "--no-progress").returncode == 0
    path.write_text(path.read_text().replace("end_time = 2e-7", "end_time = 4e-7"))
    proc = run_cli("run", path, "--restart", out, "--no-progress")
    assert proc.returncode == 0, proc.stderr
    rows, reference = _history(out), _history(tmp_path / "straight")
    assert rows.shape == reference.shape
    assert np.allclose(rows, reference, rtol=1e-12, atol=1e-300)
    listed = _frames_consistent(out)
    assert [name for _, name in listed] == [f"fields_{k:04d}.vtu" for k in range(9)]
    assert _strict_json(out / "summary.json")["end_time"] == pytest.approx(4e-7)


def test_restart_with_a_new_output_interval_leaves_no_old_frames(tmp_path):
    """Restarting from the middle of a run with another output_interval: frames after the
    checkpoint are the new run's only (none of the old run's left mixed in)."""
    import shutil

    import numpy as np

    path, out = _checkpointed_run(tmp_path, end_time="4e-7")
    assert len(list(out.glob("fields_*.vtu"))) == 9
    newest = sorted((out / "checkpoints").glob("*.npz"))
    for later in newest[1:]:                   # as if the run had stopped after 1e-7 s
        later.unlink()
    shutil.copy(out / "history.csv", tmp_path / "old_history.csv")
    path.write_text(path.read_text().replace("output_interval = 5e-8",
                                             "output_interval = 1.5e-7"))
    proc = run_cli("run", path, "--restart", out, "--no-progress")
    assert proc.returncode == 0, proc.stderr
    times = [t for t, _ in _frames_consistent(out)]
    assert np.allclose(times, [0, 5e-8, 1e-7, 1.5e-7, 3e-7, 4e-7], rtol=1e-12, atol=0)
    rows = _history(out)
    assert np.all(np.diff(rows[:, 0]) > 0) and rows[-1, 0] == pytest.approx(4e-7, rel=1e-12)


def test_restart_refuses_an_end_time_before_the_checkpoint(tmp_path):
    path, out = _checkpointed_run(tmp_path, end_time="4e-7", every="2e-7")
    before = _snapshot_of(out)
    path.write_text(path.read_text().replace("end_time = 4e-7", "end_time = 1e-7"))
    assert_input_error(run_cli("run", path, "--restart", out, "--no-progress"),
                       "run.end_time", "before the time of the checkpoint")
    assert _snapshot_of(out) == before


def _corrupt(path, how):
    data = path.read_bytes()
    if how == "truncated":
        path.write_bytes(data[:len(data) // 2])
    elif how == "empty":
        path.write_bytes(b"")
    elif how == "garbage":
        path.write_bytes(b"\x00garbage" * 100)
    elif how == "flipped":                    # the last byte of the velocities changed
        import zipfile

        with zipfile.ZipFile(path) as archive:
            info = archive.getinfo("state_v.npy")
        start = info.header_offset + 30 + int.from_bytes(
            data[info.header_offset + 26:info.header_offset + 28], "little") + int.from_bytes(
            data[info.header_offset + 28:info.header_offset + 30], "little")
        k = start + info.compress_size - 1
        path.write_bytes(data[:k] + bytes([data[k] ^ 0x01]) + data[k + 1:])


def _craft(path, **changes):
    import numpy as np

    with np.load(path, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    for key, value in changes.items():
        arrays[key] = value(arrays[key]) if callable(value) else np.asarray(value)
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)


BAD_CHECKPOINTS = {
    "truncated": lambda p: _corrupt(p, "truncated"),
    "empty": lambda p: _corrupt(p, "empty"),
    "garbage": lambda p: _corrupt(p, "garbage"),
    "flipped-byte": lambda p: _corrupt(p, "flipped"),
    "nan-time": lambda p: _craft(p, t=float("nan")),
    "infinite-time": lambda p: _craft(p, t=float("inf")),
    "negative-time": lambda p: _craft(p, t=-1.0),
    "negative-steps": lambda p: _craft(p, steps=-3),
    "nan-velocity": lambda p: _craft(p, state_v=lambda v: v * float("nan")),
    "wrong-shape": lambda p: _craft(p, state_F=lambda F: F[:-1]),
    "short-history": lambda p: _craft(p, h_time=lambda h: h[:-1]),
    "foreign-frame-name": lambda p: _craft(
        p, snapshot_files=lambda f: [("../../escape.vtu" if k == 1 else n)
                                     for k, n in enumerate(f)]),
}


@pytest.mark.parametrize("damage", sorted(BAD_CHECKPOINTS))
def test_a_bad_newest_checkpoint_falls_back_to_the_previous_one(tmp_path, damage):
    import numpy as np

    path, out = _checkpointed_run(tmp_path)
    reference = _history(out)
    checkpoints = sorted((out / "checkpoints").glob("*.npz"))
    assert len(checkpoints) >= 3
    BAD_CHECKPOINTS[damage](checkpoints[-1])
    proc = run_cli("run", path, "--restart", out, "--no-progress")
    assert proc.returncode == 0, proc.stderr
    warning = proc.stderr.strip().splitlines()
    assert len(warning) == 1 and "warning" in warning[0], proc.stderr
    assert checkpoints[-1].name in warning[0] and checkpoints[-2].name in warning[0]
    assert "Traceback" not in proc.stderr
    assert np.allclose(_history(out), reference, rtol=1e-12, atol=1e-300)
    assert _strict_json(out / "summary.json")["status"] == "completed"
    _frames_consistent(out)
    # kept, under a name the next restart does not pick
    assert (out / "checkpoints" / (checkpoints[-1].name + ".unreadable")).exists()


@pytest.mark.parametrize("damage", ["truncated", "nan-time", "garbage"])
def test_no_good_checkpoint_is_an_input_error_and_changes_nothing(tmp_path, damage):
    path, out = _checkpointed_run(tmp_path, end_time="2e-7", every="2e-7")
    checkpoints = sorted((out / "checkpoints").glob("*.npz"))
    assert len(checkpoints) == 1
    BAD_CHECKPOINTS[damage](checkpoints[0])
    before = _snapshot_of(out)
    proc = run_cli("run", path, "--restart", out, "--no-progress")
    assert_input_error(proc, checkpoints[0].name, "unreadable checkpoint")
    assert _snapshot_of(out) == before


def test_summary_json_is_strict_json_even_with_non_finite_values(tmp_path):
    from impactfv.io.writers import write_summary

    write_summary(tmp_path / "s.json", {"a": float("nan"), "b": [1.0, float("inf")],
                                        "c": {"d": -float("inf")}, "e": 2.5})
    assert _strict_json(tmp_path / "s.json") == {"a": None, "b": [1.0, None],
                                                 "c": {"d": None}, "e": 2.5}


# -------------------------------------------------------------- class 5: sizes that cannot work

# The peak resident memory of this process: VmHWM, the ru_maxrss of the process's own
# memory (ru_maxrss itself keeps, across exec, the size of the parent it was forked from:
# a fresh child of a 240 MB pytest starts at 240 MB).
MEASURE = r"""
import json, os, resource, sys, tempfile
from impactfv import load_case, run

def peak():
    try:
        with open("/proc/self/status") as fh:
            return next(int(l.split()[1]) for l in fh if l.startswith("VmHWM:")) * 1024
    except (OSError, StopIteration):
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024

tmp = tempfile.mkdtemp()
run(load_case(sys.argv[1]), os.path.join(tmp, "warm"), progress=False)   # imports, kernels
base = peak()
run(load_case(sys.argv[2]), os.path.join(tmp, "big"), progress=False)
print(json.dumps({"added": peak() - base, "base": base}))
"""


def _size_case(tmp_path, name, divisions, contact=False):
    wall = ('[[contact]]\nbodies = ["bar"]\n'
            'wall = { point = [-0.0001, 0.0], normal = [1.0, 0.0] }\n') if contact else ""
    path = write_case(tmp_path, name=name, end_time="1e-5", run_extra="max_steps = 2",
                      extra=wall)
    path.write_text(path.read_text().replace("size = [0.004, 0.001], divisions = [8, 2]",
                                             f"size = [0.01, 0.01], divisions = {divisions}"))
    return path


def _reported_memory(check_stdout):
    import re

    line = next(l for l in check_stdout.splitlines() if l.startswith("memory:"))
    value, unit, per_node = re.search(r"about ([\d.]+) (KiB|MiB|GiB) \((\d+) bytes per node",
                                      line).groups()
    return float(value) * {"KiB": 2**10, "MiB": 2**20, "GiB": 2**30}[unit], int(per_node)


@pytest.mark.parametrize("divisions,contact", [([140, 140], False), ([280, 280], False),
                                               ([447, 447], False), ([280, 280], True)],
                         ids=["20k-nodes", "80k-nodes", "200k-nodes", "80k-nodes-contact"])
def test_memory_estimate_of_check_matches_the_measured_peak(tmp_path, divisions, contact):
    """What `impactfv check` reports is within 30% of the peak resident memory a run adds
    (the peak resident size of a fresh process, over its value after imports and a tiny
    warm-up run)."""
    import subprocess
    import sys

    big = _size_case(tmp_path, "big.toml", divisions, contact)
    tiny = _size_case(tmp_path, "tiny.toml", [4, 4], contact)
    check = run_cli("check", big)
    assert check.returncode == 0, check.stderr
    estimate, per_node = _reported_memory(check.stdout)
    proc = subprocess.run([sys.executable, "-c", MEASURE, str(tiny), str(big)],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    measured = json.loads(proc.stdout.strip().splitlines()[-1])["added"]
    assert 0.7 * measured <= estimate <= 1.3 * measured, (estimate, measured)
    assert 1000 < per_node < 3000                # not the ~530 B/node of the state alone


def test_memory_estimate_of_a_3d_run_matches_the_measured_peak(tmp_path):
    """The same on tetrahedra (a box of 32^3 cells: 35,937 nodes; measured 1.02)."""
    import subprocess
    import sys

    def box_case(name, n):
        path = write_case(tmp_path, name=name, end_time="1e-5", run_extra="max_steps = 2")
        text = path.read_text().replace(
            'mesh = { generator = "rectangle", origin = [0.0, 0.0], size = [0.004, 0.001], '
            'divisions = [8, 2] }',
            f'mesh = {{ generator = "box", origin = [0.0, 0.0, 0.0], size = [0.01, 0.01, '
            f'0.01], divisions = [{n}, {n}, {n}] }}')
        path.write_text(text.replace("velocity = [1.0, 0.0]", "velocity = [1.0, 0.0, 0.0]"))
        return path

    big, tiny = box_case("big.toml", 32), box_case("tiny.toml", 3)
    check = run_cli("check", big)
    assert check.returncode == 0, check.stderr
    estimate, per_node = _reported_memory(check.stdout)
    proc = subprocess.run([sys.executable, "-c", MEASURE, str(tiny), str(big)],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    measured = json.loads(proc.stdout.strip().splitlines()[-1])["added"]
    assert 0.7 * measured <= estimate <= 1.3 * measured, (estimate, measured)


@pytest.mark.parametrize("mesh,key", [
    ('{ generator = "rectangle", origin = [0.0, 0.0], size = [1.0, 1.0], '
     'divisions = [100000, 100000] }', "body[0].mesh.divisions"),
    ('{ generator = "disc", centre = [0.0, 0.0], radius = 1.0, rings = 1000000 }',
     "body[0].mesh.rings"),
    ('{ generator = "annulus", centre = [0.0, 0.0], radius = 1.0, inner_radius = 0.5, '
     'rings = 1000000 }', "body[0].mesh.rings"),
    ('{ generator = "rectangle", origin = [0.0, 0.0], size = [1.0, 1.0], '
     'divisions = [1000000000000000000000, 3] }', "body[0].mesh.divisions"),
], ids=["1e10-nodes", "3e12-node-disc", "2e12-node-annulus", "1e21-divisions"])
def test_absurd_generated_meshes_are_refused_before_they_are_built(tmp_path, mesh, key):
    import subprocess
    import sys

    path = tmp_path / "case.toml"
    path.write_text(write_case(tmp_path).read_text().replace(
        'mesh = { generator = "rectangle", origin = [0.0, 0.0], size = [0.004, 0.001], '
        'divisions = [8, 2] }', f"mesh = {mesh}"))
    for command in (["check", path], ["run", path, "-o", tmp_path / "out"]):
        # the peak memory of the command, measured in a process of its own
        wrapper = ("import resource, subprocess, sys; p = subprocess.run(sys.argv[1:], "
                   "capture_output=True, text=True); sys.stderr.write(p.stderr); "
                   "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss); "
                   "sys.exit(p.returncode)")
        proc = subprocess.run([sys.executable, "-c", wrapper, sys.executable, "-m",
                               "impactfv.cli", *map(str, command)],
                              capture_output=True, text=True, timeout=120)
        line = assert_input_error(proc, key, "nodes", "bytes per node", "memory available")
        assert "TiB" in line
        assert int(proc.stdout.strip()) * 1024 < 2**30         # nothing big was allocated
    assert not (tmp_path / "out" / "history.csv").exists()


def test_run_refuses_a_mesh_file_case_beyond_the_memory_available(tmp_path):
    """A mesh file's size is known once it is read: run refuses before it assembles the
    scheme's arrays, check reports the figures and exits 2, earlier outputs stay."""
    import meshio

    from impactfv.mesh.generators import rectangle

    mesh = rectangle((0.0, 0.0), (0.004, 0.001), (80, 20))
    meshio.write(tmp_path / "bar.vtu", meshio.Mesh(mesh.points, [("triangle", mesh.cells)]))
    path = mesh_case(tmp_path, "bar.vtu")
    out = tmp_path / "out"
    out.mkdir()
    (out / "history.csv").write_text("precious\n")
    env = dict(os.environ, IMPACTFV_MEMORY_LIMIT="20M")
    check = run_cli("check", path, env=env)
    assert "PROBLEM: the run needs about" in check.stdout and "1,701 nodes" in check.stdout
    assert "time step: not computed" in check.stdout     # no dual built for a case too large
    assert_input_error(check, "memory available", "20 MiB")
    proc = run_cli("run", path, "-o", out, "--no-progress", env=env)
    assert_input_error(proc, str(path), "bytes per node", "more than the 20 MiB")
    assert (out / "history.csv").read_text() == "precious\n"
    # the folder holds a file impactfv did not write: only with --overwrite
    ok = run_cli("run", path, "-o", out, "--no-progress", "--overwrite",
                 env=dict(os.environ, IMPACTFV_MEMORY_LIMIT="4G"))
    assert ok.returncode == 0, ok.stderr


def test_a_memory_error_anywhere_is_one_line(tmp_path):
    import subprocess
    import sys

    path = write_case(tmp_path)
    script = ("import sys, impactfv.scheme.discretisation as d\n"
              "def boom(*a, **k):\n    raise MemoryError('Unable to allocate 74.5 GiB')\n"
              "d.median_dual = boom\n"
              "from impactfv.cli import main\nsys.exit(main(sys.argv[1:]))\n")
    proc = subprocess.run([sys.executable, "-c", script, "run", str(path), "-o",
                           str(tmp_path / "out"), "--no-progress"],
                          capture_output=True, text=True)
    assert_input_error(proc, "out of memory", "impactfv check")


def test_a_bad_memory_limit_is_an_input_error(tmp_path):
    proc = run_cli("check", write_case(tmp_path),
                   env=dict(os.environ, IMPACTFV_MEMORY_LIMIT="lots"))
    assert_input_error(proc, "IMPACTFV_MEMORY_LIMIT", "size in bytes")


def test_a_history_of_millions_of_steps_counts_in_the_memory(tmp_path):
    """One history row per step: 5 million steps of a 27-node bar need about 1 GiB."""
    path = write_case(tmp_path, end_time="1e300", run_extra="max_steps = 5000000")
    env = dict(os.environ, IMPACTFV_MEMORY_LIMIT="500M")
    check = run_cli("check", path, env=env)
    assert "PROBLEM: the run needs about" in check.stdout
    assert_input_error(check, "GiB", "more than the 500 MiB")
    out = tmp_path / "out"
    assert_input_error(run_cli("run", path, "-o", out, "--no-progress", env=env),
                       "GiB", "more than the 500 MiB")
    assert not (out / "history.csv").exists()
    path.write_text(path.read_text().replace("max_steps = 5000000", "max_steps = 5"))
    assert run_cli("run", path, "-o", out, "--no-progress", env=env).returncode == 0


@pytest.mark.parametrize("mesh,words", [
    ('{ generator = "disc", centre = [0.0, 0.0], radius = 0.001, inner_radius = 0.0005, '
     'rings = 4 }', ["inner_radius does not apply", '"disc"']),
    ('{ generator = "disc", centre = [0.0, 0.0], radius = 0.001, rings = 4, '
     'divisions = [8, 2] }', ["divisions does not apply", '"disc"']),
    ('{ generator = "rectangle", origin = [0.0, 0.0], size = [0.004, 0.001], '
     'divisions = [8, 2], radius = 0.001 }', ["radius does not apply", '"rectangle"']),
    ('{ file = "bar.msh", divisions = [8, 2] }', ["divisions does not apply", "mesh file"]),
], ids=["disc-inner-radius", "disc-divisions", "rectangle-radius", "file-divisions"])
def test_a_mesh_key_of_another_generator_is_refused(tmp_path, mesh, words):
    """A key the chosen generator does not take is a mistake, not something to ignore: a
    disc given an inner_radius would otherwise silently be a full disc, not a ring."""
    path = tmp_path / "case.toml"
    path.write_text(write_case(tmp_path).read_text().replace(
        'mesh = { generator = "rectangle", origin = [0.0, 0.0], size = [0.004, 0.001], '
        'divisions = [8, 2] }', f"mesh = {mesh}"))
    assert_input_error(run_cli("check", path), "body[0].mesh", *words)


@pytest.mark.parametrize("boundary,words,refused", [
    ('velocity = { x = 0.0 }\ntraction = [1.0e5, 0.0]', ["traction[0]", "velocity.x"], True),
    ('velocity = { y = 0.0 }\ntraction = [0.0, "1e5*t"]', ["traction[1]", "velocity.y"], True),
    ('velocity = { x = 0.0 }\ntraction = [0.0, 1.0e5]', [], False),
], ids=["number", "expression", "other-component"])
def test_a_traction_on_a_held_component_is_refused(tmp_path, boundary, words, refused):
    """A prescribed velocity wins per component (docs/case-file.md), so a traction given on a
    component the same entry holds would be dropped without a word: it is refused, naming
    both. A traction on a component the entry leaves free is a mixed condition and runs."""
    path = write_case(tmp_path, extra=f'\n[[body.boundary]]\nregion = "xmin"\n{boundary}\n')
    proc = run_cli("check", path)
    if refused:
        assert_input_error(proc, "body[0].boundary[0]", *words)
    else:
        assert proc.returncode == 0, proc.stderr


@pytest.mark.parametrize("run_extra,words", [
    ('method = "fem-t3"\nmuscl_chi = 0.6', ["muscl_chi", 'method = "fem-t3"', "ignore"]),
    ('method = "fem-q4md"\ngeometric_flux = "central"', ["geometric_flux", "fem-q4md"]),
    ('method = "fem-t3"\norder = 1', ["order", "fem-t3"]),
    ('method = "fem-q4md"\ncompatibility_time = 50.0', ["compatibility_time", "fem-q4md"]),
    ('order = 1\nmuscl_chi = 0.5', ["muscl_chi", "order = 1"]),
    ('method = "fem-t3"\nsmooth_switch = 0.6', ["smooth_switch", 'method = "fem-t3"']),
    ('order = 1\nsmooth_switch = 0.5', ["smooth_switch", "order = 1"]),
    ('muscl_chi = 0.6\nsmooth_switch = 0.6', ["muscl_chi", "smooth_switch", "alternatives"]),
], ids=["blend-fe", "flux-fe", "order-fe", "relaxation-fe", "blend-order-1", "switch-fe",
        "switch-order-1", "blend-and-switch"])
def test_an_option_the_chosen_method_would_ignore_is_refused(tmp_path, run_extra, words):
    """A finite-volume option given with an FE method (or the order-2 blend or switch at
    order 1) would be dropped without a word: it is refused, naming it; so is the U-MUSCL
    blend together with the smoothness switch. The defaults written out are fine."""
    path = write_case(tmp_path, run_extra=run_extra)
    assert_input_error(run_cli("check", path), "run", *words)
    fine = write_case(tmp_path, name="fine.toml", run_extra='method = "fem-t3"\norder = 2\n'
                      'limiter = "barth_jespersen"\nmuscl_chi = 0.0')
    assert run_cli("check", fine).returncode == 0


def test_compare_gives_the_fe_methods_the_case_without_the_fv_options(tmp_path):
    """`compare` runs an FV case with its options (here the U-MUSCL blend and the central
    flux) against the FE methods, which take the same case without them."""
    from impactfv.case import load_case
    from impactfv.compare import method_case

    path = write_case(tmp_path, run_extra='muscl_chi = 0.6\ngeometric_flux = "central"')
    case = load_case(path)
    fe = method_case(case, "fem-t3")
    assert fe.spec.run.method == "fem-t3" and fe.spec.run.muscl_chi == 0.0
    fv = method_case(case, "fv")
    assert fv.spec.run.muscl_chi == 0.6 and fv.spec.run.geometric_flux == "central"


# ------------------------------------------------ names that become history.csv columns
@pytest.mark.parametrize("name", ['bar,left', 'bar\\"', 'bar\\nx', 'bar\\tx'])
def test_names_that_would_break_the_history_csv_are_refused(tmp_path, name):
    path = write_case(tmp_path)
    path.write_text(path.read_text().replace('name = "bar"', f'name = "{name}"'))
    assert_input_error(run_cli("run", path, "-o", tmp_path / "out"), "body[0].name",
                       "history.csv")
    path = write_case(tmp_path, extra=f'boundary = [{{ region = "{name}", velocity = '
                                      '{ x = 0.0 } }]\n')
    assert_input_error(run_cli("run", path, "-o", tmp_path / "out"),
                       "body[0].boundary[0].region", "history.csv")


def test_reaction_columns_never_collide(tmp_path):
    """A region named in two boundary entries gets a column of its own that no other
    region's name gives (a region "L" twice beside a region "L_2", which the generators
    cannot name, through the naming itself): every reaction is in the history."""
    import numpy as np

    from impactfv import load_case, run
    from impactfv.scheme.energy import distinct_names

    for names in (["L", "L", "L2"], ["L", "L", "L_2"], ["L_2", "L", "L"],
                  ["L", "L", "L", "L_3"]):
        named = distinct_names(names)
        assert len(set(named)) == len(names)
        assert all(n == b or n.startswith(b + "_") for n, b in zip(named, names))

    case = load_case(write_case(tmp_path, extra=(
        'boundary = [{ region = "xmin", velocity = { x = 0.0 } },\n'
        '            { region = "xmin", velocity = { y = 0.0 } },\n'
        '            { region = "xmax", velocity = { x = 0.0 } }]\n')))
    history = run(case).history
    columns = [c for c in history if c.startswith("reaction_")]
    assert len(columns) == len(set(columns)) == 6
    assert np.any(np.abs(history["reaction_xmin_fx"]) > 0)


@pytest.mark.parametrize("depth", [400, 2000, 20000])
def test_deeply_nested_toml_is_an_input_error(tmp_path, depth):
    """Arrays nested thousands deep, in the case file or a --set value: one line, exit 2,
    not a RecursionError."""
    nested = "[" * depth + "]" * depth
    path = write_case(tmp_path, run_extra=f"cfl = {nested}")
    assert_input_error(run_cli("run", path, "-o", tmp_path / "out"), "case.toml")
    path = write_case(tmp_path)
    assert_input_error(run_cli("run", path, "-o", tmp_path / "out", "--set",
                               f"run.cfl={nested}"), "run.cfl")


def _two_blocks(tmp_path, va, vb):
    text = """[run]
end_time = 1e-6
""" + material_toml() + "".join(f"""[[body]]
name = "{name}"
material = "copper"
velocity = [{v}, 0.0]
mesh = {{ generator = "rectangle", origin = [{x0}, 0.0], size = [0.01, 0.004], divisions = [10, 4] }}
""" for name, v, x0 in (("a", va, -0.0101), ("b", vb, 0.0001))) + """[[contact]]
bodies = ["a", "b"]
model = "slip"
"""
    path = tmp_path / "blocks.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("va,vb", [(0.0, 0.0), (-5.0, 5.0)], ids=["at rest", "moving apart"])
def test_compare_without_a_closing_speed_gives_no_reference_ratios(tmp_path, va, vb):
    """Bodies at rest or moving apart have no acoustic reference pressure: the columns
    measured against it are empty (NaN), never negative or a traceback; the energy ratios
    of bodies at rest too."""
    import csv

    proc = run_cli("compare", _two_blocks(tmp_path, va, vb), "-o", tmp_path / "cmp",
                   env={**os.environ, "NUMBA_NUM_THREADS": "1"})
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    with open(tmp_path / "cmp" / "comparison.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["method"] for r in rows] == ["fv", "fem-t3", "fem-q4md"]
    for row in rows:
        for key in ("peak_over_pref", "plateau_over_pref", "roughness"):
            assert row[key] == "nan", (key, row[key])
        assert (row["energy_end_over_start"] == "nan") == (va == vb == 0.0)


def test_plot_on_damaged_files_is_one_line_or_draws(tmp_path):
    out = tmp_path / "out"
    assert run_cli("run", write_case(tmp_path), "-o", out, "--no-progress").returncode == 0
    pvd = (out / "fields.pvd").read_text()
    for damaged, word in ((pvd.replace('timestep="', 'time="', 1), "timestep"),
                          (pvd.replace('file="', 'name="', 1), "names no file")):
        (out / "fields.pvd").write_text(damaged)
        assert_input_error(run_cli("plot", out), "fields.pvd", word)
    (out / "fields.pvd").write_text(pvd)
    (out / "summary.json").write_text("[1, 2]")
    proc = run_cli("plot", out)
    assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr
