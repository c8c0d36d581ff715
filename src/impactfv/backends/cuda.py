"""The CUDA backend: the loops of one finite-volume step on an NVIDIA GPU (numba-cuda).

The loop bodies are the CPU's: the same sources (scheme.bodies, and the physics they call)
compiled as CUDA device functions by compiled.device, as compiled.point does for numba on
the CPU. Only the loops differ: one GPU thread per node (stress, gradient and limiter,
Runge-Kutta stage) or per dual face (fluxes, scattered with atomic additions), block sums
in shared memory, and scratch arrays in ``cuda.local.array`` instead of the CPU's stack
buffers. Kernels are compiled per dimension d, number of reconstructed fields m, limiter and
edge flux options, which are compile-time constants of the closures :func:`kernels` makes.
:class:`CUDALoops` implements the stage sequence's loops interface (backends.loops).

The state (v, F, x), the work arrays and the discretisation live on the device for the
whole run; per stage only a few numbers come back (the boundary power, the force of each
boundary condition, and at the last stage the next stable time step, the first bad node
and the monitors), plus the forces of the held nodes when the case has reactions, and the
prescribed values go up when the loads change in time. The state is copied back only for
outputs (:meth:`CUDALoops.to_host`).

Body forces are added on the device. Contact is not: its search and Riemann states are the
CPU's kernels, run on the host on the contact surfaces' rows of the state (:class:`HostContact`),
whose results go back to the device each stage. Without a GPU, the tests run these kernels
under numba-cuda's simulator (NUMBA_ENABLE_CUDASIM=1), which executes the same Python
sources thread by thread.
"""

from __future__ import annotations

import importlib.util
import math
import os
import types

import numpy as np

from ..compiled import device
from ..physics.limiters import NONE as NO_LIMITER

#: threads per block of every kernel (a power of two: the block sums halve it); the simulator
#: runs every thread of a block as a Python thread, so it gets small blocks
THREADS = 16 if os.environ.get("NUMBA_ENABLE_CUDASIM") == "1" else 128

def problem(case) -> str | None:
    """Why ``case`` cannot run with backend "cuda" here (one line), or None."""
    if importlib.util.find_spec("numba_cuda") is None:
        return ('run.backend = "cuda" needs numba-cuda, which is not installed '
                '(pip install "impactfv[cuda]")')
    from numba import cuda as _cuda
    if not _cuda.is_available():
        return ('run.backend = "cuda": no usable CUDA GPU here (numba-cuda finds no device '
                'or driver); use backend = "cpu"')
    if case.run.method != "fv":
        return f'run.backend = "cuda" runs the FV method only, not {case.run.method!r}'
    return None


_kernels = {}


def kernels(d: int, m: int, kind: int, options=(False, False, False)):
    """The kernels for dimension d, m reconstructed fields, limiter ``kind`` and the edge
    flux's (reconstruct, stress_reconstructed, upwind_geometric) (all compile-time
    constants), compiled once per combination."""
    key = (d, m, kind, tuple(bool(o) for o in options))
    if key not in _kernels:
        _kernels[key] = _make_kernels(*key)
    return _kernels[key]


#: numba.cuda, imported when the first kernels are made (a module global, so that the
#: simulator can swap it for its own in the kernels' globals)
cuda = None


def _make_kernels(d, m, kind, options):
    global cuda
    from numba import cuda as _cuda
    from numba import float64
    cuda = _cuda

    from ..physics import materials as M
    from ..physics import runge_kutta as T
    from ..physics.tensors import determinant as _determinant
    from ..physics.tensors import symmetric_index as _symmetric_index
    from ..scheme import bodies as B

    cauchy_stress = device(M.cauchy_stress)
    strain_energy_density = device(M.strain_energy_density)
    min_stretch = device(M.min_stretch)
    determinant = device(_determinant)
    symmetric_index = device(_symmetric_index)
    heun_energy_excess = device(T.heun_energy_excess)
    edge_flux = device(B.edge_flux)
    boundary_face_flux = device(B.boundary_face_flux)
    node_gradient = device(B.node_gradient)
    node_update = device(B.node_update)
    node_energy_rate = device(B.node_energy_rate)
    node_monitors = device(B.node_monitors)
    stage_change = device(B.stage_change)
    relaxation_change = device(B.relaxation_change)
    CP = M.CP
    NMON = 2 + d
    RECONSTRUCT, STRESS_RECONSTRUCTED, UPWIND_GEOMETRIC = options
    EDGE_ROWS, EDGE_FORCE, EDGE_VELOCITY = B.EDGE_WORK_ROWS, B.EDGE_FORCE, B.EDGE_VELOCITY
    FACE_ROWS = B.FACE_WORK_ROWS
    FACE_TRACTION, FACE_STATE_VELOCITY, FACE_VELOCITY = (
        B.FACE_TRACTION, B.FACE_STATE_VELOCITY, B.FACE_VELOCITY)

    @cuda.jit
    def stress_and_fields(F, v, node_material, table, sigma, U, pack):
        a = cuda.grid(1)
        if a >= F.shape[0]:
            return
        Fa = cuda.local.array((d, d), float64)
        sa = cuda.local.array((d, d), float64)
        for i in range(d):
            for J in range(d):
                Fa[i, J] = F[a, i, J]
        cauchy_stress(Fa, table[node_material[a]], sa)
        for i in range(d):
            for J in range(d):
                sigma[a, i, J] = sa[i, J]
        if pack:
            for i in range(d):
                U[a, i] = v[a, i]
                for j in range(i, d):
                    U[a, d + symmetric_index(i, j, d)] = sa[i, j]

    @cuda.jit
    def limited_gradient(U, node_edge_start, node_neighbour, node_C, node_half, bface_start,
                         bface_others, bface_C, volume, own, denominator, grad, x, F,
                         mismatch, with_positions):
        # scheme.bodies.node_gradient, one thread per node
        a = cuda.grid(1)
        if a >= U.shape[0]:
            return
        dual = (node_edge_start, node_neighbour, node_C, node_half, bface_start,
                bface_others, bface_C, volume)
        scratch = (cuda.local.array(m * d, float64), cuda.local.array(m, float64),
                   cuda.local.array(m, float64), cuda.local.array(m, float64),
                   cuda.local.array((d, d), float64), cuda.local.array(m, float64),
                   cuda.local.array(m, float64), cuda.local.array(m, float64))
        node_gradient(a, U, x, F, dual, own, 1.0 / denominator, kind, with_positions,
                      scratch, grad, mismatch)

    @cuda.jit
    def relax_towards_positions(D, weight, owned, node_edge_start, node_neighbour, dF):
        # scheme.bodies.relaxation_change, one thread per node
        a = cuda.grid(1)
        if a >= owned:
            return
        relaxation_change(a, D, weight, node_edge_start, node_neighbour, dF,
                          cuda.local.array((d, d), float64))

    @cuda.jit
    def zero_rates(force, dF):
        a = cuda.grid(1)
        if a >= force.shape[0]:
            return
        for i in range(d):
            force[a, i] = 0.0
            for J in range(d):
                dF[a, i, J] = 0.0

    @cuda.jit
    def interior_fluxes(v, F, sigma, grad, node_material, table, edges, C, C_len, half,
                        bias, switch, contact_state, force, dF):
        # scheme.bodies.edge_flux, one thread per interior edge, scattered atomically
        e = cuda.grid(1)
        if e >= edges.shape[0]:
            return
        work = cuda.local.array((EDGE_ROWS, d), float64)
        a = edges[e, 0]
        b = edges[e, 1]
        edge_flux(e, a, b, v, F, sigma, grad, table[node_material[a]], C, C_len, half,
                  (RECONSTRUCT, STRESS_RECONSTRUCTED, UPWIND_GEOMETRIC, bias, switch),
                  contact_state, cuda.local.array((d, d), float64),
                  cuda.local.array((d, d), float64), cuda.local.array((d, d), float64), work)
        for i in range(d):
            f = work[EDGE_FORCE, i]
            cuda.atomic.add(force, (a, i), f)
            cuda.atomic.add(force, (b, i), -f)
            for J in range(d):
                change = work[EDGE_VELOCITY, i] * C[e, J]
                cuda.atomic.add(dF, (a, i, J), change)
                cuda.atomic.add(dF, (b, i, J), -change)

    @cuda.jit
    def boundary_fluxes(v, F, sigma, node_material, table, bface_node, bface_others, bface_C,
                        bface_bc, own, denominator, bc_fixed, prescribed_velocity,
                        prescribed_traction, tangential_correction, face_contact_weight,
                        force, dF, power, bc_force):
        # scheme.bodies.boundary_face_flux, one thread per face; a face takes its boundary
        # flux for the part of it and of the step not in contact
        h = cuda.grid(1)
        if h >= bface_node.shape[0]:
            return
        free = 1.0 - face_contact_weight[h]
        if free == 0.0:
            return
        work = cuda.local.array((FACE_ROWS, d), float64)
        bc = bface_bc[h]
        a = bface_node[h]
        ln = boundary_face_flux(h, a, v, F, sigma, table[node_material[a]], bface_others,
                                bface_C, own, 1.0 / denominator, bc_fixed, bc,
                                prescribed_velocity, prescribed_traction,
                                tangential_correction, cuda.local.array((d, d), float64),
                                cuda.local.array((d, d), float64),
                                cuda.local.array((d, d), float64), work)
        face_power = 0.0
        for i in range(d):
            t = free * work[FACE_TRACTION, i] * ln
            cuda.atomic.add(force, (a, i), t)
            cuda.atomic.add(bc_force, (bc, i), t)
            for J in range(d):
                cuda.atomic.add(dF, (a, i, J), free * work[FACE_VELOCITY, i] * bface_C[h, J])
            face_power += free * work[FACE_TRACTION, i] * work[FACE_STATE_VELOCITY, i] * ln
        cuda.atomic.add(power, 0, face_power)

    @cuda.jit
    def rk_update(alpha, dt, v0, F0, x0, v, F, x, force, dF, contact_state, contact_xdot,
                  node_material, table, volume, fixed_mask, fixed_value, start, stop,
                  node_length, with_checks, with_monitors, smallest, first_bad, out, body):
        # scheme.bodies.node_update for nodes start..stop-1 (one body when with_checks),
        # and at the last stage what the CPU's rk_update_last gives: block sums in shared
        # memory, one atomic per block
        a = start + cuda.grid(1)
        tid = cuda.threadIdx.x
        part = cuda.shared.array((THREADS, NMON), float64)
        low = cuda.shared.array(THREADS, float64)
        for j in range(NMON):
            part[tid, j] = 0.0
        low[tid] = math.inf
        if a < stop:
            props = table[node_material[a]]
            Fa = cuda.local.array((d, d), float64)
            finite = node_update(a, alpha, dt, v0, F0, x0, v, F, x, force, dF,
                                 contact_state[a] != 0, contact_xdot, props, volume,
                                 fixed_mask, fixed_value, Fa)
            if with_checks:
                jac = determinant(Fa)
                if not (finite and math.isfinite(jac) and jac > 0.0):
                    cuda.atomic.min(first_bad, 0, a)
                low[tid] = node_length[a] * min_stretch(Fa) / props[CP]
                if with_monitors:
                    values = node_monitors(a, v, props, volume,
                                           strain_energy_density(Fa, props))
                    for j in range(NMON):
                        part[tid, j] = values[j]
        if not with_checks:
            return
        cuda.syncthreads()
        step = THREADS // 2
        while step > 0:
            if tid < step:
                low[tid] = min(low[tid], low[tid + step])
                for j in range(NMON):
                    part[tid, j] += part[tid + step, j]
            cuda.syncthreads()
            step //= 2
        if tid == 0:
            cuda.atomic.min(smallest, 0, low[0])
            if with_monitors:
                for j in range(NMON):
                    cuda.atomic.add(out, (body, j), part[0, j])

    @cuda.jit
    def energy_rate(v, F, sigma, force, dF, fixed_mask, v0, F0, volume, node_material, table,
                    dt, with_integration, out):
        # scheme.bodies.node_energy_rate into out[0], the power v . f of the held velocity
        # components into out[1] and, at the last stage, the energy the step adds
        # (scheme.bodies.stage_change, physics.runge_kutta.heun_energy_excess) into out[2]:
        # block sums in shared memory, one atomic per block
        a = cuda.grid(1)
        tid = cuda.threadIdx.x
        part = cuda.shared.array((THREADS, 3), float64)
        part[tid, 0] = 0.0
        part[tid, 1] = 0.0
        part[tid, 2] = 0.0
        if a < v.shape[0]:
            props = table[node_material[a]]
            if with_integration:
                change = cuda.local.array((d, d), float64)
                midway = cuda.local.array((d, d), float64)
                dv2 = stage_change(a, 1.0 / dt, v0, F0, v, F, force, dF, props, volume,
                                   fixed_mask, change, midway)
                part[tid, 2] = heun_energy_excess(dt, props, volume[a], dv2, change, midway)
            held = 0.0
            for i in range(d):
                if fixed_mask[a, i]:
                    held += v[a, i] * force[a, i]
            part[tid, 0] = node_energy_rate(a, v, force, F, sigma, dF, fixed_mask, props,
                                            cuda.local.array((d, d), float64),
                                            cuda.local.array((d, d), float64),
                                            cuda.local.array((d, d), float64))
            part[tid, 1] = held
        cuda.syncthreads()
        step = THREADS // 2
        while step > 0:
            if tid < step:
                for j in range(3):
                    part[tid, j] += part[tid + step, j]
            cuda.syncthreads()
            step //= 2
        if tid == 0:
            for j in range(3):
                cuda.atomic.add(out, j, part[0, j])

    @cuda.jit
    def body_force(force, mass, acceleration, v, out):
        # the CPU's force += mass a, and into out[0] the power sum mass a . v: block sums
        a = cuda.grid(1)
        tid = cuda.threadIdx.x
        part = cuda.shared.array(THREADS, float64)
        part[tid] = 0.0
        if a < force.shape[0]:
            p = 0.0
            for i in range(d):
                f = mass[a] * acceleration[a, i]
                force[a, i] += f
                p += f * v[a, i]
            part[tid] = p
        cuda.syncthreads()
        step = THREADS // 2
        while step > 0:
            if tid < step:
                part[tid] += part[tid + step]
            cuda.syncthreads()
            step //= 2
        if tid == 0:
            cuda.atomic.add(out, 0, part[0])

    @cuda.jit
    def pack_rows(source, rows, out, column):
        # out[k, column:column + w] = source[rows[k]] (source viewed as (n, w)): the rows of
        # the state that the contact stage on the host reads, the forces of the held nodes
        k = cuda.grid(1)
        if k >= rows.shape[0]:
            return
        r = rows[k]
        for j in range(source.shape[1]):
            out[k, column + j] = source[r, j]

    @cuda.jit
    def unpack_rows(packed, column, rows, target):
        # target[rows[k]] = packed[k, column:column + w] (target viewed as (n, w))
        k = cuda.grid(1)
        if k >= rows.shape[0]:
            return
        r = rows[k]
        for j in range(target.shape[1]):
            target[r, j] = packed[k, column + j]

    return types.SimpleNamespace(
        stress_and_fields=stress_and_fields, limited_gradient=limited_gradient,
        relax_towards_positions=relax_towards_positions,
        zero_rates=zero_rates, interior_fluxes=interior_fluxes,
        boundary_fluxes=boundary_fluxes, rk_update=rk_update,
        energy_rate=energy_rate, body_force=body_force, pack_rows=pack_rows,
        unpack_rows=unpack_rows)


def _blocks(count):
    return max(1, (count + THREADS - 1) // THREADS)


class CUDALoops:
    """The loops of the FV stage sequence (backends.loops) as CUDA kernels: the state, work
    arrays and discretisation of an FVStepper on the GPU."""

    #: the last stage does not compute the new state's stress: the next step's first does
    carries_stress = False

    def __init__(self, stepper):
        from numba import cuda as _cuda

        self.cuda = cuda = _cuda
        s, m = stepper, stepper.disc
        self.s = s
        d = m.dim
        self.k = kernels(d, len(s.components), int(s.limiter), s.flux_options[:3])
        self.bias, self.switch = s.flux_options[3:]
        # the state lives on the device: the host's v, F, x are a copy, brought up to date
        # by to_host when the device's state has moved on
        self.host_stale = False
        up = cuda.to_device
        # a view of v when only v is reconstructed: U has its own array on the device
        self.pack = s.stress_reconstructed
        self.arrays = {name: up(np.ascontiguousarray(getattr(m, name))) for name in (
            "node_material", "material_table", "edges", "C", "C_len", "half",
            "node_edge_start", "node_neighbour", "node_C", "node_half", "bface_start",
            "bface_others", "bface_C", "bface_node", "bface_bc", "bc_fixed", "volume",
            "fixed_mask", "node_length")}
        for name in ("v", "F", "x", "sigma", "grad", "force", "dF"):
            self.arrays[name] = up(np.ascontiguousarray(getattr(s, name)))
        for name in ("v", "F", "x"):
            self.arrays[name + "0"] = cuda.device_array_like(self.arrays[name])
        self.arrays["U"] = up(s.U) if self.pack else self.arrays["v"]
        self.dual = tuple(self.arrays[name] for name in (
            "node_edge_start", "node_neighbour", "node_C", "node_half", "bface_start",
            "bface_others", "bface_C", "volume"))
        self.mass = up(np.ascontiguousarray(s.mass))
        n, h = m.n_nodes, len(m.bface_node)
        # contact: what the host's contact stage decides, on the device (the state and
        # contact velocity of the nodes, the part of each face in contact)
        self.arrays["contact_state"] = up(np.zeros(n))
        self.arrays["contact_xdot"] = up(np.zeros((n, d)))
        self.arrays["face_contact_weight"] = up(np.zeros(h))
        self.contact = None if s.contact is None else HostContact(self)
        self.loads_up()
        self.power = cuda.device_array(1)
        self.energy = cuda.device_array(3)
        self.bc_force = cuda.device_array(s.bc_force.shape)
        self.smallest = cuda.device_array(1)
        self.first_bad = cuda.device_array(1, np.int64)
        self.monitors = cuda.device_array(s.monitor_buf.shape)
        self.body_start = [int(b) for b in m.body_start]
        if s.energy.reaction_rows:
            held = np.unique(s.energy.reaction_sum.indices)
            self.held = up(held.astype(np.int64))
            self.held_sum = s.energy.reaction_sum[:, held]
            self.held_force = cuda.device_array((len(held), d))

    def loads_up(self):
        """Copy the prescribed values of the loads' current time to the device."""
        up = self.cuda.to_device
        loads = self.s.loads
        self.arrays["face_velocity"] = up(loads.face_velocity)
        self.arrays["face_traction"] = up(loads.face_traction)
        self.arrays["fixed_value"] = up(loads.fixed_value)
        if loads.has_body_force:
            self.arrays["acceleration"] = up(loads.acceleration)

    def to_host(self):
        """Copy the state (v, F, x) back into the stepper's host arrays if it moved on."""
        if not self.host_stale:
            return
        s, A = self.s, self.arrays
        A["v"].copy_to_host(s.v)
        A["F"].copy_to_host(s.F)
        A["x"].copy_to_host(s.x)
        self.host_stale = False

    def from_host(self):
        """The host's v, F, x are the state: copy them to the device."""
        s, A = self.s, self.arrays
        for name in ("v", "F", "x"):
            A[name].copy_to_device(getattr(s, name))
        self.host_stale = False

    def loads_changed(self):
        """The loads were brought to a new time: copy their values up if they vary."""
        if self.s.loads.varies:
            self.loads_up()

    def stresses(self, rows):
        """The stress and packed fields of every node (a device run has one rank)."""
        A, n = self.arrays, self.s.disc.n_nodes
        self.k.stress_and_fields[_blocks(n), THREADS](A["F"], A["v"], A["node_material"],
                                                      A["material_table"], A["sigma"],
                                                      A["U"], self.pack)

    def pack(self, rows):
        raise NotImplementedError("the CUDA backend carries no stress between steps")

    def _relaxation_arrays(self):
        A, m = self.arrays, self.s.disc
        if "mismatch" not in A:
            A["mismatch"] = self.cuda.device_array((m.n_nodes, m.dim, m.dim))
            A["relaxation_weight"] = self.cuda.to_device(self.s.relaxation_weight)
        return A["mismatch"]

    def gradient(self, with_positions):
        """scheme.bodies.node_gradient at every node; with ``with_positions`` the
        relaxation's mismatch D = F - G(x) in the same pass."""
        A, m = self.arrays, self.s.disc
        own, denominator = m.closure
        mismatch = self._relaxation_arrays() if with_positions else A["F"]  # not written
        self.k.limited_gradient[_blocks(m.n_nodes), THREADS](
            A["U"], *self.dual, float(own), float(denominator), A["grad"], A["x"], A["F"],
            mismatch, with_positions)

    def positions_mismatch(self):
        """The mismatch alone (order 1): the positions' unlimited gradient pass."""
        A, m = self.arrays, self.s.disc
        own, denominator = m.closure
        mismatch = self._relaxation_arrays()
        if "positions_gradient" not in A:
            A["positions_gradient"] = self.cuda.device_array((m.n_nodes, m.dim, m.dim + 1))
        kernels(m.dim, m.dim, NO_LIMITER).limited_gradient[_blocks(m.n_nodes), THREADS](
            A["x"], *self.dual, float(own), float(denominator), A["positions_gradient"],
            A["x"], A["F"], mismatch, True)

    def relax(self):
        A, n = self.arrays, self.s.disc.n_nodes
        self.k.relax_towards_positions[_blocks(n), THREADS](
            A["mismatch"], A["relaxation_weight"], n, A["node_edge_start"],
            A["node_neighbour"], A["dF"])

    def contact_stage(self, stage, stage_time):
        """The contact stage on the host (HostContact); its result is on the device too."""
        return self.contact.stage(stage, stage_time)

    def project_angular_momentum(self, projection, last, contact):
        """The interior fluxes' torque removed from the free bodies' force
        (scheme.angular_momentum), on the host: the force and the positions come down and
        the force goes back (a copy of the force per stage; not yet a device kernel)."""
        s, A = self.s, self.arrays
        self.to_host()
        if last:
            A["x0"].copy_to_host(s.x0)
        A["force"].copy_to_host(s.force)
        projection.project(last, contact)
        A["force"].copy_to_device(s.force)

    def contact_apply(self):
        self.contact.apply()

    def contact_end_step(self, time):
        self.contact.end_step(time)

    def fluxes(self, contact):
        """force and dF of the edges and boundary faces (the device's copy of ``contact``,
        the stage's contact.driver.ContactStage); returns (boundary power, the force of each
        boundary condition's faces)."""
        s, m, A, k = self.s, self.s.disc, self.arrays, self.k
        own, denominator = m.closure
        k.zero_rates[_blocks(m.n_nodes), THREADS](A["force"], A["dF"])
        self.power.copy_to_device(np.zeros(1))
        self.bc_force.copy_to_device(np.zeros(s.bc_force.shape))
        if m.n_edges:
            k.interior_fluxes[_blocks(m.n_edges), THREADS](
                A["v"], A["F"], A["sigma"], A["grad"], A["node_material"],
                A["material_table"], A["edges"], A["C"], A["C_len"], A["half"],
                self.bias, self.switch, A["contact_state"], A["force"], A["dF"])
        h = len(m.bface_node)
        if h:
            k.boundary_fluxes[_blocks(h), THREADS](
                A["v"], A["F"], A["sigma"], A["node_material"], A["material_table"],
                A["bface_node"], A["bface_others"], A["bface_C"], A["bface_bc"], float(own),
                float(denominator), A["bc_fixed"], A["face_velocity"], A["face_traction"],
                s.tangential_correction, A["face_contact_weight"], A["force"], A["dF"],
                self.power, self.bc_force)
        return float(self.power.copy_to_host()[0]), self.bc_force.copy_to_host()

    def body_force(self):
        """Adds the body forces to force; returns their power."""
        A, n = self.arrays, self.s.disc.n_nodes
        self.power.copy_to_device(np.zeros(1))
        self.k.body_force[_blocks(n), THREADS](A["force"], self.mass, A["acceleration"],
                                               A["v"], self.power)
        return float(self.power.copy_to_host()[0])

    def held_forces(self):
        """The force on each reaction's held nodes, summed per reaction row."""
        self.k.pack_rows[_blocks(self.held.shape[0]), THREADS](self.arrays["force"],
                                                               self.held, self.held_force, 0)
        return self.held_sum @ self.held_force.copy_to_host()

    def update(self, alpha, dt, stage, last, with_monitors, contact):
        """One Runge-Kutta stage of every node (the first saves the start of the step), with
        the energy rate of the stage's state read first, nodes in contact (the device's copy
        of ``contact``) moving with their contact velocity; at the last stage also the time
        step, the state check and, when asked, the monitors (backends.loops.StageResult)."""
        from .loops import StageResult

        s, A, k = self.s, self.arrays, self.k
        n = s.disc.n_nodes
        if stage == 0:
            for name in ("v", "F", "x"):
                A[name + "0"].copy_to_device(A[name])
        self.energy.copy_to_device(np.zeros(3))
        k.energy_rate[_blocks(n), THREADS](A["v"], A["F"], A["sigma"], A["force"], A["dF"],
                                           A["fixed_mask"], A["v0"], A["F0"], A["volume"],
                                           A["node_material"], A["material_table"],
                                           float(dt), bool(last), self.energy)
        rate, held_power, integration = (float(e) for e in self.energy.copy_to_host())
        if last:
            self.smallest.copy_to_device(np.array([np.inf]))
            self.first_bad.copy_to_device(np.array([n], np.int64))
            self.monitors.copy_to_device(np.zeros(s.monitor_buf.shape))
            ranges = [(self.body_start[b], self.body_start[b + 1], b)
                      for b in range(len(self.body_start) - 1)]
        else:
            ranges = [(0, n, 0)]
        for start, stop, body in ranges:
            if stop <= start:
                continue
            k.rk_update[_blocks(stop - start), THREADS](
                float(alpha), float(dt), A["v0"], A["F0"], A["x0"], A["v"], A["F"], A["x"],
                A["force"], A["dF"], A["contact_state"], A["contact_xdot"],
                A["node_material"], A["material_table"], A["volume"],
                A["fixed_mask"], A["fixed_value"], start, stop, A["node_length"], bool(last),
                bool(with_monitors), self.smallest, self.first_bad, self.monitors, body)
        self.host_stale = True
        if not last:
            return StageResult(rate, held_power)
        if with_monitors:
            self.monitors.copy_to_host(s.monitor_buf)
        bad = int(self.first_bad.copy_to_host()[0])
        return StageResult(rate, held_power, integration, float(self.smallest.copy_to_host()[0]),
                           bad if bad < n else -1, s.monitor_buf if with_monitors else None)


class HostContact:
    """The contact stage of a device run, on the host: per stage the rows of the contact
    surfaces' nodes (positions, velocity, F, stress, gradients) come from the device, the
    CPU's contact.driver.ContactSystem runs on them in the stepper's host arrays (it reads
    and writes only those rows), and what it decides goes back: the part of each contact
    face in contact, the gradients it drops, and after the flux assembly the contact forces
    and F-equation terms (added on the host to the device's sums of the surface rows) and
    each node's contact state and velocity. The transfers grow with the contact surfaces,
    not with the mesh; the search and the contact Riemann states are the CPU's code. The
    ContactStage a stage returns holds the host's arrays; the loops read the device's."""

    def __init__(self, device):
        cuda, A, s = device.cuda, device.arrays, device.s
        self.device, self.s, self.system = device, s, s.contact
        n = s.disc.n_nodes
        self.nodes = s.contact.surface_nodes.astype(np.int64)
        self.faces = s.contact.faces.astype(np.int64)
        self.nodes_dev = cuda.to_device(self.nodes)
        self.faces_dev = cuda.to_device(self.faces)

        def view(name, host, rows=n):
            # (name, the device array viewed as (rows, w), the host array viewed likewise)
            w = int(np.prod(host.shape[1:])) if host.ndim > 1 else 1
            flat = host.reshape(rows, w)
            assert np.shares_memory(flat, host), name      # a view, written through
            return name, A[name].reshape(rows, w), flat
        self.state_in = [view("x", s.x), view("v", s.v), view("F", s.F),
                         view("sigma", s.sigma)]
        self.grad = view("grad", s.grad)[1] if s.order == 2 else None
        self.rates_io = [view("force", s.force), view("dF", s.dF)]
        system = s.contact
        self.weights = view("face_contact_weight", system.face_weight, len(s.disc.bface_node))
        self.contact_out = [("contact_state", A["contact_state"].reshape(n, 1),
                             system.state.reshape(n, 1)),
                            ("contact_xdot", A["contact_xdot"], system.xdot)]
        self.buffers = {}

    def _buffer(self, rows, width):
        key = (rows, width)
        if key not in self.buffers:
            self.buffers[key] = self.device.cuda.device_array(key)
        return self.buffers[key]

    def _down(self, views, rows, rows_dev):
        """Copy the rows ``rows`` of the device arrays ``views`` into the host arrays."""
        k = self.device.k
        width = sum(dev.shape[1] for _, dev, _ in views)
        packed = self._buffer(len(rows), width)
        column = 0
        for _, dev, _ in views:
            k.pack_rows[_blocks(len(rows)), THREADS](dev, rows_dev, packed, column)
            column += dev.shape[1]
        host = packed.copy_to_host()
        column = 0
        for _, dev, target in views:
            target[rows] = host[:, column:column + dev.shape[1]]
            column += dev.shape[1]

    def _up(self, views, rows, rows_dev):
        """Copy the rows ``rows`` of the host arrays ``views`` into the device arrays."""
        k = self.device.k
        width = sum(dev.shape[1] for _, dev, _ in views)
        host = np.empty((len(rows), width))
        column = 0
        for _, dev, source in views:
            host[:, column:column + dev.shape[1]] = source[rows]
            column += dev.shape[1]
        packed = self._buffer(len(rows), width)
        packed.copy_to_device(host)
        column = 0
        for _, dev, _ in views:
            k.unpack_rows[_blocks(len(rows)), THREADS](packed, column, rows_dev, dev)
            column += dev.shape[1]

    def stage(self, stage, stage_time):
        s = self.s
        self._down(self.state_in, self.nodes, self.nodes_dev)
        contact = self.system.stage(s.x, s.v, s.F, s.sigma, s.dt, stage, stage_time)
        self._up([self.weights], self.faces, self.faces_dev)
        # the stage's contact states (the smoothness switch leaves the contact zone's edges)
        self._up(self.contact_out[:1], self.nodes, self.nodes_dev)
        if self.grad is not None and len(contact.first_order):
            # the gradients the stage drops, zeroed on the device
            rows = self.device.cuda.to_device(contact.first_order.astype(np.int64))
            zeros = self.device.cuda.to_device(np.zeros((len(rows), self.grad.shape[1])))
            self.device.k.unpack_rows[_blocks(len(rows)), THREADS](zeros, 0, rows, self.grad)
        return contact

    def apply(self):
        s = self.s
        self._down(self.rates_io, self.nodes, self.nodes_dev)
        self.system.apply(s.force, s.dF, s.loads.fixed_value)
        self._up(self.rates_io + self.contact_out, self.nodes, self.nodes_dev)

    def end_step(self, time):
        s = self.s
        self._down(self.state_in[:3], self.nodes, self.nodes_dev)
        self.system.end_step(s.x, s.v, s.F, time)
