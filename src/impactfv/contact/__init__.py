"""Contact between deformable bodies and against rigid walls, by acoustic Riemann states."""

from .system import ContactSystem
from .overlap import find_overlaps

__all__ = ["ContactSystem", "find_overlaps"]
