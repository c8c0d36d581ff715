"""Contact between deformable bodies and against rigid walls, by acoustic Riemann states.

laws (point functions of seed eqs. 5-8) -> search (partners, gaps) -> overlap (pieces of the
dual boundary faces in contact) -> riemann_step (states, forces, contact velocities) ->
driver (ContactSystem: one stage of all of it, and what enters the FV rates).
"""
