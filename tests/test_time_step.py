"""The default Courant number is stable: the exact stability limit of the linearised scheme
(the eigenvalues of its Jacobian, against the stability region of the two-stage Runge-Kutta
scheme) lies above cfl 0.4 in 2D and 3D, on structured and unstructured meshes, for order 1
and order 2 (docs/theory.md, "Time")."""

import numpy as np
import pytest

from impactfv import load_case
from impactfv.scheme.stepper import FVStepper

MATERIAL = {"name": "c", "model": "linear_elastic", "density": 8930.0,
            "youngs_modulus": 585e6, "poisson_ratio": 0.495}


def stepper(mesh, order, dim):
    case = {"run": {"end_time": 1e-5, "order": order, "limiter": "none"},
            "material": [MATERIAL],
            "body": [{"name": "b", "material": "c", "velocity": [0.0] * dim, "mesh": mesh}]}
    return FVStepper(load_case(case))


def jacobian(st):
    """d(rates)/d(v, F) at rest, by finite differences (the scheme is linear there)."""
    m = st.disc
    n, d = m.n_nodes, m.dim
    rho = m.material_table[0, 0]

    def rates(u):
        st.v[:] = u[:n * d].reshape(n, d)
        st.F[:] = u[n * d:].reshape(n, d, d)
        st.rates(0)
        return np.concatenate([(st.force / (rho * m.volume[:, None])).ravel(),
                               (st.dF / m.volume[:, None, None]).ravel()])

    u0 = np.concatenate([np.zeros(n * d), np.tile(np.eye(d).ravel(), n)])
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
    """Measured limits: triangles 0.418 / 0.495, box 0.445 / 0.501, gmsh (353 nodes)
    0.456 / 0.551, gmsh (107 nodes) 0.449 / 0.526, gmsh (62 nodes, the test) 0.460 / 0.561
    (order 1 / order 2). No mode grows at any time step."""
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
