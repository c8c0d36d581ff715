"""Meshes: generators, file readers, checks, edges and boundary facets, the median dual."""

from .core import Mesh, renumber_for_locality, validate_and_orient
from .edges import boundary_facets, unique_edges
from .generators import (DIAGONAL_PATTERNS, annulus, disc, quads_to_triangles, rectangle,
                         rectangle_quads)
from .reader import read_mesh
from .dual import MedianDual, median_dual

__all__ = ["Mesh", "renumber_for_locality", "validate_and_orient", "boundary_facets",
           "unique_edges", "DIAGONAL_PATTERNS", "annulus", "disc", "quads_to_triangles",
           "rectangle", "rectangle_quads", "read_mesh", "MedianDual", "median_dual"]
