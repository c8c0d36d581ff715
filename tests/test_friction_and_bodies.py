"""Coulomb friction in the contact Riemann solver, contacts among several bodies, and
self-contact (docs/contact.md): against Coulomb's law, Newton's cradle and conservation."""

import meshio
import numpy as np
import pytest
from conftest import COPPER, COPPER_03, SOFT

from impactfv import InputError, load_case, run
from impactfv.contact.driver import SELF_CONTACT_DEEPEST
from impactfv.contact.overlap import contact_pieces
from impactfv.contact.search import Bins
from impactfv.geometry.bins import build_bins
from impactfv.mesh.dual import median_dual
from impactfv.mesh.generators import rectangle
from impactfv.scheme.stepper import FVStepper


def oblique_block(model, friction=None, end_time=3e-5):
    """A 2 mm copper block hitting a wall below it at 10 m/s with 20 m/s along it."""
    contact = {"bodies": ["block"], "model": model,
               "wall": {"point": [0.0, 0.0], "normal": [0.0, 1.0]}}
    if friction is not None:
        contact["friction"] = friction
    return {"run": {"end_time": end_time},
            "material": [dict(COPPER_03)],
            "body": [{"name": "block", "material": COPPER_03["name"], "velocity": [20.0, -10.0],
                      "mesh": {"generator": "rectangle", "origin": [0.0, 2e-5],
                               "size": [0.002, 0.002], "divisions": [20, 20]}}],
            "contact": [contact]}


def impulses(history):
    dt = history["dt"]
    return np.sum(history["contact0_fx"] * dt), np.sum(history["contact0_fy"] * dt)


@pytest.mark.parametrize("mu", [0.1, 0.25])
def test_sliding_impact_obeys_coulombs_law(mu):
    """The block slides all through the impact: the tangential impulse is mu times the
    normal one (measured: mu to five digits)."""
    h = run(load_case(oblique_block("coulomb", mu))).history
    tangential, normal = impulses(h)
    assert normal > 0 and tangential < 0
    assert -tangential / normal == pytest.approx(mu, rel=0.03)
    assert h["contact0_fy"][-1] == 0.0                               # it bounced off
    E = h["total_energy"]
    assert np.all(np.diff(E) <= 1e-12 * E[0])


@pytest.mark.parametrize("limit,mu", [("stick", 1e6), ("slip", 0.0)])
def test_coulomb_friction_has_stick_and_slip_as_its_limits(limit, mu):
    a = run(load_case(oblique_block("coulomb", mu))).history
    b = run(load_case(oblique_block(limit))).history
    for key in ("contact0_fx", "contact0_fy", "momentum_x", "total_energy"):
        assert np.array_equal(a[key], b[key]), key


def test_a_block_sliding_under_gravity_decelerates_at_mu_g():
    """A soft block put on a wall at 1 m/s under a strong gravity g = 1000 m/s^2 slows down
    at mu g (measured: 0.977 mu g with mu = 0.2, once the first ringing has passed)."""
    mu, g, H, W = 0.2, 1000.0, 0.01, 0.02
    case = {"run": {"end_time": 0.004},
            "material": [dict(SOFT)],
            "body": [{"name": "block", "material": "soft", "velocity": [1.0, 0.0],
                      "body_force": [0.0, -g],
                      "mesh": {"generator": "rectangle", "origin": [0.0, 0.0],
                               "size": [W, H], "divisions": [12, 6]}}],
            "contact": [{"bodies": ["block"], "model": "coulomb", "friction": mu,
                         "wall": {"point": [0.0, 0.0], "normal": [0.0, 1.0]}}]}
    h = run(load_case(case)).history
    M = SOFT["density"] * W * H
    t, vx = h["time"], h["momentum_x"] / M
    sliding = (t > 0.001) & (t < 0.0035)
    deceleration = -np.polyfit(t[sliding], vx[sliding], 1)[0]
    assert deceleration == pytest.approx(mu * g, rel=0.03)


def cradle(bars=3, nx=100, v0=10.0):
    """Newton's cradle: identical roller-sided bars in a row, the first flying at the others
    (which touch each other) at v0; every pair of them may touch ("all")."""
    L, W = 0.01, 0.001
    bodies, x = [], 0.0
    for k in range(bars):
        bodies.append({"name": f"bar{k}", "material": "copper",
                       "velocity": [v0 if k == 0 else 0.0, 0.0],
                       "mesh": {"generator": "rectangle", "origin": [x, 0.0], "size": [L, W],
                                "divisions": [nx, nx // 10]},
                       "boundary": [{"region": "ymin", "velocity": {"y": 0.0}},
                                    {"region": "ymax", "velocity": {"y": 0.0}}]})
        x += L + (1e-4 if k == 0 else 0.0)
    c = 1487.6
    end = 1e-4 / v0 + (bars + 1.5) * 2 * L / c
    return {"run": {"end_time": end}, "material": [dict(COPPER)], "body": bodies,
            "contact": [{"bodies": "all", "model": "slip"}]}


def mean_velocity(body):
    omega = median_dual(body["reference_points"], body["cells"]).volumes
    return (omega[:, None] * body["velocity"]).sum(axis=0) / omega.sum()


def test_newtons_cradle():
    """Three bars: the pulse runs through the two that touch, the last one leaves at v0 and
    the others stay behind (measured: 0.985 v0; the first 0.000, the middle 0.015 v0)."""
    v0 = 10.0
    result = run(load_case(cradle(v0=v0)))
    h = result.history
    assert [c for c in h if c.startswith("contact") and c.endswith("_fx")] == \
        ["contact0_fx", "contact1_fx", "contact2_fx"]
    velocities = [mean_velocity(result.bodies[f"bar{k}"])[0] for k in range(3)]
    assert velocities[2] == pytest.approx(v0, rel=0.03)
    assert abs(velocities[0]) < 0.03 * v0 and abs(velocities[1]) < 0.03 * v0
    M = COPPER["density"] * 0.01 * 0.001
    assert np.abs(h["momentum_x"] - h["momentum_x"][0]).max() < 1e-12 * M * v0
    for k in (0, 2):                                   # the pairs that touch
        assert np.nanmin(h[f"contact{k}_gap"]) > -0.01 * 1e-4
    assert np.all(np.isnan(h["contact1_gap"]))        # bar0 and bar2 never come near


def u_shaped_body(tmp_path, h=1e-4):
    """A 4 x 4 mm block cut by a slit two cells wide from its top down to 1 mm: two arms on
    a base, written as a .vtu mesh file."""
    mesh = rectangle((0.0, 0.0), (40 * h, 40 * h), (40, 40), "alternate")
    centroid = mesh.points[mesh.cells].mean(axis=1)
    keep = ~((centroid[:, 0] > 19 * h) & (centroid[:, 0] < 21 * h) & (centroid[:, 1] > 10 * h))
    cells = mesh.cells[keep]
    used = np.unique(cells)
    index = np.full(len(mesh.points), -1)
    index[used] = np.arange(len(used))
    path = tmp_path / "u.vtu"
    points = np.column_stack([mesh.points[used], np.zeros(len(used))])
    meshio.write(path, meshio.Mesh(points, [("triangle", index[cells])]))
    return path


def test_self_contact_closes_a_slit_without_penetration(tmp_path):
    """The arms of a U-shaped body swing at each other and close its slit: the body touches
    itself, nothing passes through (measured: the smallest gap +6e-5 h), the arms bounce
    back, and its momentum stays exactly what it was (self-contact is internal)."""
    h = 1e-4
    case = {"run": {"end_time": 8e-5},
            "material": [dict(COPPER_03)],
            "body": [{"name": "u", "material": COPPER_03["name"],
                      "velocity": ["10*tanh((0.002 - x)/0.0003)*heaviside(y - 0.001)", "0.0"],
                      "mesh": {"file": str(u_shaped_body(tmp_path, h))}}],
            "contact": [{"bodies": ["u"], "self": True, "model": "slip"}]}
    result = run(load_case(case))
    hist = result.history
    touching = np.flatnonzero(np.abs(hist["contact0_fx"]) > 0)
    assert len(touching) and touching[-1] < len(hist["time"]) - 10   # touched, let go
    assert np.nanmin(hist["contact0_gap"]) > -0.01 * h
    for key in ("momentum_x", "momentum_y"):
        assert np.abs(hist[key]).max() < 1e-13
    E = hist["total_energy"]
    assert np.all(np.diff(E) <= 1e-12 * E[0])
    body = result.bodies["u"]
    p = body["points"][body["triangles"]]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    assert (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).min() > 0


def crushed_ring(wall, cells):
    """A heavy disc (radius 4 mm, rho = 8000, E = 500 MPa) at 1.5 m/s onto the top of a soft
    ring (radius 10 mm, E = 5 MPa, nu = 0.45, rho = 1000) lying on a floor wall; slip
    everywhere: the floor (contact 0), disc and ring (1), the ring with itself (2)."""
    radius, gap = 10e-3, 0.05e-3
    return {"run": {"end_time": 16e-3, "output_interval": 16e-3},
            "material": [{"name": "rubber", "model": "neo_hookean", "density": 1000.0,
                          "youngs_modulus": 5e6, "poisson_ratio": 0.45},
                         {"name": "heavy", "model": "neo_hookean", "density": 8000.0,
                          "youngs_modulus": 500e6, "poisson_ratio": 0.3}],
            "body": [{"name": "ring", "material": "rubber",
                      "mesh": {"generator": "annulus", "centre": [0.0, 0.0], "radius": radius,
                               "inner_radius": radius - wall, "rings": cells}},
                     {"name": "disc", "material": "heavy", "velocity": [0.0, -1.5],
                      "mesh": {"generator": "disc", "centre": [0.0, radius + 4e-3 + gap],
                               "radius": 4e-3, "rings": 8}}],
            "contact": [{"bodies": ["ring"], "model": "slip",
                         "wall": {"point": [0.0, -radius - gap], "normal": [0.0, 1.0]}},
                        {"bodies": ["disc", "ring"], "model": "slip"},
                        {"bodies": ["ring"], "self": True, "model": "slip"}]}


@pytest.mark.parametrize("wall, cells", [(0.6e-3, 2),
                                         pytest.param(0.5e-3, 3, marks=pytest.mark.slow)])
def test_a_ring_crushed_until_its_inner_faces_touch(wall, cells):
    """Issue 13's self-contact case: the disc flattens the ring against the floor until the
    ring's inner faces touch (at about 13.5 ms) and press on each other. No contact
    penetrates by more than 1% of the ring's cell size h = wall / cells (measured, floor /
    disc / self: -0.31% / none / none of h with 2 cells, -0.02% / none / -0.68% with 3), no
    triangle turns inside out, and the energy balance column stays at its start to 1e-5 of
    the energy (measured 2e-6 and 3e-6). The balance holds only with Heun's energy excess
    taken with the material's elasticity at the node's state: with the small-strain one it
    is off by 20% and 26% of the energy, as Barth-Jespersen's factor switches between the
    Runge-Kutta stages on the ring's bending waves and the integration column reaches the
    size of the energy (docs/contact.md, "Known limitations"). The 3-cell wall is
    a slow test (about 3 minutes)."""
    result = run(load_case(crushed_ring(wall, cells)))
    h, cell = result.history, wall / cells
    self_force = np.hypot(h["contact2_fx"], h["contact2_fy"])
    touching = np.flatnonzero(self_force > 0.0)
    assert len(touching) and h["time"][touching[0]] > 10e-3        # the inner faces touch
    for k in range(3):
        assert np.nanmin(h[f"contact{k}_gap"]) > -0.01 * cell
    E0 = h["total_energy"][0]
    balance = h["energy_balance"]
    assert np.abs(balance - balance[0]).max() < 1e-5 * E0
    assert h["integration_energy"][-1] > 0.1 * E0     # the stages' rates do differ a lot
    ring = result.bodies["ring"]
    p = ring["points"][ring["triangles"]]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    assert (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).min() > 0


THIN_WALLS = {
    # a ring, wall 0.3 mm in one cell, facets about 0.3 mm long
    "ring": ({"generator": "annulus", "centre": [0.0, 0.0], "radius": 10e-3,
              "inner_radius": 9.7e-3, "rings": 1}, ["-100*y", "100*x"]),
    # a strip 0.3 mm thick in one cell, facets 1 mm long (over three times the wall)
    "strip": ({"generator": "rectangle", "origin": [-10e-3, -0.15e-3], "size": [20e-3, 0.3e-3],
               "divisions": [20, 1]}, ["-100*y", "100*x"]),
    # the same as a 3D plate
    "plate": ({"generator": "box", "origin": [-5e-3, -5e-3, -0.15e-3],
               "size": [10e-3, 10e-3, 0.3e-3], "divisions": [10, 10, 1]},
              ["-100*y", "100*x", "0"]),
}


@pytest.mark.parametrize("shape", list(THIN_WALLS))
def test_self_contact_does_not_take_the_far_side_of_a_thin_wall_for_a_partner(shape):
    """A body with a wall 0.3 mm thin, one cell through it, spins freely with self-contact
    on. Its far face lies behind its near face, facing it, within the search radius (two
    facet lengths): a partner by every other rule. Nothing may touch: no gap is measured, no
    contact force acts, and the run equals the same run without self-contact to round-off.
    Taken for a partner, the far side gave gaps of -1.0 of the wall and pressed the wall
    together: 1.3% (ring), 16% (strip) and 26% (plate) of the energy lost in the 0.1 ms of
    the run, against 1e-8, 0.33% and 0.81% without self-contact (search.closest_facet,
    ``deepest``)."""
    mesh, velocity = THIN_WALLS[shape]
    def case(contact):
        return {"run": {"end_time": 1e-4}, "material": [dict(SOFT)],
                "body": [{"name": "thin", "material": SOFT["name"], "velocity": velocity,
                          "mesh": mesh}],
                "contact": contact}
    h = run(load_case(case([{"bodies": ["thin"], "self": True, "model": "slip"}]))).history
    alone = run(load_case(case([]))).history
    assert np.all(np.isnan(h["contact0_gap"]))
    assert all(np.all(h[k] == 0.0) for k in h if k.startswith("contact0_f"))
    assert np.allclose(h["total_energy"], alone["total_energy"], rtol=1e-12, atol=0.0)


@pytest.mark.parametrize("shape", ["strip", "plate"])
def test_contact_pieces_do_not_reach_across_a_thin_wall(shape):
    """A node remembered in contact whose gap has opened (a remembered node stays in contact
    until its contact would be tensile) builds pieces against every facing facet within its
    partner's distance plus its face. In a self-contact that reach took in the body's own
    far side across a thin wall: in a ring crushed by a disc, the inner face's nodes, 2.5 h
    from the face they had touched, pressed the outer face into the floor wall (3.4% of h).
    The pieces obey the search's rule (search.across_own_wall). Here the middle node of the
    top face of a 0.3 mm strip (or plate) is given a partner 1 mm away: without the rule its
    face overlaps the bottom face's facets, with it no piece is built."""
    mesh, _ = THIN_WALLS[shape]
    case = {"run": {"end_time": 1e-4}, "material": [dict(SOFT)],
            "body": [{"name": "thin", "material": SOFT["name"], "velocity": [0.0] * len(
                mesh["origin"]), "mesh": mesh}],
            "contact": [{"bodies": ["thin"], "self": True, "model": "slip"}]}
    stepper = FVStepper(load_case(case))
    contact, x, X = stepper.contact, stepper.x, stepper.disc.X
    pair = contact.pairs[0]
    facets = pair.surfaces[0].facets
    d = x.shape[1]
    top = X[:, d - 1] > 0.0
    a = np.flatnonzero(top)[np.argmin(np.linalg.norm(X[top, :d - 1], axis=1))]
    up = np.zeros(d)
    up[d - 1] = 1.0
    contact.normal[a] = up
    contact.partner[:] = -1
    contact.partner[a] = 0
    contact.partner_dist[a] = 1e-3
    phi = np.zeros(len(x))
    phi[a] = 1.0
    bins = build_bins(x, facets, contact.pad)

    def pieces_of_a(deepest):
        count = contact_pieces(x, contact.disc_arrays, pair.surfaces[0].nodes, contact.found,
                               phi, contact.contact_faces, contact.straightness, facets,
                               Bins(*bins), contact.pieces, pair.skip, contact.pad, deepest)
        assert count <= len(contact.piece_node)
        return np.count_nonzero(contact.piece_node[:count] == a)

    assert pieces_of_a(0.0) > 0
    assert pieces_of_a(SELF_CONTACT_DEEPEST) == 0


@pytest.mark.parametrize("contact,message", [
    ({"bodies": ["a"], "model": "coulomb"}, "needs friction"),
    ({"bodies": ["a", "b"], "model": "slip", "friction": 0.2}, "coulomb"),
    ({"bodies": ["a", "b"], "model": "coulomb", "friction": -0.1}, "greater than or equal"),
    ({"bodies": ["a", "b"], "self": True}, "self = true takes exactly one body"),
    ({"bodies": "all", "wall": {"point": [0.0, 0.0], "normal": [1.0, 0.0]}}, "several"),
])
def test_bad_contact_entries_are_input_errors(contact, message):
    bodies = [{"name": n, "material": "copper", "velocity": [0.0, 0.0],
               "mesh": {"generator": "rectangle", "origin": [x, 0.0], "size": [0.001, 0.001],
                        "divisions": [2, 2]}} for n, x in (("a", 0.0), ("b", 0.002))]
    case = {"run": {"end_time": 1e-6}, "material": [dict(COPPER)], "body": bodies,
            "contact": [contact]}
    with pytest.raises(InputError, match=message):
        load_case(case)


def test_friction_hands_momentum_down_a_stack():
    """examples/stack_impact.toml: a disc strikes a stack of three blocks obliquely, Coulomb
    friction at every interface and on the floor. Each interface passes on less of the
    disc's tangential momentum (measured at 400 us: 5.4, 2.4, 0.5 m/s from the top down),
    the energy never rises, and no node sinks deeper than 3% of a cell into a partner
    (measured 1.1%, where a corner presses into a face: docs/contact.md, "Known
    limitations"; 2.4% without the compatibility relaxation)."""
    from pathlib import Path
    path = Path(__file__).resolve().parents[1] / "examples" / "stack_impact.toml"
    result = run(load_case(path))
    h, bodies = result.history, result.bodies
    along = {name: b["velocity"][:, 0].mean() for name, b in bodies.items()}
    assert along["top"] > along["middle"] > along["bottom"] > 0
    assert along["disc"] < 30.0
    E = h["total_energy"]
    assert np.all(np.diff(E) <= 1e-12 * E[0])
    cell = 12e-3 / 36
    gaps = [np.nanmin(h[k]) for k in h if k.endswith("_gap") and np.isfinite(h[k]).any()]
    assert min(gaps) > -0.03 * cell
