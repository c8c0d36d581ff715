"""The facet geometry of the contact search and overlap (geometry/facets.py): closest points,
dual boundary faces and polygon clipping, against brute force and exact areas."""

import numpy as np
import pytest

from impactfv.geometry import facets as G


def brute_closest(tri, point, n=400):
    """Closest point of a triangle by dense sampling of its barycentric coordinates."""
    u, v = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    keep = u + v <= 1
    u, v = u[keep], v[keep]
    pts = (1 - u - v)[:, None] * tri[0] + u[:, None] * tri[1] + v[:, None] * tri[2]
    return np.linalg.norm(pts - point, axis=1).min()


def test_closest_point_of_a_triangle():
    rng = np.random.default_rng(0)
    x = np.array([[0.0, 0.0, 0.0], [1.0, 0.1, 0.0], [0.2, 0.9, 0.3]])
    facet = np.array([0, 1, 2])
    w = np.empty(3)
    for point in rng.uniform(-1.0, 2.0, (60, 3)):
        dist = G.closest_point(x, facet, point, w)
        assert np.all(w >= -1e-14) and w.sum() == pytest.approx(1.0)
        assert np.linalg.norm(w @ x - point) == pytest.approx(dist, rel=1e-12)
        assert dist <= brute_closest(x, point) + 1e-12
        assert dist >= brute_closest(x, point) - 5e-3


def test_closest_point_of_a_segment():
    x = np.array([[0.0, 0.0], [2.0, 0.0]])
    w = np.empty(2)
    assert G.closest_point(x, np.array([0, 1]), np.array([0.5, 1.0]), w) == pytest.approx(1.0)
    assert w == pytest.approx([0.75, 0.25])
    assert G.closest_point(x, np.array([0, 1]), np.array([3.0, 0.0]), w) == pytest.approx(1.0)
    assert w == pytest.approx([0.0, 1.0])


def test_dual_faces_of_a_facet_share_its_area_vector():
    """The three quadrilaterals of a triangle are a third of it each, outward; the two
    half-segments of a segment half of it each."""
    x = np.array([[0.0, 0.0, 0.0], [1.0, 0.2, 0.1], [0.3, 0.8, -0.2]])
    S = np.empty(3)
    G.facet_area_vector(x, np.array([0, 1, 2]), S)
    out = np.empty(3)
    for a, others in ((0, [1, 2]), (1, [0, 2]), (2, [0, 1])):
        norm = G.dual_face_vector(x, x, a, np.array(others), S, out)
        assert out == pytest.approx(S / 3, rel=1e-12, abs=1e-15)
        assert norm == pytest.approx(np.linalg.norm(S) / 3)
    x2 = np.array([[0.0, 0.0], [3.0, 4.0]])
    S2 = np.empty(2)
    assert G.facet_area_vector(x2, np.array([0, 1]), S2) == pytest.approx(5.0)
    out2 = np.empty(2)
    G.dual_face_vector(x2, x2, 1, np.array([0]), S2, out2)
    assert out2 == pytest.approx(S2 / 2)
    # a body turned by 180 degrees: the face turns with it, it does not flip inward
    turned = -x2
    G.dual_face_vector(turned, x2, 1, np.array([0]), S2, out2)
    assert out2 == pytest.approx(-S2 / 2)


def square(x0, y0, s):
    return np.array([[x0, y0], [x0 + s, y0], [x0 + s, y0 + s], [x0, y0 + s]], float)


@pytest.mark.parametrize("offset,area", [((0.5, 0.5), 0.25), ((0.0, 0.0), 1.0),
                                         ((2.0, 0.0), 0.0), ((0.25, -0.5), 0.375)])
def test_clipping_two_squares(offset, area):
    assert G._test_clip(square(*offset, 1.0), square(0, 0, 1.0)) == pytest.approx(area)


def test_clipping_a_rotated_square_by_a_triangle():
    """A square turned by 45 degrees about the origin, clipped by the triangle (0,0) (1,0)
    (0,1): the part in the first quadrant below x + y = 1."""
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
    sq = square(-0.5, -0.5, 1.0) @ np.array([[c, s], [-s, c]])
    tri = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    # the turned square is |x| + |y| <= 1/sqrt(2): its first-quadrant quarter has area 1/4
    # and lies inside x + y <= 1
    assert G._test_clip(sq, tri) == pytest.approx(0.25, rel=1e-12)
    # exactness under sampling: a Monte-Carlo estimate agrees
    rng = np.random.default_rng(1)
    p = rng.uniform(-1, 1, (200_000, 2))
    inside = (np.abs(p[:, 0]) + np.abs(p[:, 1]) <= 1 / np.sqrt(2)) & (p[:, 0] >= 0) & \
        (p[:, 1] >= 0) & (p.sum(axis=1) <= 1)
    assert G._test_clip(sq, tri) == pytest.approx(4 * inside.mean(), abs=0.01)
