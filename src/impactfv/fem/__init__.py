"""Explicit finite-element baselines (linear T3 and mean-dilatation Q4) with kinematic contact.

See :mod:`impactfv.fem.stepper` for the formulation, the mean-dilatation derivation and the
contact algorithm (kinematic predictor-corrector, node-to-segment, two-pass, binned search).
"""

from .elements import element_pressure_von_mises, internal_forces
from .stepper import METHODS, FEStepper, FemBody, FemContact, reference_geometry

__all__ = ["FEStepper", "FemBody", "FemContact", "METHODS", "element_pressure_von_mises",
           "internal_forces", "reference_geometry"]
