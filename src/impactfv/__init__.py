"""impactfv: fast transient large-strain solid dynamics with contact, by an upwind
vertex-centred finite volume method (p-F mixed formulation, Total Lagrangian).

``load_case`` and ``run`` are imported on first use, so that the command line can install
its signal handlers before numpy, numba and the case schema are loaded."""

from .version import __version__
from .backends import threads as _threads  # noqa: F401  (passive OpenMP waits, first)
from .errors import InputError, SimulationError

__all__ = ["load_case", "run", "InputError", "SimulationError", "__version__"]


def __getattr__(name):
    if name == "load_case":
        from .case import load_case
        return load_case
    if name == "run":
        from .pipeline import run
        return run
    raise AttributeError(f"module 'impactfv' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
