"""Contact surfaces: which boundary facets of a body take part in a contact."""

from __future__ import annotations

import numpy as np

from ..errors import InputError


def surface_facets(boundary, regions, wanted, key: str, body: str) -> np.ndarray:
    """The facets of ``body``'s contact surface: its whole ``boundary`` (oriented facets), or
    when ``wanted`` names regions, the union of those of its ``regions`` (name -> facets) it
    has, sorted. ``key`` names the case entry in the error raised when it has none."""
    if wanted is None:
        return np.ascontiguousarray(boundary, dtype=np.int64)
    found = [regions[r] for r in wanted if r in regions]
    if not found:
        raise InputError(f"{key}: body {body!r} has none of {', '.join(wanted)} (it has: "
                         f"{', '.join(sorted(regions)) or 'none'})")
    return np.ascontiguousarray(np.unique(np.concatenate(found), axis=0), dtype=np.int64)
