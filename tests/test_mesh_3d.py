"""Tetrahedral meshes: the box generator, the checks of a mesh file, and the identities of
the 3D median dual (docs/theory.md, "Space")."""

import numpy as np
import pytest

from impactfv.errors import InputError
from impactfv.mesh import Mesh, median_dual, validate_and_orient
from impactfv.mesh.core import signed_volumes
from impactfv.mesh.dual import green_gauss_gradient
from impactfv.mesh.edges import boundary_facets, cell_facets, facet_keys
from impactfv.mesh.generators import box


def perturbed_box(divisions=(4, 3, 5), seed=0, amount=0.08):
    mesh = box((0.0, 0.0, 0.0), (2.0, 1.0, 1.5), divisions)
    rng = np.random.default_rng(seed)
    pts = mesh.points.copy()
    lo, hi = np.zeros(3), np.array([2.0, 1.0, 1.5])
    interior = np.all((pts > lo + 1e-9) & (pts < hi - 1e-9), axis=1)
    h = min(2.0 / divisions[0], 1.0 / divisions[1], 1.5 / divisions[2])
    pts[interior] += rng.uniform(-amount * h, amount * h, (interior.sum(), 3))
    return Mesh(pts, mesh.cells, mesh.regions)


def test_box_is_a_conforming_positively_oriented_tetrahedral_mesh():
    mesh = box((1.0, -1.0, 0.5), (2.0, 1.0, 1.5), (4, 3, 5))
    assert mesh.points.shape == (5 * 4 * 6, 3) and mesh.cells.shape == (6 * 60, 4)
    volumes = signed_volumes(mesh.points, mesh.cells)
    assert np.all(volumes > 0)
    assert volumes.sum() == pytest.approx(3.0, rel=1e-13)
    # every interior face has two tetrahedra, every boundary face one: no hanging faces
    _, counts = np.unique(facet_keys(cell_facets(mesh.cells, 3)), return_counts=True)
    n_boundary = 2 * 2 * (4 * 3 + 3 * 5 + 4 * 5)
    assert set(counts) == {1, 2} and (counts == 1).sum() == n_boundary


def test_quality_of_cubic_kuhn_cells():
    """Kuhn's tetrahedra of a cube have dihedral angles of 45, 60 and 90 degrees, and the
    radius ratio R / (3 r) of 1 for a regular tetrahedron."""
    q = box((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), (3, 3, 3)).quality()
    assert q["min_dihedral_deg"] == pytest.approx(45.0, abs=1e-9)
    assert q["edge_length_min"] == pytest.approx(1 / 3) and \
        q["edge_length_max"] == pytest.approx(np.sqrt(3) / 3)
    # one Kuhn tetrahedron of a unit cube: R = sqrt(3)/2, r = 1 / (2 + sqrt(2)) ... checked
    # against the formula for the simplex (0,0,0) (1,0,0) (1,1,0) (1,1,1)
    p = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [1, 1, 1]], float)
    areas = [0.5, 0.5, np.sqrt(2) / 2, np.sqrt(2) / 2]
    r_in = 3 * (1 / 6) / sum(areas)
    assert q["aspect_ratio_max"] == pytest.approx(np.sqrt(3) / 2 / (3 * r_in), rel=1e-9)
    regular = Mesh(np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float),
                   np.array([[0, 1, 2, 3]]))
    regular = validate_and_orient(regular, "regular")
    assert regular.quality()["aspect_ratio_max"] == pytest.approx(1.0, rel=1e-12)
    assert regular.quality()["min_dihedral_deg"] == pytest.approx(70.528779, rel=1e-7)


@pytest.mark.parametrize("divisions", [(3, 3, 3), (4, 5, 2), (2, 7, 2)])
def test_box_corners_are_not_cut_off_by_one_tetrahedron(divisions):
    """Every box corner lies on the main diagonal of its cell: six tetrahedra meet there (a
    single one would leave a corner node a 24th of a cell's volume)."""
    mesh = box((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), divisions)
    corners = [i for i, p in enumerate(mesh.points) if np.all((p == 0) | (p == 1))]
    assert len(corners) == 8
    for c in corners:
        assert (mesh.cells == c).any(axis=1).sum() == 6


def test_box_is_symmetric_about_its_centre_planes():
    """(with even division counts: an odd count leaves a centre cell that no mirror maps
    onto itself)"""
    mesh = box((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), (4, 6, 2))
    cells = {tuple(sorted(map(tuple, np.round(mesh.points[t], 12)))) for t in mesh.cells}
    for axis in range(3):
        mirrored = set()
        for t in mesh.cells:
            p = mesh.points[t].copy()
            p[:, axis] = 1.0 - p[:, axis]
            mirrored.add(tuple(sorted(map(tuple, np.round(p, 12)))))
        assert mirrored == cells


def test_box_regions_are_the_outward_faces_of_each_side():
    mesh = box((0.0, 0.0, 0.0), (2.0, 1.0, 1.5), (4, 3, 5))
    size = np.array([2.0, 1.0, 1.5])
    total = 0
    for axis, name in enumerate("xyz"):
        for side, sign in (("min", -1.0), ("max", 1.0)):
            faces = mesh.regions[name + side]
            p = mesh.points[faces]
            S = 0.5 * np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
            assert np.allclose(p[:, :, axis], 0.0 if side == "min" else size[axis])
            assert np.all(sign * S[:, axis] > 0)
            other = [k for k in range(3) if k != axis]
            assert np.abs(S[:, axis]).sum() == pytest.approx(np.prod(size[other]), rel=1e-13)
            total += len(faces)
    assert total == len(boundary_facets(mesh.cells, 3))


def test_dual_volumes_sum_to_the_body_volume():
    mesh = perturbed_box()
    dual = median_dual(mesh.points, mesh.cells)
    assert dual.volumes.sum() == pytest.approx(signed_volumes(mesh.points, mesh.cells).sum(),
                                               rel=1e-13)
    assert np.all(dual.volumes > 0)


def test_area_vectors_close_at_every_node():
    mesh = perturbed_box(seed=1)
    d = median_dual(mesh.points, mesh.cells)
    closure = np.zeros((mesh.n_nodes, 3))
    np.add.at(closure, d.edges[:, 0], d.area_vectors)
    np.add.at(closure, d.edges[:, 1], -d.area_vectors)
    for k in range(3):
        np.add.at(closure, d.facets[:, k], d.facet_vectors / 3)
    assert np.abs(closure).max() < 1e-15


def test_every_dual_face_points_along_its_edge():
    """C_ab^e . (X_b - X_a) = V_e / 2 in each tetrahedron, so C_ab . (X_b - X_a) > 0."""
    mesh = perturbed_box(seed=2)
    d = median_dual(mesh.points, mesh.cells)
    along = np.einsum("ij,ij->i", d.area_vectors,
                      mesh.points[d.edges[:, 1]] - mesh.points[d.edges[:, 0]])
    assert along.min() > 0
    # sum over edges of C_ab . (X_b - X_a) = 3 V (six edges of V/2 in every tetrahedron)
    assert along.sum() == pytest.approx(3 * signed_volumes(mesh.points, mesh.cells).sum(),
                                        rel=1e-12)


def test_gradient_of_a_linear_field_is_exact():
    """The (6, 1, 1)/8 boundary closure makes Green-Gauss exact for linear fields in 3D."""
    mesh = perturbed_box(seed=3)
    d = median_dual(mesh.points, mesh.cells)
    A = np.array([[3.0, -2.0, 0.5], [-0.5, 4.0, 1.0]])
    u = mesh.points @ A.T + np.array([1.0, -2.0])
    g = green_gauss_gradient(d, u)
    assert np.abs(g - A).max() < 1e-12


def test_gradient_equals_the_volume_weighted_element_gradients():
    mesh = perturbed_box(seed=4)
    d = median_dual(mesh.points, mesh.cells)
    X, Y, Z = mesh.points.T
    u = np.sin(3 * X) * np.cos(2 * Y) + X * Z ** 2
    g = green_gauss_gradient(d, u)[:, 0, :]
    p = mesh.points[mesh.cells]
    volume = signed_volumes(mesh.points, mesh.cells)
    edges = np.stack([p[:, k] - p[:, 0] for k in (1, 2, 3)], axis=1)
    du = u[mesh.cells[:, 1:]] - u[mesh.cells[:, :1]]
    ge = np.linalg.solve(edges, du[:, :, None])[:, :, 0]
    ref = np.zeros((mesh.n_nodes, 3))
    for k in range(4):
        np.add.at(ref, mesh.cells[:, k], (volume / 4)[:, None] * ge)
    ref /= d.volumes[:, None]
    assert np.abs(g - ref).max() < 1e-11 * np.abs(ref).max()


# ------------------------------------------------------------------ checks of a mesh file

def unit_tets():
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], float)
    return pts, np.array([[0, 1, 2, 3], [1, 2, 3, 4]])


def test_inverted_tetrahedra_are_turned_and_regions_reoriented():
    pts, tets = unit_tets()
    tets = tets[:, [0, 2, 1, 3]]                          # both inverted
    face = np.array([[0, 1, 2]])                           # region given inward
    mesh = validate_and_orient(Mesh(pts, tets, {"bottom": face}), "m.msh")
    assert np.all(signed_volumes(mesh.points, mesh.cells) > 0)
    p = mesh.points[mesh.regions["bottom"][0]]
    assert np.cross(p[1] - p[0], p[2] - p[0])[2] < 0     # outward: -z


@pytest.mark.parametrize("cells,message", [
    ([[0, 1, 2, 3], [0, 1, 2, 4], [0, 1, 2, 4]], "shared by more than two"),
    ([[0, 1, 2, 2], [1, 2, 3, 4]], "repeats a node"),
    ([[0, 1, 2, 5], [1, 2, 3, 4]], "out of range"),
])
def test_bad_tetrahedra_are_input_errors(cells, message):
    pts, _ = unit_tets()
    pts[4] = [0.2, 0.2, -1.0]
    with pytest.raises(InputError, match=message):
        validate_and_orient(Mesh(pts, np.array(cells)), "m.msh")


def test_flat_and_folded_tetrahedral_meshes_are_refused():
    pts, tets = unit_tets()
    flat = pts.copy()
    flat[3] = [0.3, 0.3, 0.0]
    with pytest.raises(InputError, match="degenerate tetrahedron"):
        validate_and_orient(Mesh(flat, tets), "m.msh")
    # a fifth point on the same side of face (1, 2, 3) as node 0: the two tets overlap
    folded = pts.copy()
    folded[4] = [0.1, 0.1, 0.1]
    with pytest.raises(InputError, match="folds over itself"):
        validate_and_orient(Mesh(folded, tets), "m.msh")


def test_region_not_on_the_boundary_is_refused():
    pts, tets = unit_tets()
    with pytest.raises(InputError, match="not on the boundary"):
        validate_and_orient(Mesh(pts, tets, {"inner": np.array([[1, 2, 3]])}), "m.msh")


def test_gmsh_tetrahedra_with_physical_surfaces(tmp_path):
    """A gmsh .msh of tetrahedra: its physical surfaces become the regions."""
    gmsh = pytest.importorskip("gmsh")
    path = tmp_path / "cube.msh"
    gmsh.initialize(["", "-v", "0"])
    try:
        gmsh.model.add("cube")
        gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
        gmsh.model.occ.synchronize()
        surfaces = gmsh.model.getEntities(2)
        lowest = min(surfaces, key=lambda s: gmsh.model.occ.getCenterOfMass(*s)[2])
        gmsh.model.addPhysicalGroup(2, [lowest[1]], name="bottom")
        gmsh.model.addPhysicalGroup(3, [1], name="solid")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.35)
        gmsh.model.mesh.generate(3)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    from impactfv.mesh import read_mesh

    mesh = validate_and_orient(read_mesh(path), str(path))
    assert mesh.dim == 3 and set(mesh.regions) == {"bottom"}
    assert signed_volumes(mesh.points, mesh.cells).sum() == pytest.approx(1.0, rel=1e-12)
    p = mesh.points[mesh.regions["bottom"]]
    assert np.allclose(p[:, :, 2], 0.0)
    S = 0.5 * np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    assert np.all(S[:, 2] < 0) and -S[:, 2].sum() == pytest.approx(1.0, rel=1e-12)
