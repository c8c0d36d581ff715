"""``impactfv check``: what a run would do, without running it."""

from __future__ import annotations

import math

import numpy as np

from .case import Case
from .materials import CP
from .scheme.discretisation import discretise

# float64 work arrays per node the FV stepper allocates beyond the discretisation
# (scheme.stepper.FVStepper): v, F, x, their stage copies, P, grad, vmin, vmax, phi, force, dF
def _stepper_doubles_per_node(d):
    return 2 * (d + d * d + d) + d * d + d * d + 3 * d + d + d * d


def check_report(case: Case) -> str:
    return check_case(case)[0]


def check_case(case: Case) -> tuple[str, list[str]]:
    """The report of ``impactfv check`` and the problems in it that ``run`` would refuse."""
    from .pipeline.run import step_count_problem

    problems = []
    disc = discretise(case)
    lines = [f"case: {case.source}" + (f"  ({case.title})" if case.title else "")]
    for body in case.bodies:
        q = body.mesh.quality()
        mat = body.material
        if body.mesh.dim == 2:
            quads = "" if body.mesh.quads is None else \
                f" (cut from {len(body.mesh.quads)} quadrilaterals)"
            lines.append(f"body {body.name!r}: {q['nodes']} nodes, {q['triangles']} triangles"
                         f"{quads}, area {q['area']:.6g} m^2")
            angle = f"min angle {q['min_angle_deg']:.1f} deg"
        else:
            lines.append(f"body {body.name!r}: {q['nodes']} nodes, {q['tetrahedra']} "
                         f"tetrahedra, volume {q['volume']:.6g} m^3")
            angle = f"min dihedral angle {q['min_dihedral_deg']:.1f} deg"
        lines.append(f"  edges {q['edge_length_min']:.4g} .. {q['edge_length_max']:.4g} m, "
                     f"max aspect ratio {q['aspect_ratio_max']:.3g}, {angle}")
        lines.append(f"  material {mat.name!r} ({mat.law}): c_p = {mat.p_wave_speed:.2f} m/s, "
                     f"c_s = {mat.s_wave_speed:.2f} m/s, impedance rho c_p = "
                     f"{mat.p_impedance:.4g} kg/(m^2 s)")
        facet = "edges" if body.mesh.dim == 2 else "faces"
        regions = ", ".join(f"{k} ({len(v)} {facet})"
                            for k, v in sorted(body.mesh.regions.items()))
        lines.append(f"  boundary regions: {regions or 'none'}")
        for name, why in sorted(body.mesh.skipped_sets.items()):
            lines.append(f"  named set {name!r} is no region: {why}")
    h_over_c = float(np.min(disc.node_length / disc.material_table[disc.node_material, CP]))
    dt = case.run.cfl * h_over_c
    steps = math.ceil(case.run.end_time / dt)
    nbytes = sum(a.nbytes for a in vars(disc).values() if isinstance(a, np.ndarray))
    nbytes += 8 * _stepper_doubles_per_node(disc.dim) * disc.n_nodes
    lines.append(f"time step: {dt:.4e} s (cfl {case.run.cfl}) at the start; about {steps} steps "
                 f"to {case.run.end_time:.4e} s ({2 * steps} Runge-Kutta stages)")
    if (problem := step_count_problem(case, dt)):
        problems.append(problem)
        lines.append(f"PROBLEM: {problem} (run will refuse this case)")
    lines.append(f"scheme: {case.run.method}, order {case.run.order}, limiter "
                 f"{case.run.limiter}")
    lines.append(f"memory: about {nbytes / 2**20:.1f} MiB for the state and work arrays "
                 f"({nbytes / disc.n_nodes:.0f} bytes per node, {disc.n_nodes} nodes, "
                 f"{disc.n_edges} edges)")
    if case.contacts:
        from .geometry.penetration import find_overlaps
        for k, c in enumerate(case.contacts):
            partner = "a rigid wall" if c.wall is not None else repr(c.bodies[1])
            lines.append(f"contact[{k}]: {c.bodies[0]!r} with {partner}, model {c.model}")
        overlaps = find_overlaps(case)
        lines += [f"PROBLEM: {p} (run will refuse this case)" for p in overlaps]
        if not overlaps:
            lines.append("no bodies overlap at the start")
        problems += overlaps
    return "\n".join(lines), problems
