"""One explicit central-difference (velocity Verlet) step of the FE baselines, compiled.

The step takes its arrays in bundles: the nodal :class:`State` (written in place), the
constant :class:`NodeData`, the mesh's :class:`~impactfv.fem.elements.Elements` and the
contact's :class:`~impactfv.fem.contact.ContactPasses` and
:class:`~impactfv.fem.contact.ContactWork`.
"""

from collections import namedtuple

from numba import njit

from .contact import contact_correct
from .elements import internal_forces

#: the nodal state, all (N,2) and updated in place by :func:`step`: positions ``x``,
#: velocities ``v``, accelerations ``acc`` and internal forces ``f``
State = namedtuple("State", ["x", "v", "acc", "f"])

#: constant nodal data: lumped mass ``mass (N,)``, inverse mass per component ``minv (N,2)``
#: (0 where the component is prescribed), prescribed components ``fmask (N,2)`` and their
#: velocities ``fval (N,2)``
NodeData = namedtuple("NodeData", ["mass", "minv", "fmask", "fval"])


@njit(cache=True)
def step(state, nodes, elements, passes, work, cforce, cgap, dt, maxit, tol):
    """One velocity-Verlet (central-difference) step with kinematic contact.

    v_{n+1/2} = v_n + dt/2 a_n; contact correction of v_{n+1/2} so that x_n + dt v_{n+1/2}
    does not penetrate; x_{n+1} = x_n + dt v_{n+1/2}; a_{n+1} = -M^-1 f_int(x_{n+1});
    v_{n+1} = v_{n+1/2} + dt/2 a_{n+1}.  Prescribed components are reset each half step.
    ``cforce``, ``cgap``, ``maxit`` and ``tol`` are those of :func:`contact_correct`.

    Returns (strain energy, kinetic energy, px, py, energy change by the contact, dt limit
    ratio, min J, number of contact constraints), all at t_{n+1}.
    """
    x, v, acc, f = state
    hdt = 0.5 * dt
    half_kick(v, acc, nodes, hdt)
    dke, ncons = contact_correct(x, v, acc, nodes.minv, nodes.mass, dt, passes, work, cforce,
                                 cgap, maxit, tol)
    for i in range(x.shape[0]):
        x[i, 0] += dt * v[i, 0]
        x[i, 1] += dt * v[i, 1]
    cells, grads, wj, area0, emat, mtab = elements
    se, dtlim, jmin = internal_forces(x, cells, grads, wj, area0, emat, mtab, f)
    ke, px, py = accelerations(state, nodes, hdt)
    return se, ke, px, py, dke, dtlim, jmin, ncons


@njit(cache=True)
def half_kick(v, acc, nodes, hdt):
    """v += dt/2 a, prescribed components set to their values."""
    for i in range(v.shape[0]):
        for d in range(2):
            if nodes.fmask[i, d]:
                v[i, d] = nodes.fval[i, d]
            else:
                v[i, d] += hdt * acc[i, d]


@njit(cache=True)
def accelerations(state, nodes, hdt):
    """a = -M^-1 f, v += dt/2 a (prescribed components reset); returns kinetic energy and
    momentum of the new velocities."""
    acc, v, f = state.acc, state.v, state.f
    mass, minv = nodes.mass, nodes.minv
    ke = 0.0
    px = 0.0
    py = 0.0
    for i in range(v.shape[0]):
        for d in range(2):
            acc[i, d] = -f[i, d] * minv[i, d]
            if nodes.fmask[i, d]:
                v[i, d] = nodes.fval[i, d]
            else:
                v[i, d] += hdt * acc[i, d]
        ke += 0.5 * mass[i] * (v[i, 0] ** 2 + v[i, 1] ** 2)
        px += mass[i] * v[i, 0]
        py += mass[i] * v[i, 1]
    return ke, px, py
