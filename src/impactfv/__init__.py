"""impactfv: fast transient large-strain solid dynamics with contact, by an upwind
vertex-centred finite volume method (p-F mixed formulation, Total Lagrangian)."""

__version__ = "0.1.0"

from .errors import InputError, SimulationError  # noqa: E402
from .case import load_case  # noqa: E402
from .pipeline import run  # noqa: E402

__all__ = ["load_case", "run", "InputError", "SimulationError", "__version__"]
