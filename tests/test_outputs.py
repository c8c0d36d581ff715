"""Results out: ParaView frames with reference points + displacement and the fields users
expect, compressed; rigid walls as geometry; history every N steps; a choice of fields; the
PNG pictures of ``impactfv plot``."""

import csv
import json
import struct
from pathlib import Path

import meshio
import numpy as np
import pytest
from conftest import COPPER, run_cli

from impactfv import load_case, run
from impactfv.errors import InputError
from impactfv.case import FIELDS
from impactfv.io.writers import SnapshotWriter, cell_type
from impactfv.pipeline import Schedule
from impactfv.validation.bars import bar_on_wall, two_bars


def frames(folder):
    import xml.etree.ElementTree as ET
    root = ET.parse(Path(folder) / "fields.pvd").getroot()
    return [(float(d.get("timestep")), Path(folder) / d.get("file"))
            for d in root.iter("DataSet")]


@pytest.fixture(scope="module")
def bars_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("bars")
    case = two_bars(divisions=(20, 4), end_time=8e-6)
    case["run"]["output_interval"] = 4e-6
    return run(load_case(case), out), out


def test_frames_hold_reference_points_and_displacement(bars_run):
    result, out = bars_run
    t, last = frames(out)[-1]
    mesh = meshio.read(last)
    X = np.concatenate([f["reference_points"] for f in result.bodies.values()])
    x = np.concatenate([f["points"] for f in result.bodies.values()])
    assert np.array_equal(mesh.points[:, :2], X)            # the reference configuration
    assert np.all(mesh.points[:, 2] == 0.0)
    u = mesh.point_data["displacement"]
    assert np.abs(u).max() > 1e-5                             # the bars did move
    assert np.allclose(mesh.points[:, :2] + u[:, :2], x, rtol=0, atol=1e-15)
    assert "vtkZLibDataCompressor" in last.read_text(errors="ignore")[:400]


def test_frames_have_the_documented_fields(bars_run):
    result, out = bars_run
    mesh = meshio.read(frames(out)[-1][1])
    data = mesh.point_data
    assert set(data) == set(FIELDS)
    n = len(mesh.points)
    assert data["velocity"].shape == (n, 3) and data["stress"].shape == (n, 6)
    assert data["body"].dtype.kind == "i" and data["contact_status"].dtype.kind == "i"
    assert np.bincount(data["body"]).tolist() == [len(f["points"])
                                                  for f in result.bodies.values()]
    s = data["stress"]  # xx, yy, zz, xy, yz, xz
    assert np.abs(s[:, 4:]).max() == 0.0                      # plane strain
    assert np.allclose(data["pressure"], -(s[:, 0] + s[:, 1] + s[:, 2]) / 3,
                       atol=1e-9 * np.abs(s).max())
    dev = s[:, :3] - s[:, :3].mean(axis=1, keepdims=True)
    vm = np.sqrt(1.5 * (np.sum(dev ** 2, axis=1) + 2 * s[:, 3] ** 2))
    assert np.allclose(data["von_mises"], vm, atol=1e-9 * np.abs(s).max())
    assert np.abs(s[:, 2]).max() > 1e6                        # sigma_zz of plane strain
    assert set(np.unique(data["contact_status"])) <= {0, 1, 2}
    assert (data["contact_status"] == 2).sum() > 0            # in contact at 8 us (slip)
    assert np.all(data["J"] > 0.9) and np.all(data["J"] < 1.1)


def test_rigid_walls_are_written_as_geometry(tmp_path):
    case = bar_on_wall(divisions=(20, 4), end_time=4e-6)
    case["contact"][0]["wall"]["velocity"] = [-10.0, 0.0]
    case["run"]["output_interval"] = 2e-6
    run(load_case(case), tmp_path)
    wall = case["contact"][0]["wall"]
    point, normal = np.array(wall["point"], float), np.array(wall["normal"], float)
    normal /= np.linalg.norm(normal)
    listed = frames(tmp_path)
    assert (tmp_path / "walls.pvd").is_file()
    for k, (t, _) in enumerate(listed):
        w = meshio.read(tmp_path / f"walls_{k:04d}.vtu")
        assert [b.type for b in w.cells] == ["line"]
        p = w.points[:, :2]
        moved = point + t * np.array(wall["velocity"])
        assert np.allclose((p - moved) @ normal, 0.0, atol=1e-15)
        assert np.linalg.norm(p[1] - p[0]) >= 0.01           # as long as the 10 mm bar


def test_fe_frames_keep_quads_and_reference_points(tmp_path):
    case = two_bars(divisions=(10, 2), end_time=4e-6)
    case["run"]["method"] = "fem-q4md"
    result = run(load_case(case), tmp_path)
    mesh = meshio.read(frames(tmp_path)[-1][1])
    assert [b.type for b in mesh.cells] == ["quad"]
    X = np.concatenate([f["reference_points"] for f in result.bodies.values()])
    assert np.array_equal(mesh.points[:, :2], X)
    assert {"stress", "J", "pressure", "body"} <= set(mesh.point_data)
    s = mesh.point_data["stress"]
    assert np.allclose(mesh.point_data["pressure"], -(s[:, 0] + s[:, 1] + s[:, 2]) / 3,
                       atol=1e-6 * np.abs(s).max())


def test_frames_are_dimension_generic(tmp_path):
    """3D: tetrahedra, 3-component vectors and 3 x 3 stress as they come (the 3D stepper)."""
    X = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], float)
    tets = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
    sigma = np.zeros((5, 3, 3))
    sigma[:, 0, 2] = sigma[:, 2, 0] = np.arange(5.0)
    writer = SnapshotWriter(tmp_path, walls=[(np.zeros(3), np.array([0, 0, 1.0]),
                                              np.zeros(3), 2.0)])
    writer.write(0.0, X, tets, {"velocity": np.ones((5, 3)), "stress": sigma,
                                "body": np.zeros(5)})
    mesh = meshio.read(tmp_path / "fields_0000.vtu")
    assert [b.type for b in mesh.cells] == ["tetra"]
    assert np.array_equal(mesh.point_data["stress"][:, 5], np.arange(5.0))   # xz
    assert mesh.point_data["body"].dtype.kind == "i"
    wall = meshio.read(tmp_path / "walls_0000.vtu")
    assert [b.type for b in wall.cells] == ["quad"] and np.allclose(wall.points[:, 2], 0)
    assert cell_type(2, 3) == "triangle" and cell_type(2, 4) == "quad"


def test_output_file_size_falls_with_compression(bars_run, tmp_path):
    """The frames are zlib-compressed: at least 1.5x smaller than the same data raw."""
    _, out = bars_run
    path = frames(out)[-1][1]
    mesh = meshio.read(path)
    meshio.write(tmp_path / "raw.vtu", mesh, binary=True, compression=None)
    assert path.stat().st_size * 1.5 < (tmp_path / "raw.vtu").stat().st_size


# ------------------------------------------------------------------ [output]

def test_history_every_n_steps_keeps_the_first_and_last_rows(tmp_path):
    case = two_bars(divisions=(20, 4), end_time=6e-6)
    full = run(load_case(case))
    case["output"] = {"history_every": 7}
    sparse = run(load_case(case), tmp_path)
    steps = full.summary["steps"]
    assert steps % 7 != 0 and sparse.summary["steps"] == steps
    expected = list(range(0, steps + 1, 7)) + [steps]
    assert np.array_equal(sparse.history["time"], full.history["time"][expected])
    # the same rows; a row the sparse run computes after the step (backends.cpu.monitors) rather
    # than in the last stage's pass (backends.cpu.rk_update_last) may round its sums differently
    # where the compiler contracts them into fused multiply-adds differently
    np.testing.assert_allclose(sparse.history["total_energy"],
                               full.history["total_energy"][expected], rtol=1e-14, atol=0)
    with open(tmp_path / "history.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == len(expected)
    assert float(rows[-1]["time"]) == pytest.approx(6e-6, rel=1e-12)
    assert json.loads((tmp_path / "summary.json").read_text())["final"]["time"] == \
        pytest.approx(6e-6, rel=1e-12)


def test_a_choice_of_fields(tmp_path):
    case = two_bars(divisions=(10, 2), end_time=2e-6)
    case["output"] = {"fields": ["pressure", "contact_status"]}
    run(load_case(case), tmp_path)
    mesh = meshio.read(frames(tmp_path)[-1][1])
    assert set(mesh.point_data) == {"pressure", "contact_status"}


@pytest.mark.parametrize("output,words", [
    ('fields = ["pressure", "presure"]', ["output.fields", "unknown field 'presure'",
                                          "did you mean 'pressure'", "valid: velocity,"]),
    ("history_every = 0", ["output.history_every", "greater than or equal to 1"]),
    ("history_evry = 3", ["output.history_evry", "did you mean 'history_every'"]),
    ("history_every = 2.5", ["output.history_every"]),
])
def test_bad_output_settings_are_one_line(tmp_path, output, words):
    case = tmp_path / "c.toml"
    case.write_text(f"""[run]
end_time = 1e-6
[output]
{output}
[[material]]
name = "copper"
density = 8930.0
youngs_modulus = 585.0e6
poisson_ratio = 0.495
[[body]]
name = "b"
material = "copper"
mesh = {{ generator = "rectangle", origin = [0, 0], size = [1, 1], divisions = [2, 2] }}
""")
    proc = run_cli("check", case)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    for word in words:
        assert word in lines[0], lines[0]


def test_schedule_defaults_keep_every_step():
    assert Schedule(1.0).history_every == 1 and Schedule(1.0).fields is None


# ------------------------------------------------------------------ impactfv plot

def png_pixels(path):
    """(width, height, RGB(A) pixel array) of a PNG, checking its signature."""
    data = Path(path).read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    import matplotlib.image as mpimg
    img = mpimg.imread(path)
    width, height = struct.unpack(">II", data[16:24])
    return width, height, img


def assert_not_blank(path):
    width, height, img = png_pixels(path)
    assert width > 300 and height > 200
    rgb = img[..., :3].reshape(-1, 3)
    colours = np.unique(np.round(rgb * 255).astype(np.uint8), axis=0)
    assert len(colours) > 50                  # curves, colour maps, text: not one colour
    assert rgb.std() > 0.05


def test_plot_writes_field_and_history_pictures(bars_run, tmp_path):
    _, out = bars_run
    proc = run_cli("plot", out, "-o", tmp_path / "pics")
    assert proc.returncode == 0, proc.stderr
    for name in ("pressure.png", "histories.png"):
        assert_not_blank(tmp_path / "pics" / name)
    proc = run_cli("plot", out, "-o", tmp_path / "pics", "--field", "velocity_x",
                   "--times", "0,8e-6")
    assert proc.returncode == 0, proc.stderr
    assert_not_blank(tmp_path / "pics" / "velocity_x.png")
    w2, h2, _ = png_pixels(tmp_path / "pics" / "velocity_x.png")
    w4, h4, _ = png_pixels(tmp_path / "pics" / "pressure.png")
    assert (w2, h2) != (w4, h4)               # two frames drawn, not the default three


def test_the_pictures_of_a_field_differ_between_frames(bars_run, tmp_path):
    """The drawn field is read from the frames: the first frame (at rest, p = 0 everywhere:
    one colour on the bodies) and the last (after the impact: a colour map of pressures)
    give different pictures."""
    _, out = bars_run

    def colours(t):
        assert run_cli("plot", out, "-o", tmp_path / t, "--times", t).returncode == 0
        rgb = png_pixels(tmp_path / t / "pressure.png")[2][..., :3].reshape(-1, 3)
        return len(np.unique(np.round(rgb * 255).astype(np.uint8), axis=0))

    assert colours("8e-6") > 2 * colours("0")


@pytest.mark.parametrize("args,words", [
    (["--field", "presure"], ["no field 'presure'", "pressure"]),
    (["--field", "stress"], ["stress_xx"]),
    (["--times", "soon"], ["--times"]),
])
def test_plot_bad_arguments_are_one_line(bars_run, args, words):
    _, out = bars_run
    proc = run_cli("plot", out, *args)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    for word in words:
        assert word in lines[0], lines[0]


def test_plot_refuses_a_folder_without_results(tmp_path):
    proc = run_cli("plot", tmp_path)
    assert proc.returncode == 2 and "not a result folder" in proc.stderr


def test_run_plot_option(tmp_path):
    case = tmp_path / "bars.toml"
    case.write_text(f"""[run]
end_time = 2e-6
[[material]]
{''.join(f'{k} = {v!r}' + chr(10) for k, v in COPPER.items()).replace("'", '"')}
[[body]]
name = "bar"
material = "copper"
velocity = [50.0, 0.0]
mesh = {{ generator = "rectangle", origin = [0, 0], size = [0.004, 0.001], divisions = [8, 2] }}
[[body.boundary]]
region = "xmin"
velocity = {{ x = 0.0 }}
""")
    proc = run_cli("run", case, "-o", tmp_path / "out", "--no-progress", "--plot")
    assert proc.returncode == 0, proc.stderr
    assert_not_blank(tmp_path / "out" / "plots" / "pressure.png")
    assert_not_blank(tmp_path / "out" / "plots" / "histories.png")


def test_png_checker_sees_a_blank_picture(tmp_path):
    """The 'not blank' check of these tests fails on a blank picture."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig = plt.figure(figsize=(5, 4))
    fig.savefig(tmp_path / "blank.png")
    plt.close(fig)
    with pytest.raises(AssertionError):
        assert_not_blank(tmp_path / "blank.png")
