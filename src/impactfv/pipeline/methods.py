"""The choice of method: a case's ``run.method`` names the stepper that runs it."""

from __future__ import annotations

from ..case import Case


def make_stepper(case: Case):
    """The stepper of ``case.run.method``: "fv" (the upwind vertex-centred finite volume
    scheme) or one of the explicit FE baselines "fem-t3" and "fem-q4md"."""
    if case.run.method == "fv":
        from ..scheme.stepper import FVStepper
        return FVStepper(case)
    from ..fem.stepper import FEStepper
    return FEStepper.from_case(case)
