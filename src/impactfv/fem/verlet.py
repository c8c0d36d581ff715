"""One explicit central-difference (velocity Verlet) step of the FE baselines, compiled."""

from numba import njit

from .contact import contact_correct
from .elements import internal_forces


@njit(cache=True)
def step(x, v, acc, f, minv, mass, fmask, fval, dt, cells, grads, wj, area0, emat, mtab,
         pslave_ptr, slave_nodes, pseg_ptr, segs, psedge_ptr, sedges, pcontact, pslave_is_a,
         pdepth, normals, xp, cons_n, cons_xi, cons_nrm, cons_p, cforce, cgap, maxit, tol):
    """One velocity-Verlet (central-difference) step with kinematic contact.

    v_{n+1/2} = v_n + dt/2 a_n; contact correction of v_{n+1/2} so that x_n + dt v_{n+1/2}
    does not penetrate; x_{n+1} = x_n + dt v_{n+1/2}; a_{n+1} = -M^-1 f_int(x_{n+1});
    v_{n+1} = v_{n+1/2} + dt/2 a_{n+1}.  Prescribed components are reset each half step.

    Returns (strain energy, kinetic energy, px, py, energy change by the contact, dt limit ratio, min J,
    number of contact constraints), all at t_{n+1}.
    """
    nn = x.shape[0]
    hdt = 0.5 * dt
    for i in range(nn):
        for d in range(2):
            if fmask[i, d]:
                v[i, d] = fval[i, d]
            else:
                v[i, d] += hdt * acc[i, d]
    dke, ncons = contact_correct(x, v, minv, mass, acc, dt, pslave_ptr, slave_nodes, pseg_ptr,
                                 segs, psedge_ptr, sedges, pcontact, pslave_is_a, pdepth,
                                 normals, xp, cons_n, cons_xi, cons_nrm, cons_p, cforce, cgap,
                                 maxit, tol)
    for i in range(nn):
        x[i, 0] += dt * v[i, 0]
        x[i, 1] += dt * v[i, 1]
    se, dtlim, jmin = internal_forces(x, cells, grads, wj, area0, emat, mtab, f)
    ke, px, py = accelerations(f, minv, fmask, fval, hdt, acc, v, mass)
    return se, ke, px, py, dke, dtlim, jmin, ncons


@njit(cache=True)
def accelerations(f, minv, fmask, fval, hdt, acc, v, mass):
    """a = -M^-1 f, v += dt/2 a (prescribed components reset); returns kinetic energy and
    momentum of the new velocities."""
    ke = 0.0
    px = 0.0
    py = 0.0
    for i in range(v.shape[0]):
        for d in range(2):
            acc[i, d] = -f[i, d] * minv[i, d]
            if fmask[i, d]:
                v[i, d] = fval[i, d]
            else:
                v[i, d] += hdt * acc[i, d]
        ke += 0.5 * mass[i] * (v[i, 0] ** 2 + v[i, 1] ** 2)
        px += mass[i] * v[i, 0]
        py += mass[i] * v[i, 1]
    return ke, px, py
