"""``impactfv check``: what a run would do, without running it."""

from __future__ import annotations

import math

import numpy as np

from .case import Case
from .physics.materials import CP
from .scheme.discretisation import discretise

def check_report(case: Case) -> str:
    return check_case(case)[0]


def check_case(case: Case) -> tuple[str, list[str]]:
    """The report of ``impactfv check`` and the problems in it that ``run`` would refuse."""
    from .memory import available_bytes, estimate_case, format_bytes, memory_problem
    from .pipeline.run import expected_steps, step_count_problem

    problems = []
    available = available_bytes()
    if (problem := memory_problem(estimate_case(case), available)):
        # the scheme's arrays would not fit: report the meshes and the memory only
        disc = None
    else:
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
    if disc is not None:
        h_over_c = float(np.min(disc.node_length /
                                disc.material_table[disc.node_material, CP]))
        dt = case.run.cfl * h_over_c
        steps = math.ceil(case.run.end_time / dt)
        lines.append(f"time step: {dt:.4e} s (cfl {case.run.cfl}) at the start; about {steps} "
                     f"steps to {case.run.end_time:.4e} s ({2 * steps} Runge-Kutta stages)")
        if (problem := step_count_problem(case, dt)):
            problems.append(problem)
            lines.append(f"PROBLEM: {problem} (run will refuse this case)")
        memory = estimate_case(case, expected_steps(case, dt))
    else:
        lines.append("time step: not computed (the case does not fit in the memory available)")
        memory = estimate_case(case)
    lines.append(f"scheme: {case.run.method}, order {case.run.order}, limiter "
                 f"{case.run.limiter}")
    shown = f"{format_bytes(available)} available" if available is not None else \
        "an unknown amount available"
    lines.append(f"memory: {memory.describe()}, of {shown}")
    if (problem := memory_problem(memory, available)):
        problem = f"the run {problem}"
        problems.append(problem)
        lines.append(f"PROBLEM: {problem} (run will refuse this case)")
    if case.contacts:
        from .geometry.penetration import find_overlaps
        for k, c in enumerate(case.contacts):
            partner = "a rigid wall" if c.wall is not None else "itself" if c.self_contact \
                else repr(c.bodies[1])
            law = f"coulomb, friction {c.friction}" if c.model == "coulomb" else c.model
            lines.append(f"contact[{k}]: {c.bodies[0]!r} with {partner}, model {law}")
        overlaps = find_overlaps(case)
        lines += [f"PROBLEM: {p} (run will refuse this case)" for p in overlaps]
        if not overlaps:
            lines.append("no bodies overlap at the start")
        problems += overlaps
    return "\n".join(lines), problems
