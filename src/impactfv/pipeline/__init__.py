"""One run pipeline for every method: the time loop, history, output and checkpoint schedule,
summary, progress display, signals, and the choice of method. Methods plug in as steppers
(impactfv.scheme.stepper.FVStepper, impactfv.fem.stepper.FEStepper) and never import back."""

from .result import Interrupted, RunResult
from .run import Schedule, run, run_stepper

__all__ = ["Interrupted", "RunResult", "Schedule", "run", "run_stepper"]
