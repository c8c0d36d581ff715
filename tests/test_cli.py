"""The command line: outputs a user finds, and one-line errors with exit code 2."""

import csv
import json
import xml.etree.ElementTree as ET
from pathlib import Path

import meshio
import numpy as np
import pytest
from conftest import material_toml, run_cli

ROOT = Path(__file__).resolve().parents[1]

GOOD = """
title = "cli test"
[run]
end_time = 2.0e-6
output_interval = 1.0e-6

""" + material_toml() + """
[[body]]
name = "bar"
material = "copper"
velocity = [50.0, 0.0]
mesh = { generator = "rectangle", origin = [0.0, 0.0], size = [0.004, 0.001], divisions = [12, 3] }

[[body.boundary]]
region = "xmin"
velocity = { x = 0.0 }
"""


def impactfv(*args, cwd=None):
    return run_cli(*args, cwd=cwd)


def test_run_writes_history_summary_and_paraview_files(tmp_path):
    case = tmp_path / "bar.toml"
    case.write_text(GOOD)
    proc = impactfv("run", case, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    out = tmp_path / "results" / "bar"
    with open(out / "history.csv") as fh:
        rows = list(csv.DictReader(fh))
    for col in ("time", "dt", "kinetic_energy", "strain_energy", "total_energy",
                "momentum_x", "momentum_y"):
        assert col in rows[0]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "completed"
    assert summary["steps"] == len(rows) - 1
    assert float(rows[-1]["time"]) == pytest.approx(2.0e-6, rel=1e-12)
    pvd = ET.parse(out / "fields.pvd").getroot()
    files = [d.get("file") for d in pvd.iter("DataSet")]
    assert len(files) == 3
    mesh = meshio.read(out / files[-1])
    for name in ("velocity", "displacement", "pressure", "von_mises", "J"):
        assert name in mesh.point_data
    # the clamped end pushes back: a compressive (positive) pressure appears there
    assert mesh.point_data["pressure"].max() > 1e6


def test_check_reports_time_step_and_memory(tmp_path):
    case = tmp_path / "bar.toml"
    case.write_text(GOOD)
    proc = impactfv("check", case)
    assert proc.returncode == 0, proc.stderr
    assert "c_p = 1487.57 m/s" in proc.stdout
    assert "time step" in proc.stdout and "memory" in proc.stdout
    assert not (tmp_path / "results").exists()


BAD = [
    ("[run]\nend_time = 2.0e-6", "[run]\nend_tim = 2.0e-6", "run.end_tim: unknown key (did you mean 'end_time'?)"),
    ("[run]\nend_time = 2.0e-6", "[run]\ncfl = 0.5", "run.end_time: required key is missing"),
    ("end_time = 2.0e-6", 'end_time = "soon"', "run.end_time"),
    ("poisson_ratio = 0.495", "poisson_ratio = 0.5", "material[0].poisson_ratio"),
    ("density = 8930.0", "density = 0.0", "material[0].density"),
    ('material = "copper"', 'material = "steel"', "body[0].material: unknown material 'steel'"),
    ('mesh = { generator = "rectangle", origin = [0.0, 0.0], size = [0.004, 0.001], divisions = [12, 3] }',
     'mesh = { file = "missing.msh" }', "missing.msh: mesh file not found"),
    ('region = "xmin"', 'region = "left"', "body[0].boundary[0].region: unknown region 'left'"),
    ("velocity = [50.0, 0.0]", 'velocity = ["__import__(\'os\')", 0]', "body[0].velocity.x"),
    ("velocity = [50.0, 0.0]", "velocity = [50.0]", "body[0].velocity"),
    ("divisions = [12, 3]", "divisions = [12, 0]", "body[0].mesh"),
]


@pytest.mark.parametrize("good,bad,expected", BAD)
def test_bad_input_gives_one_line_and_exit_code_2(tmp_path, good, bad, expected):
    assert good in GOOD
    case = tmp_path / "bad.toml"
    case.write_text(GOOD.replace(good, bad, 1))
    proc = impactfv("run", case, cwd=tmp_path)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert expected in lines[0]
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "results").exists() or not any((tmp_path / "results").rglob("*.csv"))


def test_degenerate_triangles_in_a_mesh_file_are_refused(tmp_path):
    pts = np.array([[0, 0], [1, 0], [0, 1], [2, 0]], float)
    tri = np.array([[0, 1, 2], [0, 1, 3]])  # the second is flat
    meshio.write(tmp_path / "flat.msh", meshio.Mesh(pts, [("triangle", tri)]),
                 file_format="gmsh22", binary=False)
    case = tmp_path / "c.toml"
    case.write_text(GOOD.replace('{ generator = "rectangle", origin = [0.0, 0.0], size = [0.004, '
                                 '0.001], divisions = [12, 3] }', '{ file = "flat.msh" }')
                    .split("[[body.boundary]]")[0])
    proc = impactfv("check", case)
    assert proc.returncode == 2
    assert "flat.msh" in proc.stderr and "degenerate" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1


def test_gmsh_file_with_physical_groups(tmp_path):
    """A .msh file read through meshio: physical line groups become named regions."""
    from impactfv.mesh import rectangle
    m = rectangle((0, 0), (0.004, 0.001), (8, 2))
    lines = np.concatenate([m.regions["xmin"], m.regions["ymin"]])
    tags = np.concatenate([np.full(len(m.regions["xmin"]), 1), np.full(len(m.regions["ymin"]), 2)])
    mesh = meshio.Mesh(np.column_stack([m.points, np.zeros(len(m.points))]),
                       [("line", lines), ("triangle", m.cells)],
                       cell_data={"gmsh:physical": [tags, np.full(len(m.cells), 3)],
                                  "gmsh:geometrical": [tags, np.full(len(m.cells), 3)]},
                       field_data={"clamp": np.array([1, 1]), "floor": np.array([2, 1]),
                                   "domain": np.array([3, 2])})
    meshio.write(tmp_path / "bar.msh", mesh, file_format="gmsh22", binary=False)
    text = GOOD.replace('{ generator = "rectangle", origin = [0.0, 0.0], size = [0.004, 0.001], '
                        'divisions = [12, 3] }', '{ file = "bar.msh" }')
    text = text.replace('region = "xmin"', 'region = "clamp"')
    (tmp_path / "bar.toml").write_text(text)
    proc = impactfv("run", "bar.toml", "-o", "out", "--no-progress", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["nodes"] == len(m.points)


# ------------------------------------------------------------------ --set, --debug, help

def test_set_overrides_keys_of_the_case(tmp_path):
    case = tmp_path / "bar.toml"
    case.write_text(GOOD)
    proc = impactfv("run", case, "-o", tmp_path / "out", "--no-progress",
                    "--set", "run.end_time=1e-6", "--set", "body[0].velocity=[10, 0]",
                    "--set", "run.method=fem-t3")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["end_time"] == pytest.approx(1e-6, rel=1e-12)
    assert summary["method"] == "fem-t3"
    with open(tmp_path / "out" / "history.csv") as fh:
        first = next(csv.DictReader(fh))
    # the clamped column of nodes starts at rest, the others at 10 m/s (not 50)
    mass = 8930.0 * 0.004 * 0.001
    assert 0.8 * 0.5 * mass * 10 ** 2 < float(first["kinetic_energy"]) < 0.5 * mass * 10 ** 2


@pytest.mark.parametrize("command", ["run", "check", "compare"])
@pytest.mark.parametrize("setting,words", [
    ("run.end_tim=1e-6", ["--set run.end_tim: unknown key (did you mean 'end_time'?)"]),
    ("body[0].mesh.sise=[1, 1]", ["--set body[0].mesh.sise: unknown key", "'size'"]),
    ("body[2].velocity=[1, 0]", ["--set body[2].velocity", "1 entry in body"]),
    ("run.end_time=soon", ["--set run.end_time: input should be a valid number"]),
    ("run.cfl=2", ["--set run.cfl: input should be less than or equal to 1"]),
    ("run.end_time", ["expected KEY=VALUE"]),
    ("body[0].velocity=[1,", ["--set body[0].velocity: not a TOML value"]),
])
def test_bad_set_gives_one_line_and_exit_code_2(tmp_path, command, setting, words):
    case = tmp_path / "bar.toml"
    case.write_text(GOOD)
    proc = impactfv(command, case, "--set", setting, cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert str(case) in lines[0]
    for word in words:
        assert word in lines[0], lines[0]
    assert not (tmp_path / "results").exists()


def test_debug_after_the_subcommand_shows_the_traceback(tmp_path):
    case = tmp_path / "bar.toml"
    case.write_text(GOOD.replace("end_time = 2.0e-6", "end_time = -1.0"))
    quiet = impactfv("check", case)
    assert quiet.returncode == 2 and "Traceback" not in quiet.stderr
    for args in (("--debug", "check", case), ("check", case, "--debug")):
        loud = impactfv(*args)
        assert "Traceback" in loud.stderr and "InputError" in loud.stderr, args


def test_help_reads_as_plain_text():
    for args in ((), ("run",), ("check",), ("compare",), ("plot",)):
        proc = impactfv(*args, "--help")
        assert proc.returncode == 0
        assert "``" not in proc.stdout and "`" not in proc.stdout
        assert "\n\n\n" not in proc.stdout
        assert proc.stdout.strip()


def test_usage_errors_are_one_line():
    proc = impactfv("run")
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1 and "case" in proc.stderr


def test_check_output_has_no_stray_blank_lines(tmp_path):
    proc = impactfv("check", ROOT / "examples" / "plate_with_hole.toml")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("case: ") and "\n\n" not in proc.stdout


def test_the_run_path_does_not_load_matplotlib(tmp_path):
    """matplotlib is only for pictures (compare, plot): a run, with its overlap check of
    two bodies, does not import it."""
    import subprocess
    import sys
    code = ("import sys\n"
            "from impactfv import load_case, run\n"
            "from impactfv.validation.bars import two_bars\n"
            f"run(load_case(two_bars(divisions=(10, 2), end_time=1e-6)), {str(tmp_path)!r})\n"
            "print('matplotlib' in sys.modules)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "False"


def test_progress_bar_draws_on_one_line():
    import io

    from impactfv.pipeline.progress import progress_bar

    stream = io.StringIO()
    bar = progress_bar(True, 2e-5, stream, columns=120)
    for _ in range(4):
        bar.update(5e-6)
    bar.close()
    text = stream.getvalue()
    assert text.endswith("100%|" + "#" * 30 + "| 2.000e-05/2.000e-05 s [00:00<00:00]\n")
    assert text.count("\n") == 1 and text.startswith("\rsimulated time")
    assert progress_bar(False, 1.0) is None


def test_progress_bar_notes_the_first_step_and_then_blanks_the_note_out(monkeypatch):
    """The note shown until the first update is overwritten by blanks, so no tail of it
    stays on the line; the time left comes from the updates after the first one, not from
    the wait before it; on any terminal width the line fits (it never wraps)."""
    import io

    from impactfv.pipeline import progress

    clock = [1000.0]
    monkeypatch.setattr(progress.time, "monotonic", lambda: clock[0])
    stream = io.StringIO()
    bar = progress.ProgressBar(1.0, stream, interval=0.0, note="first step (compiling)",
                               columns=200)
    first = stream.getvalue()
    assert first.startswith("\rsimulated time   0%|") and first.endswith(" first step (compiling)")
    clock[0] += 100.0                      # a first step of 100 s (compilation)
    bar.update(0.25)
    second = stream.getvalue()[len(first):]
    assert "compiling" not in second
    assert len(second) == len(first)       # the longer line blanked out to its end
    assert second.rstrip().endswith("[01:40<?]")    # one update: no rate yet
    clock[0] += 10.0                       # then 0.25 s of simulated time per 10 s
    bar.update(0.25)
    third = stream.getvalue()[len(first) + len(second):]
    # 0.5 left at 0.025 per s: 20 s (from the whole 110 s it would be 110 s)
    assert third.rstrip().endswith("[01:50<00:20]"), third
    # a continued run starts at its time, and its first step is still the first update
    stream = io.StringIO()
    bar = progress.ProgressBar(1.0, stream, interval=0.0, columns=200, start_at=0.5)
    clock[0] += 100.0
    bar.update(0.1)
    clock[0] += 10.0
    bar.update(0.1)
    assert stream.getvalue().rstrip().endswith("[01:50<00:30]")
    for columns in (20, 40, 60, 64, 72, 80, 100, 140):
        stream = io.StringIO()
        bar = progress.ProgressBar(1.0, stream, interval=0.0, columns=columns,
                                   note="loading the kernels (compiled on the first run)")
        clock[0] += 7300.0                 # clocks with hours are longer
        bar.update(0.5)
        bar.close()
        lines = stream.getvalue().rstrip("\n").split("\r")[1:]
        assert all(len(line) <= columns - 1 for line in lines), (columns, lines)
        # the note, at least shortened, shown from 80 columns
        assert ("loading the kernels" in lines[0]) == (columns >= 80), (columns, lines[0])
    assert "|" + "#" * 15 + " " * 15 + "|" in lines[-1]    # 140 columns: the whole bar


def test_progress_bar_width_falls_back_when_the_terminal_reports_none(monkeypatch):
    """A pseudo-terminal may report 0 columns; a stream without a terminal has no size: the
    bar then takes COLUMNS (or 80), never a width that would cut its line to nothing."""
    import io
    import os

    from impactfv.pipeline import progress

    class Tty(io.StringIO):
        def fileno(self):
            return 2

    monkeypatch.setenv("COLUMNS", "97")
    monkeypatch.setattr(progress.os, "get_terminal_size",
                        lambda fd=None: os.terminal_size((0, 0)))
    assert progress._terminal_columns(Tty()) == 97
    assert progress._terminal_columns(io.StringIO()) == 97     # no fileno: no terminal
