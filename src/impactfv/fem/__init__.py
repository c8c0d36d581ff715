"""Explicit finite-element baselines (linear T3 and mean-dilatation Q4) with kinematic contact.

See :mod:`impactfv.fem.solver` for the formulation, the mean-dilatation derivation and the
contact algorithm (kinematic predictor-corrector, node-to-segment, two-pass, cell-list search).
"""

from .mesh import boundary_edges, mesh_edges, quads_to_triangles, rectangle_quads
from .solver import (METHODS, FemBody, FemContact, FemResult, reference_geometry,
                     simulate_fem)
from .kernels import element_pressure_von_mises, internal_forces

__all__ = ["FemBody", "FemContact", "FemResult", "METHODS", "boundary_edges",
           "element_pressure_von_mises", "internal_forces", "mesh_edges",
           "quads_to_triangles", "rectangle_quads", "reference_geometry", "simulate_fem"]
