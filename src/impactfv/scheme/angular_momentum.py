"""Discrete angular momentum projection: the interior fluxes exert no torque on a free body
(docs/theory.md, "Momentum: linear and angular").

The interior face forces of the scheme cancel in pairs (linear momentum is exact) but are not
parallel to their edges, so their torques do not cancel, and the upwind terms drift the
angular momentum of a spinning body. Per stage and per body without held velocity
components, the momentum rates of the interior fluxes f_a get the smallest correction (in
the mass-weighted norm) that removes their torque and leaves their sum:

    f_a <- f_a + m_a lambda x (y_a - y_c),      I_c lambda = -sum_a (y_a - y_c) x f_a^int,

a rigid angular acceleration lambda about the body's centre of mass y_c, with I_c its inertia
tensor about it (sum m (|r|^2 I - r (x) r); sum m |r|^2 in 2D). The boundary tractions
(prescribed loads), contact and body forces keep their torque. With the positions y the
stage's rates act at, the state's at the first stage and those the step ends at at the
second, the two-stage Runge-Kutta step changes the angular momentum sum_a m_a x_a x v_a by
exactly dt/2 (T_0 + T_1), T_s the torque of the external forces of stage s: to round-off
for a free body. (Write A = sum x x m v; with x* = x0 + dt v0, v* = v0 + dt f0 / m,
x1 = x0 + dt v0 + dt^2 f0 / (2 m) and m v1 = m v0 + dt (f0 + f1) / 2, every other term of
A1 - A0 cancels node by node: A1 = A0 + dt/2 sum x0 x f0 + dt/2 sum x1 x f1.)
"""

from __future__ import annotations

import numpy as np

from ..backends import cpu as K


class AngularMomentumProjection:
    """The angular momentum projection of an FVStepper's interior momentum rates; inactive
    when no body is free (every body holds a velocity component somewhere: supports supply
    torque)."""

    def __init__(self, stepper):
        s, m = stepper, stepper.disc
        self.s = s
        d = m.dim
        o = s.n_owned
        nb = len(m.bodies)
        held = np.zeros(nb)
        np.add.at(held, m.body_of_node[:o], m.fixed_mask[:o].any(axis=1))
        #: per body: no node of it (on any rank) holds a velocity component
        self.free = s._sum(held) == 0
        # each body's sums about its reference centroid (small r: no cancellation)
        moments = np.zeros((nb, 1 + d))
        np.add.at(moments, m.body_of_node[:o],
                  np.hstack([s.mass[:o, None], s.mass[:o, None] * m.X[:o]]))
        moments = s._sum(moments)
        self.origin = moments[:, 1:] / np.maximum(moments[:, :1], 1e-300)
        self.body = m.body_of_node.astype(np.int64)
        self.sums = np.zeros((nb, 4 + d + d * d))
        self.spin = np.zeros((nb, 3))
        self.y = np.empty((m.n_nodes, d))
        # the dual boundary faces of the free bodies' owned nodes, their area |C| and body
        faces = np.flatnonzero((m.bface_node < o)
                               & self.free[m.body_of_node[m.bface_node]])
        self.faces = faces
        self.face_area = np.linalg.norm(m.bface_C[faces], axis=1)
        self.face_body = m.body_of_node[m.bface_node[faces]]

    @property
    def active(self) -> bool:
        return bool(self.free.any())

    def project(self, last: bool, contact):
        """Correct stepper.force (the interior and boundary fluxes of the stage, before
        contact and body forces) at the owned nodes of the free bodies. ``last``: the last
        stage; ``contact``: the stage's ContactStage (contact velocities)."""
        s, m = self.s, self.s.disc
        o, d = s.n_owned, m.dim
        K.projection_positions(last, s.dt, s.x0, s.x, s.v, contact.state, contact.xdot, o,
                               self.y)
        K.body_moments(self.y, s.mass, s.force, self.body, o, self.origin, self.sums)
        sums = s._sum(self.sums.copy())
        sums[:, 1 + d + d * d:] -= self._load_torque(contact.face_weight)
        mass = sums[:, 0]
        first = sums[:, 1:1 + d]
        second = sums[:, 1 + d:1 + d + d * d].reshape(-1, d, d)
        torque = sums[:, 1 + d + d * d:]
        centre = first / mass[:, None]
        self.spin[:] = 0.0
        for k in np.flatnonzero(self.free):
            # second moment about the centre of mass, then the inertia tensor
            J = second[k] - mass[k] * np.outer(centre[k], centre[k])
            if d == 2:
                self.spin[k, 2] = -torque[k, 2] / np.trace(J)
            else:
                inertia = np.trace(J) * np.eye(3) - J
                self.spin[k] = -np.linalg.lstsq(inertia, torque[k], rcond=1e-12)[0]
        K.add_rigid_spin(self.y, s.mass, self.body, o, centre + self.origin, self.spin,
                         s.force)

    def _load_torque(self, face_weight):
        """The torque of the prescribed tractions on the free bodies' boundary faces (their
        Riemann traction is the prescribed one), per body, about each body's origin."""
        m, s = self.s.disc, self.s
        nb, d = len(m.bodies), m.dim
        torque = np.zeros((nb, 3))
        traction = s.loads.face_traction[self.faces]
        loaded = np.flatnonzero(traction.any(axis=1))
        if not len(loaded):
            return s._sum(torque)
        h = self.faces[loaded]
        body = self.face_body[loaded]
        f = traction[loaded] * ((1.0 - face_weight[h]) * self.face_area[loaded])[:, None]
        r = self.y[m.bface_node[h]] - self.origin[body]
        if d == 2:
            np.add.at(torque[:, 2], body, r[:, 0] * f[:, 1] - r[:, 1] * f[:, 0])
        else:
            np.add.at(torque, body, np.cross(r, f))
        return s._sum(torque)
