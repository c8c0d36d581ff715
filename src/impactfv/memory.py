"""How much memory a run needs, from the shapes of the arrays it allocates, and how much the
machine has available: ``impactfv check`` reports the estimate, ``run`` (and ``load_case``,
for generated meshes, before it builds them) refuses a case that cannot fit.

A run's memory peaks at one of two moments:

* setup: the case's meshes, the assembled arrays of the bodies done so far, and the median
  dual of the largest body under construction (mesh.dual.median_dual holds up to 76 float64
  per triangle at once: centroids, the three directed edges with their midpoints and area
  vectors, the sort keys and the work arrays of ``np.unique``);
* time loop: every array that lives through the run (the meshes, scheme.discretisation,
  the FV stepper's state and work arrays, the contact system's, the history), plus the
  largest transient: writing a frame (the point fields, their 3-component copies and the
  base64 text meshio builds for every array of the VTU file) or a checkpoint.

The array sizes below follow scheme/discretisation.py, scheme/stepper.py and
contact/driver.py one by one. On top of the arrays, the allocator keeps about 10% more
resident than is allocated (freed blocks not returned to the system; measured against the
peak resident size at 20k to 200k nodes by tests/test_hostile_input.py), and the
interpreter, numpy, numba and the compiled kernels take about 200 MiB whatever the case.
The FE baselines allocate less (55 to 70% of the figure); the estimate is an upper bound
for them.

``IMPACTFV_MEMORY_LIMIT`` (bytes, or with a K, M, G or T suffix: powers of 1024) caps the
memory a run may plan on, on a machine shared with other work.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

#: resident memory of the interpreter, numpy, numba and the loaded kernels (a tiny run)
RUNTIME_BYTES = 200 * 2**20
#: resident memory per byte of allocated arrays (the allocator's free lists and padding)
ALLOCATOR_OVERHEAD = 1.10
#: bytes median_dual holds at once per cell: 76 float64 or int64 per triangle (measured
#: against the peak resident size), 92 per tetrahedron (tracemalloc's peak of median_dual;
#: with it the estimate of a 3D run is within 4% of its measured peak at 9k to 97k nodes)
DUAL_BYTES_PER_CELL = {2: 76 * 8, 3: 92 * 8}


@dataclass
class BodyCounts:
    """Sizes of one body's mesh: nodes, cells (triangles or tetrahedra) and boundary
    facets; ``known_edges`` when counted (3D), else Euler's formula of a triangulation."""

    nodes: int
    triangles: int
    boundary: int
    in_contact: bool = False
    known_edges: int | None = None

    @property
    def edges(self) -> int:
        if self.known_edges is not None:
            return self.known_edges
        # Euler's formula of a planar triangulation (one more per hole): E = V + T - 1
        return self.nodes + self.triangles - 1


def counts_of_mesh(mesh, in_contact=False) -> BodyCounts:
    n, t = int(mesh.n_nodes), int(len(mesh.cells))
    if mesh.dim == 3:
        from .mesh.edges import boundary_facets, unique_edges
        return BodyCounts(n, t, len(boundary_facets(mesh.cells, 3)), in_contact,
                          len(unique_edges(mesh.cells, 3)))
    boundary = max(2 * (n + t - 1) - 3 * t, 3)     # 3T = 2E - B
    return BodyCounts(n, t, boundary, in_contact)


def counts_of_generator(spec, in_contact=False) -> BodyCounts | None:
    """The sizes a built-in generator would make (exact), without building it."""
    if spec.generator == "rectangle":
        nx, ny = (int(k) for k in spec.divisions)
        if spec.pattern == "crossed":
            return BodyCounts((nx + 1) * (ny + 1) + nx * ny, 4 * nx * ny, 2 * (nx + ny),
                              in_contact)
        return BodyCounts((nx + 1) * (ny + 1), 2 * nx * ny, 2 * (nx + ny), in_contact)
    if spec.generator == "disc":
        r = int(spec.rings)
        return BodyCounts(1 + 3 * r * (r + 1), 6 * r * r, 6 * r, in_contact)
    if spec.generator == "annulus":
        from .mesh.generators import annulus_segments
        m = annulus_segments(spec.radius, spec.inner_radius, int(spec.rings))
        r = int(spec.rings)
        return BodyCounts((r + 1) * m, 2 * r * m, 2 * m, in_contact)
    if spec.generator == "box":
        nx, ny, nz = (int(k) for k in spec.divisions)
        # Kuhn cells: per cube 3 axis edges, 3 face diagonals and 1 body diagonal
        edges = (nx * (ny + 1) * (nz + 1) + (nx + 1) * ny * (nz + 1) + (nx + 1) * (ny + 1) * nz
                 + nx * ny * (nz + 1) + nx * (ny + 1) * nz + (nx + 1) * ny * nz + nx * ny * nz)
        return BodyCounts((nx + 1) * (ny + 1) * (nz + 1), 6 * nx * ny * nz,
                          4 * (nx * ny + ny * nz + nx * nz), in_contact, edges)
    return None


@dataclass
class MemoryEstimate:
    nodes: int
    edges: int
    setup: int           # bytes at the setup peak
    loop: int            # bytes at the time-loop peak

    @property
    def arrays(self) -> int:
        return max(self.setup, self.loop)

    @property
    def total(self) -> int:
        """Resident bytes the case adds to the process: the larger peak, with allocator
        overhead."""
        return int(ALLOCATOR_OVERHEAD * self.arrays)

    @property
    def per_node(self) -> float:
        return self.total / max(self.nodes, 1)

    def describe(self) -> str:
        return (f"about {format_bytes(self.total)} ({self.per_node:.0f} bytes per node, "
                f"{self.nodes:,} nodes, {self.edges:,} edges; peak "
                f"{'during setup' if self.setup > self.loop else 'in the time loop'})")


def estimate(bodies: list[BodyCounts], order: int = 2, upwind: bool = True,
             n_contacts: int = 0, steps: int = 0, dim: int = 2,
             relaxed: bool = True) -> MemoryEstimate:
    """The memory of an FV run of bodies of these sizes (see the module text); ``steps``:
    the expected number of time steps (history rows); ``relaxed``: the compatibility
    relaxation is on (run.compatibility_time > 0, the default)."""
    d = dim
    n = sum(b.nodes for b in bodies)
    t = sum(b.triangles for b in bodies)
    m = sum(b.edges for b in bodies)
    k = sum(b.boundary for b in bodies)        # boundary facets
    h = d * k                                  # dual boundary faces
    cell = 8 * (d + 1)
    meshes = n * 8 * d + t * cell + k * 8 * d                      # points, cells, regions
    per_node = (8 * d + 4 + 4 + 8 + 8                              # X, material, body,
                                                                   # volume, node_length
                + 8 + 8                                            # node_edge_start,
                                                                   # bface_start
                + d + 8 * d + 8 * d)                               # fixed mask, value, v0
    per_edge = (16 + 8 * d + 8 + 8 * d                             # edges, C, C_len, half
                + 2 * 8 + 2 * 8 * d + 2 * 8 * d)                   # node_neighbour, C, half
    per_face = 8 + 8 * (d - 1) + 8 * d + 8 + 4                     # bface node, others,
                                                                   # C, facet, bc
    layouts = t * cell + 2 * k * 8 * d                             # cells, regions, facets
    disc = n * per_node + m * per_edge + h * per_face + layouts
    ncomp = d + d * (d + 1) // 2 if (order == 2 and upwind) else d
    stepper = n * (2 * 8 * (d + d * d + d)                         # v F x and copies
                   + 8 * d * d                                     # Cauchy stress
                   + (8 * ncomp if ncomp > d else 0)               # packed U
                   + 8 * ncomp * (d + 1) + 2 * 8 * ncomp           # gradient and limiter
                                                                   # factor, min, max
                   + 8 * d + 8 * d * d                             # force, dF
                   + 1 + 8 * d                                     # contact state, xdot
                   + (8 if d == 3 else 0)) + 8 * h                 # stretch bounds (3D),
                                                                   # face weights
    if relaxed:
        stepper += n * 8 * d * d + m * 2 * 8                       # mismatch D, edge weights
        if order == 1:
            stepper += n * 8 * d * (d + 1)                         # the positions' gradient
    contact = 0
    if n_contacts:
        faces = d * sum(b.boundary for b in bodies if b.in_contact)
        contact = (n * (3 + 8 * 10 + 8 * 5 * d + 8)                # per-node arrays
                   + h * (8 + 8 * d)                               # face weight, velocity
                   + faces * (3 * 8 + 8 * 4)                       # face lists, surfaces
                   + (4 * faces + 16) * (6 * 8 + 8 * d))           # pieces
    columns = 2 + 3 + d + 3 * n_contacts
    history = 3 * 8 * columns * max(steps + 1, 1024)               # doubling: old + new
    fields = 8 * n * (3 + d + 1)                                   # pressure, von Mises, J,
                                                                   # displacement, body
    if n_contacts:
        fields += 16 * n                                           # contact status, pressure
    copies = 3 * 8 * 3 * n if d < 3 else 0                         # 3-component vectors
    vtu = (3 * 8 * n + t * (cell + 8 + 1)                          # points, cells, offsets,
           + 8 * n * (3 + 3 + 4 + (2 if n_contacts else 0)))       # types, point data
    frame = fields + t * cell + copies + 4 * vtu // 3 + max(t * cell, 3 * 8 * n)
    checkpoint = 2 * (n * 8 * (d + 2 * d * d + d) + history // 3)  # arrays (with the
                                                                   # carried stress), copy
    loop = meshes + disc + stepper + contact + history + max(frame, checkpoint)
    # the largest body's dual under construction, after the other bodies' per-body parts
    # (positions, materials, volumes, lengths, velocities; edges and area vectors; faces)
    largest = max(bodies, key=lambda b: b.triangles)
    others = [b for b in bodies if b is not largest]
    parts = sum(b.nodes * (8 * d + 4 + 4 + 8 + 8 + 8 * d) + b.edges * (16 + 8 * d)
                + d * b.boundary * per_face for b in others)
    setup = (meshes + parts + largest.nodes * 8 * d + largest.triangles * cell
             + largest.triangles * DUAL_BYTES_PER_CELL[d])
    return MemoryEstimate(n, m, setup, loop)


def estimate_case(case, steps: int = 0) -> MemoryEstimate:
    """The estimate of a loaded case (meshes read and checked)."""
    contact_bodies = {name for c in case.contacts for name in c.bodies}
    bodies = [counts_of_mesh(b.mesh, b.name in contact_bodies) for b in case.bodies]
    return estimate(bodies, case.run.order, case.run.geometric_flux == "upwind",
                    len(case.contacts), steps, case.bodies[0].mesh.dim,
                    case.run.compatibility_time > 0)


def format_bytes(value: float) -> str:
    for unit, size in (("TiB", 2**40), ("GiB", 2**30), ("MiB", 2**20)):
        if value >= size:
            return f"{value / size:.3g} {unit}"
    return f"{value / 2**10:.3g} KiB"


def _read_int(path: str) -> int | None:
    try:
        with open(path) as fh:
            text = fh.read().strip()
        return int(text) if text.isdigit() else None
    except (OSError, ValueError):
        return None


def available_bytes() -> int | None:
    """Memory this process can still use: MemAvailable of /proc/meminfo (else the free pages
    os.sysconf reports), lowered to what a cgroup limit, ``ulimit -v`` and
    IMPACTFV_MEMORY_LIMIT leave; None if nothing can tell."""
    available = None
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    available = int(line.split()[1]) * 1024
                    break
    except (OSError, ValueError, IndexError):
        pass
    if available is None:
        try:
            available = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (ValueError, OSError, AttributeError):
            available = None
    for limit_file, usage_file in (("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
                                   ("/sys/fs/cgroup/memory/memory.limit_in_bytes",
                                    "/sys/fs/cgroup/memory/memory.usage_in_bytes")):
        limit, usage = _read_int(limit_file), _read_int(usage_file)
        if limit is not None and usage is not None and limit < 2**60:
            left = max(limit - usage, 0)
            available = left if available is None else min(available, left)
    limit = _address_space_limit()
    if limit is not None:                                   # ulimit -v
        left = max(limit - _virtual_bytes(), 0)
        available = left if available is None else min(available, left)
    cap = user_limit()
    if cap is not None:
        available = cap if available is None else min(available, cap)
    return available


def user_limit() -> int | None:
    """``IMPACTFV_MEMORY_LIMIT`` in bytes (None if unset); InputError if it is not a size."""
    text = os.environ.get("IMPACTFV_MEMORY_LIMIT", "").strip()
    if not text:
        return None
    scale = {"K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}
    unit = text[-1].upper()
    number = text[:-1] if unit in scale else text
    try:
        value = float(number) * scale.get(unit, 1)
    except ValueError:
        value = float("nan")
    if not (value >= 0 and value < float("inf")):
        from .errors import InputError
        raise InputError(f"IMPACTFV_MEMORY_LIMIT: expected a size in bytes (e.g. 8G), "
                         f"got {text!r}")
    return int(value)


def _address_space_limit() -> int | None:
    try:
        import resource
        limit = resource.getrlimit(resource.RLIMIT_AS)[0]
        return None if limit == resource.RLIM_INFINITY or limit < 0 else int(limit)
    except (ImportError, OSError, ValueError, AttributeError):
        return None


def _virtual_bytes() -> int:
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError, AttributeError):
        return 0


def resident_bytes() -> int:
    """The resident memory of this process now (0 if the system cannot tell)."""
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError, AttributeError):
        return 0


def needed_bytes(est: MemoryEstimate) -> int:
    """What the run still has to take from the machine: the case's arrays, plus the part of
    the runtime this process does not hold yet."""
    return est.total + max(RUNTIME_BYTES - resident_bytes(), 0)


def memory_problem(est: MemoryEstimate, available: int | None = None,
                   held: int = 0) -> str | None:
    """A message when the estimate exceeds the available memory; None when it fits or the
    machine cannot tell. ``held``: bytes of the estimate this process has already taken
    (they are no longer available, but count in the estimate)."""
    available = available_bytes() if available is None else available
    if available is None:
        return None
    need = needed_bytes(est)
    if need - max(held, 0) <= available:
        return None
    runtime = need - est.total
    plus = f" plus {format_bytes(runtime)} for Python and the compiled kernels" if runtime \
        else ""
    return (f"needs {est.describe()}{plus}, more than the {format_bytes(available)} of "
            "memory available; use a coarser mesh or a machine with more memory")
