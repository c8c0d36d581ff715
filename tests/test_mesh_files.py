"""Meshes from the tools impact engineers use: Abaqus .inp files with named sets, quad
meshes, meshes in millimetres, gmsh meshes with physical groups; each runs with its
regions."""

import json
from pathlib import Path

import meshio
import numpy as np
import pytest
from conftest import COPPER, material_toml, run_cli

from impactfv import load_case, run
from impactfv.errors import InputError
from impactfv.mesh import boundary_facets, read_mesh, rectangle
from impactfv.mesh.edges import edge_keys

ROOT = Path(__file__).resolve().parents[1]


def keys(facets):
    return set(edge_keys(np.asarray(facets)).tolist())


def write_inp(path, points, cells, etype, node_ids, elem_ids, sets_text=""):
    lines = ["*HEADING", "written by the tests", "** a comment", "*NODE"]
    lines += [f"{i}, {float(x)!r}, {float(y)!r}" for i, (x, y) in zip(node_ids, points)]
    lines.append(f"*ELEMENT, TYPE={etype}, ELSET=ALL")
    lines += [f"{e}, " + ", ".join(str(node_ids[n]) for n in c) for e, c in zip(elem_ids, cells)]
    lines.append(sets_text)
    lines += ["*MATERIAL, NAME=COPPER", "*DENSITY", "8930.", "*STEP", "*END STEP"]
    path.write_text("\n".join(lines) + "\n")


def face_lines(cells, elem_ids, facets):
    """'element, Sk' lines of the faces of ``cells`` that are in ``facets``."""
    wanted = keys(facets)
    out = []
    m = cells.shape[1]
    for e, c in zip(elem_ids, cells):
        for k in range(m):
            if edge_keys(np.array([[c[k], c[(k + 1) % m]]]))[0] in wanted:
                out.append(f"{e}, S{k + 1}")
    return out


# ------------------------------------------------------------------ Abaqus named sets

@pytest.fixture
def triangle_inp(tmp_path):
    """A 4 mm x 1 mm rectangle of CPE3 triangles (ids with gaps) and its named sets."""
    m = rectangle((0.0, 0.0), (0.004, 0.001), (8, 2))
    node_ids = 10 * np.arange(1, len(m.points) + 1) + 3
    elem_ids = 7 * np.arange(1, len(m.cells) + 1)
    x, y = m.points[:, 0], m.points[:, 1]
    nid = lambda mask: ", ".join(map(str, node_ids[mask]))  # noqa: E731
    bottom = np.flatnonzero(np.isin(m.cells, np.flatnonzero(np.isclose(y, 0))).any(axis=1))
    top_elements = np.flatnonzero(np.isin(m.cells, np.flatnonzero(np.isclose(y, 0.001)))
                                  .any(axis=1))
    middle = np.flatnonzero(np.isclose(x, 0.002) & np.isclose(y, 0.0005))
    text = "\n".join([
        "*NSET, NSET=CLAMP", nid(np.isclose(x, 0)),
        "*ELSET, ELSET=BOTTOM_ELS", ", ".join(map(str, elem_ids[bottom])),
        "*NSET, NSET=TOP", nid(np.isclose(y, 0.001)),
        "*ELSET, ELSET=TOP", ", ".join(map(str, elem_ids[top_elements])),
        "*NSET, NSET=MIDDLE", nid(middle),
        "*NSET, NSET=EDGES", "CLAMP, TOP",
        "*SURFACE, NAME=RIGHT, TYPE=ELEMENT",
        *face_lines(m.cells, elem_ids, m.regions["xmax"]),
    ])
    path = tmp_path / "plate.inp"
    write_inp(path, m.points, m.cells, "CPE3", node_ids, elem_ids, text)
    expected_bottom = boundary_facets(m.cells)
    expected_bottom = expected_bottom[np.isin(
        edge_keys(expected_bottom), edge_keys(np.concatenate(
            [m.cells[bottom][:, [i, (i + 1) % 3]] for i in range(3)])))]
    return path, m, expected_bottom


def test_abaqus_named_sets_become_regions(triangle_inp):
    path, m, expected_bottom = triangle_inp
    mesh = read_mesh(path)
    assert np.allclose(mesh.points, m.points)
    assert keys(mesh.regions["CLAMP"]) == keys(m.regions["xmin"])       # node set
    assert keys(mesh.regions["BOTTOM_ELS"]) == keys(expected_bottom)    # element set
    assert len(mesh.regions["BOTTOM_ELS"]) == 8 + 2                    # + the two corners
    assert keys(mesh.regions["TOP"]) == keys(m.regions["ymax"])        # both: the facets
    assert keys(mesh.regions["RIGHT"]) == keys(m.regions["xmax"])      # *SURFACE, S-faces
    assert keys(mesh.regions["EDGES"]) == keys(m.regions["xmin"]) | keys(m.regions["ymax"])
    assert keys(mesh.regions["ALL"]) == keys(boundary_facets(m.cells))  # ELEMENT, ELSET=
    assert "MIDDLE" not in mesh.regions and "no facet on the boundary" in \
        mesh.skipped_sets["MIDDLE"]


def test_a_case_runs_with_abaqus_regions(triangle_inp, tmp_path):
    path, m, _ = triangle_inp
    case = tmp_path / "plate.toml"
    case.write_text(f"""[run]
end_time = 1e-6
{material_toml()}
[[body]]
name = "plate"
material = "copper"
velocity = [20.0, 5.0]
mesh = {{ file = "plate.inp" }}
[[body.boundary]]
region = "CLAMP"
velocity = {{ x = 0.0, y = 0.0 }}
[[body.boundary]]
region = "RIGHT"
traction = [-1.0e6, 0.0]
""")
    proc = run_cli("check", case)
    assert proc.returncode == 0, proc.stderr
    assert "CLAMP (2 edges)" in proc.stdout and "RIGHT (2 edges)" in proc.stdout
    assert "MIDDLE" in proc.stdout        # the skipped set is reported with its reason
    result = run(load_case(case))
    assert result.summary["status"] == "completed"
    f = result.bodies["plate"]
    clamped = np.isclose(f["reference_points"][:, 0], 0.0)
    assert clamped.sum() == 3
    assert np.all(f["velocity"][clamped] == 0.0)
    assert np.abs(f["velocity"][~clamped]).max() > 1.0


def test_region_naming_a_skipped_set_says_why(triangle_inp, tmp_path):
    case = tmp_path / "c.toml"
    case.write_text(f"""[run]
end_time = 1e-6
{material_toml()}
[[body]]
name = "plate"
material = "copper"
mesh = {{ file = "plate.inp" }}
[[body.boundary]]
region = "MIDDLE"
velocity = {{ x = 0.0 }}
""")
    proc = run_cli("check", case)
    assert proc.returncode == 2
    line = proc.stderr.strip()
    assert len(line.splitlines()) == 1 and "body[0].boundary[0].region" in line
    assert "'MIDDLE' is a node set with no facet on the boundary" in line


@pytest.mark.parametrize("text,words", [
    ("*ELEMENT, TYPE=CPE8R\n1, 1, 2, 3, 4, 5, 6, 7, 8", ["TYPE=CPE8R", "quadratic"]),
    ("*ELEMENT, TYPE=CAX4\n1, 1, 2, 3, 4", ["CAX4", "axisymmetric"]),
    ("*ELSET, ELSET=A\nNOPE", ["plate.inp:", "unknown set 'NOPE'"]),
    ("*SURFACE, NAME=S\n7, S4", ["plate.inp:", "no face S4"]),
    ("*SURFACE, NAME=S\n99999, S1", ["plate.inp:", "element 99999"]),
    ("*NSET, NSET=A\n123456", ["plate.inp:", "node 123456"]),
], ids=["quadratic", "axisymmetric", "unknown-set", "bad-face", "unknown-element",
        "unknown-node"])
def test_bad_abaqus_input_is_one_line(triangle_inp, text, words):
    path, _, _ = triangle_inp
    path.write_text(path.read_text().replace("*MATERIAL", text + "\n*MATERIAL"))
    with pytest.raises(InputError) as info:
        read_mesh(path)
    message = str(info.value)
    assert "\n" not in message
    for word in words:
        assert word in message, message


def test_meshio_point_and_cell_sets_become_regions(monkeypatch, tmp_path):
    """Formats other than .inp carry named sets as meshio's point_sets / cell_sets."""
    m = rectangle((0.0, 0.0), (0.004, 0.001), (8, 2))
    lines = m.regions["ymin"]
    fake = meshio.Mesh(m.points, [("line", lines), ("triangle", m.cells)],
                       point_sets={"left": np.flatnonzero(np.isclose(m.points[:, 0], 0))},
                       cell_sets={"floor": [np.arange(len(lines)), np.zeros(0, int)],
                                  "corner": [np.zeros(0, int), np.array([0])]})
    monkeypatch.setattr(meshio, "read", lambda name: fake)
    (tmp_path / "m.med").write_text("")
    mesh = read_mesh(tmp_path / "m.med")
    assert keys(mesh.regions["left"]) == keys(m.regions["xmin"])
    assert keys(mesh.regions["floor"]) == keys(m.regions["ymin"])
    corner = boundary_facets(m.cells[:1])
    assert keys(mesh.regions["corner"]) == keys(corner) & keys(boundary_facets(m.cells))


# ------------------------------------------------------------------ quadrilaterals

@pytest.fixture
def quad_inp(tmp_path):
    """A 10 mm x 4 mm plate of 10 x 4 CPE4R quads, coordinates in millimetres."""
    nx, ny = 10, 4
    X, Y = np.meshgrid(np.linspace(0, 10, nx + 1), np.linspace(0, 4, ny + 1))
    points = np.column_stack([X.ravel(), Y.ravel()])
    nid = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1)
    quads = np.column_stack([nid[:-1, :-1].ravel(), nid[:-1, 1:].ravel(),
                             nid[1:, 1:].ravel(), nid[1:, :-1].ravel()])
    left = np.flatnonzero(points[:, 0] == 0)
    text = "*NSET, NSET=LEFT\n" + ", ".join(str(i + 1) for i in left)
    path = tmp_path / "quads.inp"
    write_inp(path, points, quads, "CPE4R", np.arange(1, len(points) + 1),
              np.arange(1, len(quads) + 1), text)
    return path, points, quads


def test_quads_are_cut_in_a_checkerboard(quad_inp):
    path, points, quads = quad_inp
    mesh = read_mesh(path)
    assert np.array_equal(mesh.quads, quads) and len(mesh.cells) == 2 * len(quads)
    assert np.allclose(mesh.points, points)
    # the diagonal of every quad: the edge of its two triangles that is no quad edge
    quad_edges = keys(np.concatenate([quads[:, [i, (i + 1) % 4]] for i in range(4)]))
    tri_edges = np.concatenate([mesh.cells[:, [i, (i + 1) % 3]] for i in range(3)])
    diagonals = np.unique(edge_keys(tri_edges)[~np.isin(edge_keys(tri_edges),
                                                        list(quad_edges))])
    assert len(diagonals) == len(quads)
    ends = np.bincount(np.concatenate([diagonals >> 32, diagonals & 0xFFFFFFFF]),
                       minlength=len(points))
    cells_at = np.bincount(quads.ravel(), minlength=len(points))
    # no preferred direction: a node is the end of all the diagonals around it or of none
    assert set(np.unique(ends[cells_at == 4])) == {0, 4}
    # every corner is cut through (two triangles there, not one)
    assert np.all(ends[cells_at == 1] == 1)
    # half the diagonals run one way, half the other (up to the boundary)
    d = points[diagonals & 0xFFFFFFFF] - points[diagonals >> 32]
    rising = np.sum(d[:, 0] * d[:, 1] > 0)
    assert abs(rising - len(quads) / 2) <= 2


@pytest.mark.parametrize("method", ["fv", "fem-t3", "fem-q4md"])
def test_quad_mesh_runs_with_every_method(quad_inp, method):
    path, points, quads = quad_inp
    case = {"run": {"end_time": 1e-6, "method": method}, "material": [COPPER],
            "body": [{"name": "plate", "material": "copper", "velocity": [0.0, -20.0],
                      "mesh": {"file": path.name, "scale": 1e-3},
                      "boundary": [{"region": "LEFT", "velocity": {"x": 0.0, "y": 0.0}}]}]}
    result = run(load_case(case, base_dir=path.parent))
    f = result.bodies["plate"]
    assert result.summary["status"] == "completed"
    assert np.allclose(np.sort(f["reference_points"], axis=0), np.sort(points * 1e-3, axis=0))
    if method == "fem-q4md":
        assert f["cells"].shape == (len(quads), 4)
    left = f["reference_points"][:, 0] == 0.0
    assert left.sum() == 5 and np.all(f["velocity"][left] == 0.0)


# ------------------------------------------------------------------ millimetres

def test_a_millimetre_mesh_with_scale_runs_like_the_metre_mesh(tmp_path):
    m = rectangle((0.0, 0.0), (0.004, 0.001), (12, 3))
    lines = m.regions["xmin"]
    for name, factor in (("m.msh", 1.0), ("mm.msh", 1e3)):
        mesh = meshio.Mesh(m.points * factor, [("line", lines), ("triangle", m.cells)],
                           cell_data={"gmsh:physical": [np.ones(len(lines), int),
                                                        np.full(len(m.cells), 2)],
                                      "gmsh:geometrical": [np.ones(len(lines), int),
                                                           np.full(len(m.cells), 2)]},
                           field_data={"clamp": np.array([1, 1]), "bar": np.array([2, 2])})
        meshio.write(tmp_path / name, mesh, file_format="gmsh22", binary=False)
    results = []
    for mesh in ({"file": "m.msh"}, {"file": "mm.msh", "scale": 1e-3},
                 {"generator": "rectangle", "origin": [0, 0], "size": [4, 1],
                  "divisions": [12, 3], "scale": 1e-3}):
        case = {"run": {"end_time": 2e-6}, "material": [COPPER],
                "body": [{"name": "bar", "material": "copper", "velocity": [50.0, 0.0],
                          "mesh": mesh,
                          "boundary": [{"region": "clamp" if "file" in mesh else "xmin",
                                        "velocity": {"x": 0.0}}]}]}
        results.append(run(load_case(case, base_dir=tmp_path)))
    reference = results[0]
    for other in results[1:]:
        assert np.allclose(other.bodies["bar"]["reference_points"],
                           reference.bodies["bar"]["reference_points"], rtol=0, atol=1e-15)
        assert other.summary["steps"] == reference.summary["steps"]
        for column in ("kinetic_energy", "strain_energy", "momentum_x"):
            assert np.allclose(other.history[column], reference.history[column],
                               rtol=1e-9, atol=1e-12 * reference.history["total_energy"][0])
    assert results[0].history["strain_energy"].max() > 0.01 * results[0].history[
        "total_energy"][0]


@pytest.mark.parametrize("value", ["0.0", "-1e-3", "nan", '"mm"'])
def test_scale_must_be_a_positive_number(tmp_path, value):
    case = tmp_path / "c.toml"
    case.write_text(f"""[run]
end_time = 1e-6
{material_toml()}
[[body]]
name = "b"
material = "copper"
mesh = {{ generator = "rectangle", origin = [0, 0], size = [1, 1], divisions = [2, 2], scale = {value} }}
""")
    proc = run_cli("check", case)
    assert proc.returncode == 2 and "body[0].mesh.scale" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1


# ------------------------------------------------------------------ gmsh

GMSH_EXAMPLE = ROOT / "examples" / "plate_with_hole.msh"


def test_the_gmsh_example_mesh_has_its_physical_groups():
    mesh = read_mesh(GMSH_EXAMPLE)
    assert set(mesh.regions) == {"clamp", "struck", "sides", "hole"}
    assert np.ptp(mesh.points[:, 0]) == pytest.approx(20.0)      # millimetres
    # the hole's edges lie on its circle, the clamp's on x = 0
    hole = mesh.points[np.unique(mesh.regions["hole"])]
    assert np.allclose(np.hypot(hole[:, 0] - 10, hole[:, 1] - 5), 2.5, atol=1e-6)
    assert np.allclose(mesh.points[np.unique(mesh.regions["clamp"])][:, 0], 0.0)


def test_the_gmsh_example_case_runs_with_its_regions(tmp_path):
    proc = run_cli("run", ROOT / "examples" / "plate_with_hole.toml", "-o", tmp_path,
                   "--no-progress", "--set", "run.end_time=1e-6")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["status"] == "completed" and summary["bodies"] == ["plate", "disc"]


def test_the_gmsh_script_makes_the_example_mesh(tmp_path):
    pytest.importorskip("gmsh")
    import importlib.util

    spec = importlib.util.spec_from_file_location("plate_with_hole",
                                                  ROOT / "examples" / "plate_with_hole.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    made = read_mesh(module.make_mesh(tmp_path / "made.msh"))
    shipped = read_mesh(GMSH_EXAMPLE)
    assert set(made.regions) == set(shipped.regions)
    assert abs(len(made.points) - len(shipped.points)) <= 0.1 * len(shipped.points)
