"""Run a validated :class:`~impactfv.case.Case` with the explicit FE baselines.

``impactfv.solver.run`` sends ``method = "fem-t3"`` and ``"fem-q4md"`` here.  The case is
translated into :class:`~impactfv.fem.solver.FemBody` / :class:`FemContact` objects:

* ``fem-t3`` uses each body's triangle mesh as it is (the same nodes and triangles the FV
  scheme builds its median dual on);
* ``fem-q4md`` needs quadrilaterals: a body meshed with ``generator = "rectangle"`` gets the
  bilinear quads of the same grid (:func:`~impactfv.fem.mesh.rectangle_quads`: same nodes,
  ``nx x ny`` quads instead of ``2 nx ny`` triangles); a body read from a file is refused;
* a ``[[body.boundary]]`` velocity component is prescribed strongly on every node of its
  region (for quads the region nodes are found by position: the nodes of the grid lying on
  the region's edges of the triangle mesh, i.e. on x = min / x = max / y = min / y = max);
* a ``[[contact]]`` between two bodies becomes a frictionless kinematic node-to-segment
  contact whose surfaces are the bodies' boundary edges (or the edges of the contact's
  ``regions``).  The FE contact is frictionless only, so ``model = "stick"`` is refused;
  ``model = "slip"`` (frictionless in the FV scheme too) is the matching choice;
* traction boundaries and rigid-wall contacts are not implemented in the FE module and are
  refused with an :class:`~impactfv.errors.InputError`.

The result is a :class:`~impactfv.solver.RunResult` like the FV one: ``history`` (the FV
columns plus ``contact_energy``), ``bodies[name]`` (``reference_points``, ``points``,
``cells``, ``triangles`` (the cells for T3, each quad split in two for Q4, for plotting),
``velocity``, ``displacement``, ``pressure``, ``von_mises``; pressures and von Mises stresses
are reference-area-weighted nodal averages of the element values) and ``summary`` (the FV
keys).  With an output folder it writes ``history.csv``, ``summary.json`` and ``fields.pvd``
snapshots at the output interval (nodal fields on the triangles above).
"""

from __future__ import annotations

import time as _time
from pathlib import Path

import numpy as np

from .. import __version__
from ..errors import InputError, SimulationError
from ..io.writers import SnapshotWriter, write_history_csv, write_summary
from .mesh import boundary_edges, mesh_edges, quads_to_triangles, rectangle_quads
from .solver import METHODS, FemBody, FemContact, simulate_fem

HISTORY_ORDER = ("time", "dt", "kinetic_energy", "strain_energy", "total_energy", "momentum_x",
                 "momentum_y")


def _region_nodes_by_position(tri_points, region_edges, quad_points):
    """Indices in ``quad_points`` of the nodes of a triangle-mesh region (matched by
    position, rounded to 1e-9 of the bounding box)."""
    scale = float(np.ptp(quad_points, axis=0).max()) or 1.0
    key = lambda p: tuple(np.round(np.asarray(p) / scale, 9).tolist())  # noqa: E731
    lookup = {key(p): i for i, p in enumerate(quad_points)}
    out = []
    for node in np.unique(region_edges):
        i = lookup.get(key(tri_points[node]))
        if i is None:
            raise InputError(f"region node at {tri_points[node].tolist()} is not a node of the "
                             "quadrilateral grid")
        out.append(i)
    return np.array(out, dtype=np.int64)


def _body_mesh(case, ib, body, method):
    """(points, cells, plot triangles, region -> node indices, region -> edges)."""
    mesh = body.mesh
    if method == "fem-t3":
        regions = {k: np.unique(e) for k, e in mesh.regions.items()}
        return (np.asarray(mesh.points, float), np.asarray(mesh.triangles, np.int64),
                np.asarray(mesh.triangles, np.int64), regions, dict(mesh.regions))
    spec = body.spec.mesh
    if spec.generator != "rectangle":
        raise InputError(f"{case.source}: body[{ib}].mesh: method fem-q4md needs "
                         "rectangle-generated meshes (generator = \"rectangle\"), "
                         f"body {body.name!r} reads {spec.file!r}")
    pts, quads, _ = rectangle_quads(spec.origin, spec.size, spec.divisions)
    regions = {k: _region_nodes_by_position(mesh.points, e, pts)
               for k, e in mesh.regions.items()}
    # region edges of the quad mesh: boundary edges with both nodes in the region
    bedges = boundary_edges(quads)
    redges = {k: bedges[np.isin(bedges[:, 0], n) & np.isin(bedges[:, 1], n)]
              for k, n in regions.items()}
    return pts, quads, quads_to_triangles(quads), regions, redges


def build_fem_problem(case, method=None):
    """Translate a case into ``(bodies, contacts, plot_triangles)`` for :func:`simulate_fem`."""
    method = method or case.run.method
    if method not in METHODS:
        raise InputError(f"{case.source}: run.method: {method!r} is not a FE method "
                         f"({', '.join(METHODS)})")
    names = [b.name for b in case.bodies]
    fem_bodies, plot_tris = [], []
    contact_edges = {}
    for ib, body in enumerate(case.bodies):
        pts, cells, tris, rnodes, redges = _body_mesh(case, ib, body, method)
        mask = np.zeros(pts.shape, bool)
        value = np.zeros(pts.shape)
        for j, bc in enumerate(body.boundary):
            if bc.traction is not None:
                raise InputError(f"{case.source}: body[{ib}].boundary[{j}]: traction "
                                 f"boundaries are not supported by method {method!r} "
                                 "(use method = \"fv\")")
            nodes = rnodes[bc.region]
            for c, comp in enumerate((bc.velocity.x, bc.velocity.y)):
                if comp is not None:
                    mask[nodes, c] = True
                    value[nodes, c] = comp
        velocity = body.initial_velocity(pts)
        fem_bodies.append(FemBody(body.name, pts, cells, body.material, velocity, mask, value,
                                  None))
        plot_tris.append(tris)
        contact_edges[ib] = (boundary_edges(cells), redges)
    contacts = []
    used = {}
    for k, spec in enumerate(case.contacts):
        if spec.wall is not None:
            raise InputError(f"{case.source}: contact[{k}].wall: rigid-wall contact is not "
                             f"supported by method {method!r} (use method = \"fv\")")
        if spec.model != "slip":
            raise InputError(f"{case.source}: contact[{k}].model: the FE contact is "
                             f"frictionless; method {method!r} needs model = \"slip\"")
        ia, ib_ = (names.index(n) for n in spec.bodies)
        for i in (ia, ib_):
            bedges, redges = contact_edges[i]
            if spec.regions is None:
                edges = bedges
            else:
                found = [redges[r] for r in spec.regions if r in redges]
                if not found:
                    raise InputError(f"{case.source}: contact[{k}].regions: body {names[i]!r} "
                                     f"has none of {', '.join(spec.regions)}")
                edges = np.unique(np.concatenate(found), axis=0)
            if i in used and not np.array_equal(used[i], edges):
                raise InputError(f"{case.source}: contact[{k}]: body {names[i]!r} is in "
                                 "several contacts with different surfaces; method "
                                 f"{method!r} takes one contact surface per body")
            used[i] = edges
            fem_bodies[i].contact_edges = edges
        contacts.append(FemContact(ia, ib_))
    return fem_bodies, contacts, plot_tris


def run_fem_case(case, output_dir=None, progress=None):
    """Run ``case`` with ``case.run.method`` in ("fem-t3", "fem-q4md"); see the module doc."""
    from ..solver import RunResult

    wall_start = _time.perf_counter()
    method = case.run.method
    bodies, contacts, plot_tris = build_fem_problem(case, method)
    end = case.run.end_time
    interval = case.run.output_interval or end / 10.0
    out = Path(output_dir) if output_dir is not None else None
    snap_times = []
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        n_out = int(np.floor(end / interval * (1 + 1e-12)))
        snap_times = [0.0] + [min(i * interval, end) for i in range(1, n_out + 1)]
        if snap_times[-1] < end * (1 - 1e-12):
            snap_times.append(end)
    from ..solver import _progress_bar  # one progress bar for every method
    bar = _progress_bar(progress, end)
    callback = None
    if bar is not None:
        def callback(fraction):
            bar.update(fraction * end - bar.n)
    status = "completed"
    try:
        res = simulate_fem(bodies, contacts, end, method, cfl=case.run.cfl,
                           snapshot_times=snap_times, progress=callback)
    except FloatingPointError as exc:
        if out is not None:
            write_summary(out / "summary.json",
                          {"title": case.title, "version": __version__, "method": method,
                           "status": "failed", "error": str(exc)})
        raise SimulationError(f"{method}: {exc}; try a smaller cfl or a finer mesh") from None
    finally:
        if bar is not None:
            bar.close()
    history = {k: res.history[k] for k in HISTORY_ORDER}
    history.update({k: v for k, v in res.history.items() if k not in history})
    fields = {}
    for b, tris in zip(bodies, plot_tris):
        d = dict(res.bodies[b.name])
        d["triangles"] = np.asarray(tris, np.int64)
        d["displacement"] = d["points"] - d["reference_points"]
        fields[b.name] = d
    n_nodes = int(sum(len(b.points) for b in bodies))
    n_cells = int(sum(len(b.cells) for b in bodies))
    n_edges = int(sum(len(mesh_edges(b.cells)) for b in bodies))
    loop = res.wall_time
    last = {k: float(v[-1]) for k, v in history.items()}
    summary = {
        "title": case.title, "version": __version__, "method": method, "status": status,
        "nodes": n_nodes, "edges": n_edges, "cells": n_cells,
        "bodies": [b.name for b in bodies], "steps": int(res.steps),
        "end_time": float(history["time"][-1]),
        "wall_time_s": _time.perf_counter() - wall_start, "time_loop_s": loop,
        # one force evaluation per step: counted like one FV stage
        "node_stage_updates_per_second": n_nodes * res.steps / loop if loop > 0 else None,
        "final": last,
    }
    snapshots = []
    if out is not None:
        writer = SnapshotWriter(out, "fields")
        offsets = np.cumsum([0] + [len(b.points) for b in bodies])
        tris_all = np.concatenate([t + offsets[i] for i, t in enumerate(plot_tris)])
        for t, state in res.snapshots:
            pts = np.concatenate([state[b.name]["points"] for b in bodies])
            ref = np.concatenate([state[b.name]["reference_points"] for b in bodies])
            data = {key: np.concatenate([state[b.name][key] for b in bodies])
                    for key in ("velocity", "pressure", "von_mises")}
            data["displacement"] = pts - ref
            data["body"] = np.repeat(np.arange(len(bodies)), np.diff(offsets)).astype(float)
            writer.write(t, pts, tris_all, data)
        snapshots = writer.entries
        write_history_csv(out / "history.csv", history, len(history["time"]))
        summary["wall_time_s"] = _time.perf_counter() - wall_start
        write_summary(out / "summary.json", summary)
    return RunResult(history, fields, summary, out, snapshots)

