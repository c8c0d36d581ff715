"""Loads that may change in time and space: the prescribed boundary velocities and tractions
of ``[[body.boundary]]`` and the body forces of ``[[body]]`` (seed eq. 9a's f_R), evaluated
at the time of each Runge-Kutta stage into the arrays the kernels read (docs/case-file.md).

A component is a number or an expression of the reference position x, y (z) and the time t;
a boundary entry's ``amplitude`` table [[t0, a0], [t1, a1], ...] scales all its components,
linearly between its points and constant beyond them (as Abaqus's *AMPLITUDE). Tractions and
velocities of a boundary face are taken at its closure point, (5 X_a + X_b) / 6 in 2D and
(6 X_a + X_b + X_c) / 8 in 3D (the point whose state the boundary flux uses); prescribed
nodal velocities at the node. Loads that do not vary are evaluated once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..case import LOAD_VARIABLES, Case
from ..errors import InputError, SimulationError
from ..expr import compile_expression


@dataclass
class _Component:
    index: int          # Cartesian component
    value: object       # float, or a compiled expression f(x, y, [z], t)
    key: str            # the case key, for errors

    @property
    def varies(self) -> bool:
        return not isinstance(self.value, float)

    def at(self, points, t):
        if not self.varies:
            return self.value
        out = self.value(*points.T, np.full(len(points), t))
        if not np.all(np.isfinite(out)):
            message = f"{self.key}: the expression gives non-finite values at t = {t:.6g} s"
            if t > 0.0:
                # the case was good until now: a failed simulation, whose outputs are kept
                raise SimulationError(message, time=t)
            raise InputError(message)
        return out


@dataclass
class _Row:
    """One [[body.boundary]] entry: its faces (rows of the face arrays), its region's nodes
    and the prescribed components."""

    faces: np.ndarray
    nodes: np.ndarray
    velocity: list
    traction: list
    amplitude: np.ndarray | None

    def scale(self, t) -> float:
        if self.amplitude is None:
            return 1.0
        return float(np.interp(t, self.amplitude[:, 0], self.amplitude[:, 1]))


def _components(values, key, dim):
    names = LOAD_VARIABLES[:dim] + ("t",)
    out = []
    for c, item in enumerate(values[:dim]):
        if item is None:
            continue
        where = f"{key}.{'xyz'[c]}"
        if isinstance(item, str):
            item = compile_expression(item, where, names)
        else:
            item = float(item)
        out.append(_Component(c, item, where))
    return out


class Loads:
    """The prescribed boundary values and body forces of a case at a given time.

    ``face_velocity`` and ``face_traction`` (h, d) hold each dual boundary face's prescribed
    velocity and traction (zero where the face is free), ``fixed_value`` (n, d) the strongly
    prescribed nodal velocities and ``acceleration`` (n, d) the body force per unit mass.
    """

    def __init__(self, case: Case, disc):
        n, d = disc.n_nodes, disc.dim
        h = len(disc.bface_node)
        self.face_velocity = np.zeros((h, d))
        self.face_traction = np.zeros((h, d))
        self.fixed_value = np.zeros((n, d))
        self.acceleration = np.zeros((n, d))
        own, denominator = disc.closure
        others = disc.X[disc.bface_others].sum(axis=1) if h else np.zeros((0, d))
        self.face_points = (own * disc.X[disc.bface_node] + others) / denominator
        self.X = disc.X
        self.rows = []
        row = 0
        for ib, body in enumerate(case.bodies):
            for j, spec in enumerate(body.boundary):
                row += 1
                key = f"{case.source}: body[{ib}].boundary[{j}]"
                velocity = spec.velocity.components(3) if spec.velocity is not None else ()
                self.rows.append(_Row(
                    faces=np.flatnonzero(disc.bface_bc == row),
                    nodes=disc.bc_nodes[row],
                    velocity=_components(list(velocity), key + ".velocity", d),
                    traction=_components(list(spec.traction or ()), key + ".traction", d),
                    amplitude=None if spec.amplitude is None else np.array(spec.amplitude)))
        self.body_forces = []
        for ib, (body, layout) in enumerate(zip(case.bodies, disc.bodies)):
            if body.spec.body_force is not None:
                self.body_forces.append((slice(layout.start, layout.stop), _components(
                    list(body.spec.body_force), f"{case.source}: body[{ib}].body_force", d)))
        self.varies = any(r.amplitude is not None or any(c.varies for c in r.velocity + r.traction)
                          for r in self.rows) or \
            any(c.varies for _, comps in self.body_forces for c in comps)
        self.has_body_force = bool(self.body_forces)
        self._evaluate(0.0)
        self.time = 0.0

    def at(self, t: float):
        """Bring the arrays to time t (nothing to do when no load varies)."""
        if self.varies and t != self.time:
            self._evaluate(t)
            self.time = t

    def _evaluate(self, t: float):
        # rows in case order, so that a later entry's nodal value wins (as its mask does)
        for row in self.rows:
            a = row.scale(t)
            points = self.face_points[row.faces]
            for comp in row.velocity:
                self.face_velocity[row.faces, comp.index] = a * comp.at(points, t)
                self.fixed_value[row.nodes, comp.index] = a * comp.at(self.X[row.nodes], t)
            for comp in row.traction:
                self.face_traction[row.faces, comp.index] = a * comp.at(points, t)
        for nodes, comps in self.body_forces:
            for comp in comps:
                self.acceleration[nodes, comp.index] = comp.at(self.X[nodes], t)
