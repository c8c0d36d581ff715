"""Identities of the median dual (docs/theory.md, "Space")."""

import numpy as np
import pytest

from impactfv.mesh import DIAGONAL_PATTERNS, median_dual, rectangle
from impactfv.mesh.dual import green_gauss_gradient


def perturbed_mesh(pattern, seed=0):
    mesh = rectangle((0.0, 0.0), (2.0, 1.0), (9, 6), pattern)
    rng = np.random.default_rng(seed)
    pts = mesh.points.copy()
    interior = (pts[:, 0] > 1e-9) & (pts[:, 0] < 2 - 1e-9) & (pts[:, 1] > 1e-9) & \
        (pts[:, 1] < 1 - 1e-9)
    pts[interior] += rng.uniform(-0.05, 0.05, (interior.sum(), 2))
    mesh.points = pts
    return mesh


@pytest.mark.parametrize("pattern", DIAGONAL_PATTERNS)
def test_dual_areas_sum_to_body_area(pattern):
    mesh = perturbed_mesh(pattern)
    dual = median_dual(mesh.points, mesh.cells)
    assert dual.volumes.sum() == pytest.approx(2.0, rel=1e-13)
    assert np.all(dual.volumes > 0)


@pytest.mark.parametrize("pattern", DIAGONAL_PATTERNS)
def test_area_vectors_close_at_every_node(pattern):
    mesh = perturbed_mesh(pattern)
    d = median_dual(mesh.points, mesh.cells)
    closure = np.zeros((mesh.n_nodes, 2))
    np.add.at(closure, d.edges[:, 0], d.area_vectors)
    np.add.at(closure, d.edges[:, 1], -d.area_vectors)
    np.add.at(closure, d.facets[:, 0], d.facet_vectors / 2)
    np.add.at(closure, d.facets[:, 1], d.facet_vectors / 2)
    assert np.abs(closure).max() < 1e-14


@pytest.mark.parametrize("pattern", DIAGONAL_PATTERNS)
def test_gradient_of_linear_field_is_exact(pattern):
    mesh = perturbed_mesh(pattern, seed=3)
    d = median_dual(mesh.points, mesh.cells)
    X, Y = mesh.points.T
    u = np.column_stack([3.0 * X - 2.0 * Y + 1.0, -0.5 * X + 4.0 * Y])
    g = green_gauss_gradient(d, u)
    expected = np.array([[3.0, -2.0], [-0.5, 4.0]])
    assert np.abs(g - expected).max() < 1e-12


def test_gradient_equals_area_weighted_element_gradients():
    """The edge-based gradient is the Omega-weighted mean of P1 element gradients."""
    mesh = perturbed_mesh("alternate", seed=7)
    d = median_dual(mesh.points, mesh.cells)
    X, Y = mesh.points.T
    u = np.sin(3 * X) * np.cos(2 * Y) + X ** 3
    g = green_gauss_gradient(d, u)[:, 0, :]
    p = mesh.points[mesh.cells]
    area = mesh.triangle_areas()
    ref = np.zeros((mesh.n_nodes, 2))
    for e, tri in enumerate(mesh.cells):
        A = np.column_stack([p[e, 1] - p[e, 0], p[e, 2] - p[e, 0]]).T
        ge = np.linalg.solve(A, [u[tri[1]] - u[tri[0]], u[tri[2]] - u[tri[0]]])
        for node in tri:
            ref[node] += area[e] / 3 * ge
    ref /= d.volumes[:, None]
    assert np.abs(g - ref).max() < 1e-11 * np.abs(ref).max()


def test_disc_generator_covers_the_polygon_with_good_triangles():
    from impactfv.mesh import disc

    mesh = disc((1.0, -2.0), 0.5, 6)
    n = 6 * 6
    assert mesh.n_nodes == 1 + 3 * 6 * 7
    dual = median_dual(mesh.points, mesh.cells)
    assert dual.volumes.sum() == pytest.approx(0.5 * n * 0.25 * np.sin(2 * np.pi / n),
                                               rel=1e-12)
    p = mesh.points[mesh.cells]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    area = 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    assert area.min() > 0.3 * area.mean()
    outer = mesh.regions["outer"]
    assert len(outer) == n
    assert np.allclose(np.linalg.norm(mesh.points[outer[:, 0]] - [1.0, -2.0], axis=1), 0.5)
    # counter-clockwise: each facet's right-hand normal points out of the disc
    edge = mesh.points[outer[:, 1]] - mesh.points[outer[:, 0]]
    normal = np.column_stack([edge[:, 1], -edge[:, 0]])
    mid = 0.5 * (mesh.points[outer[:, 0]] + mesh.points[outer[:, 1]]) - [1.0, -2.0]
    assert np.all((normal * mid).sum(axis=1) > 0)


def test_annulus_generator_covers_the_ring_with_good_triangles():
    """mesh generator "annulus": ``rings`` cells through the wall, an even number m of about
    square cells around it (annulus_segments), each cut along one diagonal in a
    checkerboard. The dual cells tile the polygonal ring exactly; boundary regions "outer"
    and "inner" lie on their circles, oriented so that each facet's right-hand normal points
    out of the material; the memory estimate counts exactly what it builds."""
    from impactfv.memory import counts_of_generator
    from impactfv.case import MeshSpec
    from impactfv.mesh import annulus
    from impactfv.mesh.generators import annulus_segments

    centre, R, r, rings = (1.0, -2.0), 0.5, 0.3, 4
    mesh = annulus(centre, R, r, rings)
    m = annulus_segments(R, r, rings)
    assert m % 2 == 0 and mesh.n_nodes == (rings + 1) * m and len(mesh.cells) == 2 * rings * m
    dual = median_dual(mesh.points, mesh.cells)
    polygon_ring = 0.5 * m * (R * R - r * r) * np.sin(2 * np.pi / m)
    assert dual.volumes.sum() == pytest.approx(polygon_ring, rel=1e-12)
    p = mesh.points[mesh.cells]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    area = 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    assert area.min() > 0.5 * area.mean()
    for name, radius, outward in (("outer", R, 1.0), ("inner", r, -1.0)):
        facets = mesh.regions[name]
        assert len(facets) == m
        assert np.allclose(np.linalg.norm(mesh.points[facets] - centre, axis=2), radius)
        edge = mesh.points[facets[:, 1]] - mesh.points[facets[:, 0]]
        normal = np.column_stack([edge[:, 1], -edge[:, 0]])
        mid = 0.5 * (mesh.points[facets[:, 0]] + mesh.points[facets[:, 1]]) - centre
        assert np.all(outward * (normal * mid).sum(axis=1) > 0)
    counts = counts_of_generator(MeshSpec(generator="annulus", centre=centre, radius=R,
                                          inner_radius=r, rings=rings))
    assert (counts.nodes, counts.triangles, counts.boundary) == \
        (mesh.n_nodes, len(mesh.cells), 2 * m)
