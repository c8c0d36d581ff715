"""The default Courant number is stable: the exact stability limit of the linearised scheme
(the eigenvalues of its Jacobian, against the stability region of the two-stage Runge-Kutta
scheme) lies above cfl 0.4 in 2D and 3D, on structured and unstructured meshes, for order 1
and order 2 (docs/theory.md, "Time"); and under compression the upwind geometric flux grows a
family of grid-scale modes that the central one has not (docs/theory.md, "Stability under
compression")."""

import numpy as np
import pytest

from impactfv import load_case
from impactfv.physics.materials import CP
from impactfv.scheme.stepper import FVStepper

MATERIAL = {"name": "c", "model": "linear_elastic", "density": 8930.0,
            "youngs_modulus": 585e6, "poisson_ratio": 0.495}


def stepper(mesh, order, dim):
    case = {"run": {"end_time": 1e-5, "order": order, "limiter": "none"},
            "material": [MATERIAL],
            "body": [{"name": "b", "material": "c", "velocity": [0.0] * dim, "mesh": mesh}]}
    return FVStepper(load_case(case))


def jacobian(st, F0=None):
    """d(rates)/d(v, F) at rest with the uniform deformation F0 (default the identity), by
    finite differences."""
    m = st.disc
    n, d = m.n_nodes, m.dim
    rho = m.material_table[0, 0]
    F0 = np.eye(d) if F0 is None else F0

    def rates(u):
        st.v[:] = u[:n * d].reshape(n, d)
        st.F[:] = u[n * d:].reshape(n, d, d)
        st.rates(0)
        return np.concatenate([(st.force / (rho * m.volume[:, None])).ravel(),
                               (st.dF / m.volume[:, None, None]).ravel()])

    u0 = np.concatenate([np.zeros(n * d), np.tile(F0.ravel(), n)])
    r0 = rates(u0.copy())
    J = np.empty((len(u0), len(u0)))
    for k in range(len(u0)):
        u = u0.copy()
        u[k] += 1e-7
        J[:, k] = (rates(u) - r0) / 1e-7
    return J


def stable_cfl(st, growing=None):
    """Largest cfl for which every dt lambda lies in |1 + z + z^2 / 2| <= 1. With a list
    ``growing``, the modes that grow at any time step (Re lambda > 0) are left out of the
    search and their largest Re(lambda) dt at the default cfl is appended to it."""
    lam = np.linalg.eigvals(jacobian(st))
    # rigid-body and other neutral modes (|lambda| at round-off level)
    lam = lam[np.abs(lam) > 1e-6 * np.abs(lam).max()]
    dt_of_cfl = st.stable_dt() / st.cfl
    if growing is not None:
        rising = lam.real * st.stable_dt() > 1e-8
        growing.append((lam.real[rising] * st.stable_dt()).max(initial=0.0))
        lam = lam[~rising]
    lo, hi = 0.0, 4.0
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        z = mid * dt_of_cfl * lam
        if np.all(np.abs(1 + z + z * z / 2) <= 1 + 1e-12):
            lo = mid
        else:
            hi = mid
    return lo


def gmsh_box(tmp_path):
    gmsh = pytest.importorskip("gmsh")
    path = tmp_path / "box.msh"
    gmsh.initialize(["", "-v", "0"])
    try:
        gmsh.model.add("box")
        gmsh.model.occ.addBox(0, 0, 0, 0.004, 0.002, 0.002)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [1], name="solid")
        gmsh.option.setNumber("Mesh.MeshSizeMin", 0.0012)
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.0012)
        gmsh.model.mesh.generate(3)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return {"file": str(path)}


RECTANGLE = {"generator": "rectangle", "origin": [0, 0], "size": [0.004, 0.002],
             "divisions": [16, 8], "pattern": "alternate"}
BOX = {"generator": "box", "origin": [0, 0, 0], "size": [0.004, 0.002, 0.002],
       "divisions": [6, 3, 3]}


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("mesh,dim", [(RECTANGLE, 2), (BOX, 3), ("gmsh", 3)],
                         ids=["triangles", "box", "gmsh tetrahedra"])
def test_default_courant_number_is_below_the_stability_limit(tmp_path, mesh, dim, order):
    """Measured limits with the defaults (the compatibility relaxation on): triangles
    0.414 / 0.489, box 0.442 / 0.497 (order 1 / order 2). Without the relaxation: triangles 0.418 / 0.495, box 0.445 / 0.501, gmsh (353 nodes) 0.456 / 0.551,
    gmsh (107 nodes) 0.449 / 0.526, gmsh (62 nodes, the test) 0.460 / 0.561. No mode grows
    at any time step."""
    if mesh == "gmsh":
        mesh = gmsh_box(tmp_path)
    growing = []
    limit = stable_cfl(stepper(mesh, order, dim), growing)
    assert 0.4 < limit < 1.0, limit
    assert growing[0] == 0.0, growing


def test_normal_only_boundary_correction_leaves_growing_modes_on_tetrahedra(tmp_path):
    """Why 3D takes the full boundary correction by default (docs/theory.md, "Boundaries"):
    with the normal part only, the 62-node gmsh box at order 2 has modes that grow at any
    time step (measured Re(lambda) dt = 1.0e-5 at the default cfl), from the free faces'
    tangential components that nothing damps; the 2D disc (61 nodes) has none."""
    def growth(mesh, dim):
        case = {"run": {"end_time": 1e-5, "order": 2, "limiter": "none",
                        "boundary_correction": "normal"},
                "material": [MATERIAL],
                "body": [{"name": "b", "material": "c", "velocity": [0.0] * dim,
                          "mesh": mesh}]}
        growing = []
        stable_cfl(FVStepper(load_case(case)), growing)
        return growing[0]

    assert 1e-7 < growth(gmsh_box(tmp_path), 3) < 1e-3
    assert growth({"generator": "disc", "centre": [0, 0], "radius": 0.002, "rings": 4}, 2) == 0


def prestressed_block(geometric, stretch, compatibility_time=0.0, dim=2):
    """A free 4 x 2 mm block (4 x 2 x 2 mm in 3D) of the seed material (neo-Hookean,
    nu = 0.495), 8 x 4 cells (6 x 3 x 3 boxes in 3D), stretched uniformly along x by
    F11 = ``stretch`` with the other diagonal entries such that the lateral stresses are
    zero, and held in that state by the dead loads P N on its sides (an exact equilibrium
    of the scheme). Returns its stepper, F and sigma."""
    from conftest import COPPER

    from impactfv.physics.materials import Material, cauchy_stress

    props = np.array(Material.from_entry(COPPER).table_row())

    def stress(F22):
        sigma = np.zeros((dim, dim))
        cauchy_stress(np.diag([stretch] + [F22] * (dim - 1)), props, sigma)
        return sigma

    lo, hi = 0.5, 2.0
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if stress(mid)[1, 1] > 0 else (mid, hi)
    F0 = np.diag([stretch] + [0.5 * (lo + hi)] * (dim - 1))
    sigma = stress(F0[1, 1])
    P = np.linalg.det(F0) * sigma @ np.linalg.inv(F0).T
    sides = {f"{c}{end}": sign * np.eye(dim)[k] for k, c in enumerate("xyz"[:dim])
             for end, sign in (("min", -1.0), ("max", 1.0))}
    mesh = ({"generator": "rectangle", "origin": [0, 0], "size": [0.004, 0.002],
             "divisions": [8, 4]} if dim == 2 else
            {"generator": "box", "origin": [0, 0, 0], "size": [0.004, 0.002, 0.002],
             "divisions": [6, 3, 3]})
    case = {"run": {"end_time": 1e-5, "order": 2, "limiter": "none",
                    "geometric_flux": geometric, "compatibility_time": compatibility_time},
            "material": [COPPER],
            "body": [{"name": "b", "material": COPPER["name"], "velocity": [0.0] * dim,
                      "mesh": mesh,
                      "boundary": [{"region": r, "traction": (P @ N).tolist()}
                                   for r, N in sides.items()]}]}
    return FVStepper(load_case(case)), F0, sigma


def rigid_rotation_rate(st, F0, sigma):
    """Growth rate sqrt(12 |sigma11| / (rho (L^2 + t^2))) of the rigid rotation of the
    prestressed block (compressed along x by its dead loads) in a plane containing x, with
    L and t its current length and thickness."""
    rho = st.disc.material_table[0, 0]
    length, thickness = 0.004 * F0[0, 0], 0.002 * F0[1, 1]
    return np.sqrt(12 * -sigma[0, 0] / (rho * (length ** 2 + thickness ** 2)))


@pytest.mark.parametrize("geometric", ["upwind", "central"])
def test_compression_makes_the_upwind_geometric_flux_grow_a_mode_per_node(geometric):
    """Why compressed free surfaces wrinkle at h = 0.1 mm (docs/theory.md, "Stability under
    compression"). Linearised about a block compressed to F11 = 0.9 (sigma11 = -82 MPa, held
    by dead loads), both fluxes have the physical instability of a free body under compressive
    dead loads, a rigid rotation growing at sqrt(12 |sigma11| / (rho (L^2 + t^2))) (measured
    8.2e4 /s against 7.9e4 /s of that rigid-body estimate). The central flux has nothing else
    growing faster than 1e-4 per step (measured 4.9e-5), the upwind flux a family of about one
    mode per node (36 growing of 45 nodes, 25 faster than 1e-4 per step; the same per step on
    16 x 8 and 24 x 12 cells, so that a finer mesh folds sooner in time). In tension nothing
    grows with either flux."""
    st, F0, sigma = prestressed_block(geometric, 0.9)
    lam = np.sort(np.linalg.eigvals(jacobian(st, F0)).real)[::-1]
    dt = st.stable_dt()
    rotation = rigid_rotation_rate(st, F0, sigma)
    assert lam[0] == pytest.approx(rotation, rel=0.1)
    fast = int(np.sum(lam[1:] * dt > 1e-4))
    if geometric == "central":
        assert fast == 0
    else:
        assert fast >= st.disc.n_nodes // 3
    st, F0, sigma = prestressed_block(geometric, 1.05)
    assert sigma[0, 0] > 0
    assert np.max(np.linalg.eigvals(jacobian(st, F0)).real) * st.stable_dt() < 1e-7


def jacobian_with_positions(st, F0):
    """d(rates)/d(v, F, x) at rest in the uniform state F0, x = F0 X, by finite differences:
    the rates of F depend on the positions when F is relaxed towards their gradient."""
    m = st.disc
    n, d = m.n_nodes, m.dim
    rho = m.material_table[0, 0]

    def rates(u):
        st.v[:] = u[:n * d].reshape(n, d)
        st.F[:] = u[n * d:n * d * (d + 1)].reshape(n, d, d)
        st.x[:] = u[n * d * (d + 1):].reshape(n, d)
        st.rates(0)
        return np.concatenate([(st.force / (rho * m.volume[:, None])).ravel(),
                               (st.dF / m.volume[:, None, None]).ravel(), st.v.ravel()])

    u0 = np.concatenate([np.zeros(n * d), np.tile(F0.ravel(), n), (m.X @ F0.T).ravel()])
    r0 = rates(u0.copy())
    J = np.empty((len(u0), len(u0)))
    for k in range(len(u0)):
        u = u0.copy()
        step = 1e-7 if k < n * d * (d + 1) else 1e-10     # F is O(1), x O(1 mm)
        u[k] += step
        J[:, k] = (rates(u) - r0) / step
    return J


@pytest.mark.parametrize("compatibility_time", [0.0, 30.0, 100.0])
def test_compatibility_relaxation_removes_the_compression_modes(compatibility_time):
    """F relaxed towards the Green-Gauss gradient of the positions (run.compatibility_time,
    docs/theory.md, "Compatibility relaxation"): linearised about the block compressed to
    F11 = 0.9 (as above, positions now part of the state), the upwind flux's family of
    incompatible rotations is gone and only the physical rigid rotation under dead loads
    grows (measured: nothing else above 0 at 30 and 100 transit times, with the grid-scale
    part of the mismatch relaxed as with all of it; at 300, 8 modes grow up to 3.0e-4 per
    step; without the relaxation 36 modes grow, the fastest at 1.1e-3 per step; without
    the edges that touch a boundary node, 21 grow at 30). The
    relaxation leaves the uniform compressed state an exact equilibrium, and nothing grows
    in tension."""
    st, F0, sigma = prestressed_block("upwind", 0.9, compatibility_time)
    J = jacobian_with_positions(st, F0)
    m = st.disc
    st.v[:] = 0.0
    st.F[:] = F0
    st.x[:] = m.X @ F0.T
    st.rates(0)
    cp, h = m.material_table[0, CP], m.node_length.min()
    assert np.abs(st.dF / m.volume[:, None, None]).max() < 1e-9 * cp / h
    lam = np.sort(np.linalg.eigvals(J).real)[::-1]
    dt = st.stable_dt()
    rotation = rigid_rotation_rate(st, F0, sigma)
    assert lam[0] == pytest.approx(rotation, rel=0.1)
    growing = int(np.sum(lam[1:] * dt > 1e-6))
    if compatibility_time == 0.0:
        assert growing >= m.n_nodes // 3
    else:
        assert growing == 0
        st, F0, sigma = prestressed_block("upwind", 1.05, compatibility_time)
        assert np.max(np.linalg.eigvals(jacobian_with_positions(st, F0)).real) \
            * st.stable_dt() < 1e-7


def test_compatibility_relaxation_does_no_work_under_a_uniform_stress():
    """The relaxation's edge weights are symmetric (docs/theory.md, "Compatibility
    relaxation"), so its strain power sum_a P_a : (Omega_a dF_a/dt) is a sum over edges of
    w_ab (P_a - P_b) : (D_a - D_b): zero, to round-off, for a uniform stress however far the
    positions are from F; it moves F only where F and the positions disagree from node to
    node, and leaves a uniform mismatch alone."""
    st, F0, sigma = prestressed_block("upwind", 0.9, 30.0)
    m = st.disc
    P = np.linalg.det(F0) * sigma @ np.linalg.inv(F0).T
    st.F[:] = F0
    st.x[:] = m.X @ F0.T + 2e-5 * np.random.default_rng(3).standard_normal(m.X.shape)
    st.dF[:] = 0.0
    st._relax_towards_positions()
    change = np.abs(st.dF).max()
    assert change > 0.0
    assert abs(np.einsum("ij,aij->", P, st.dF)) < 1e-12 * np.abs(P).max() * np.abs(st.dF).sum()
    # a uniform mismatch (here a uniform F against positions that did not move) is left alone
    st.x[:] = m.X
    st.dF[:] = 0.0
    st._relax_towards_positions()
    assert np.abs(st.dF).max() < 1e-12 * change


@pytest.mark.parametrize("dim", [2, 3])
def test_the_gradient_pass_gives_the_relaxation_the_mismatch_of_f_and_the_positions(dim):
    """At order 2 the gradient pass of the reconstructed fields also writes the relaxation's
    mismatch D = F - G(x) (backends.cpu.limited_gradient, with_positions). For positions that are
    a linear map of the reference ones, x = A X + b, the Green-Gauss gradient is A exactly, so
    D = F - A at every node, boundary nodes included; for any positions D equals what the
    positions-only pass (order 1) gives."""
    st, F0, sigma = prestressed_block("upwind", 0.9, 30.0, dim=dim)
    m = st.disc
    rng = np.random.default_rng(7)
    A = np.eye(dim) + 0.1 * rng.standard_normal((dim, dim))
    st.F[:] = F0 + 1e-3 * rng.standard_normal(st.F.shape)
    st.x[:] = m.X @ A.T + 1e-3
    st.state_changed()
    st.rates()
    assert np.abs(st.mismatch - (st.F - A)).max() < 1e-12
    st.x[:] += 2e-5 * rng.standard_normal(m.X.shape)
    st.state_changed()
    st.rates()
    fused = st.mismatch.copy()
    st.mismatch[:] = 0.0
    st._relax_towards_positions()            # the positions-only pass
    assert np.abs(fused - (st.F - A)).max() > 1e-3     # the positions are no longer linear
    assert np.abs(st.mismatch - fused).max() <= 1e-15 * np.abs(fused).max()


@pytest.mark.parametrize("compatibility_time", [0.0, 30.0])
def test_compatibility_relaxation_removes_the_compression_modes_in_3d(compatibility_time):
    """The same in 3D (6 x 3 x 3 boxes of tetrahedra, F11 = 0.9, sigma11 = -59 MPa, the full
    boundary correction of 3D): without the relaxation about two growing modes per node
    (measured 205 on 112 nodes, the fastest after the rigid rotations 1.2e-3 per step); with
    it at 30 transit times only the two rigid rotations under dead loads, about y and z, at
    the rigid-block rate (at 100, three more grow, up to 5.5e-4 per step)."""
    st, F0, sigma = prestressed_block("upwind", 0.9, compatibility_time, dim=3)
    lam = np.sort(np.linalg.eigvals(jacobian_with_positions(st, F0)).real)[::-1]
    dt = st.stable_dt()
    rotation = rigid_rotation_rate(st, F0, sigma)
    assert lam[:2] == pytest.approx([rotation, rotation], rel=0.1)
    growing = int(np.sum(lam[2:] * dt > 1e-6))
    if compatibility_time == 0.0:
        assert growing >= st.disc.n_nodes
    else:
        assert growing == 0
