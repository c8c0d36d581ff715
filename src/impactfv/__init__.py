"""impactfv: fast transient large-strain solid dynamics with contact, by an upwind
vertex-centred finite volume method (p-F mixed formulation, Total Lagrangian)."""

from .version import __version__
from .backends import threads as _threads  # noqa: F401  (passive OpenMP waits, first)
from .errors import InputError, SimulationError
from .case import load_case
from .pipeline import run

__all__ = ["load_case", "run", "InputError", "SimulationError", "__version__"]
