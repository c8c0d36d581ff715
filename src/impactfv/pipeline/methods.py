"""The choice of method: a case's ``run.method`` names the stepper that runs it."""

from __future__ import annotations

from ..case import Case


def make_stepper(case: Case):
    """The stepper of ``case.run.method``: "fv" (the upwind vertex-centred finite volume
    scheme) or one of the explicit FE baselines "fem-t3" and "fem-q4md". ``run.backend``
    "cuda" (the FV scheme on a GPU) is refused here with one line when it cannot run."""
    if case.run.backend == "cuda":
        from ..backends.cuda import problem
        from ..errors import InputError
        why = problem(case)
        if why:
            raise InputError(f"{case.source}: {why}")
    from ..parallel.comm import world
    comm = world()
    if comm is not None:          # started by mpiexec on several ranks (docs/parallel.md)
        if case.run.method != "fv":
            from ..errors import InputError
            raise InputError(f"{case.source}: run.method = {case.run.method!r} runs on one "
                             "rank; the FV scheme runs on several (start it without mpiexec)")
        from ..parallel.stepper import ParallelFVStepper
        return ParallelFVStepper(case, comm)
    if case.run.method == "fv":
        from ..scheme.stepper import FVStepper
        return FVStepper(case)
    from ..fem.stepper import FEStepper
    return FEStepper.from_case(case)
