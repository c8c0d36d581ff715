"""Triangle meshes: generators, file readers, checks and the median dual."""

from .trimesh import TriMesh, boundary_edges_of
from .generators import rectangle, DIAGONAL_PATTERNS
from .reader import read_mesh
from .dual import MedianDual, median_dual

__all__ = ["TriMesh", "boundary_edges_of", "rectangle", "DIAGONAL_PATTERNS", "read_mesh",
           "MedianDual", "median_dual"]
