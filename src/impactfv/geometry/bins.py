"""Uniform bins over the facets of a surface: the search that keeps contact cost linear in
the surface size.

Each facet is registered in every bin its bounding box, grown by ``pad``, meets; a point then
finds every facet within ``pad`` of it (and a few more) in the one bin that contains it. The
bin count is kept proportional to the number of facets. Works in any dimension.
"""

import math

import numpy as np
from numba import njit


@njit(cache=True, inline="always", error_model="numpy")
def _facet_box(x, facets, f, pad, lo, hi):
    """The bounding box of facet f grown by pad, into lo and hi."""
    d = x.shape[1]
    for k in range(d):
        lo[k] = np.inf
        hi[k] = -np.inf
    for j in range(facets.shape[1]):
        a = facets[f, j]
        for k in range(d):
            lo[k] = min(lo[k], x[a, k] - pad)
            hi[k] = max(hi[k], x[a, k] + pad)


@njit(cache=True, error_model="numpy")
def _register(x, facets, pad, lo, h, shape, count, items, fill):
    """Count (fill False: count[c + 1] += 1) or list (fill True, count holding the bin
    starts) each facet in every bin its padded box meets, facets in order."""
    d = x.shape[1]
    cursor = count[:-1].copy()
    i_lo = np.empty(d, np.int64)
    i_hi = np.empty(d, np.int64)
    idx = np.empty(d, np.int64)
    flo = np.empty(d)
    fhi = np.empty(d)
    for f in range(facets.shape[0]):
        _facet_box(x, facets, f, pad, flo, fhi)
        for k in range(d):
            i_lo[k] = max(int((flo[k] - lo[k]) / h), 0)
            i_hi[k] = min(int((fhi[k] - lo[k]) / h), shape[k] - 1)
            idx[k] = i_lo[k]
        while True:
            c = 0
            for k in range(d - 1, -1, -1):
                c = c * shape[k] + idx[k]
            if fill:
                items[cursor[c]] = f
                cursor[c] += 1
            else:
                count[c + 1] += 1
            k = 0
            while k < d:
                idx[k] += 1
                if idx[k] <= i_hi[k]:
                    break
                idx[k] = i_lo[k]
                k += 1
            if k == d:
                break


@njit(cache=True, error_model="numpy")
def build_bins(x, facets, pad):
    """Bins of the facets at positions x: returns (origin, h, shape, start, items).

    Bin with integer coordinates (i_0, ..., i_{d-1}) has the flat index
    c = i_0 + shape_0 (i_1 + shape_1 i_2) and holds items[start[c]:start[c+1]].
    """
    d = x.shape[1]
    m = facets.shape[0]
    lo = np.full(d, np.inf)
    hi = np.full(d, -np.inf)
    flo = np.empty(d)
    fhi = np.empty(d)
    lmax = 0.0
    for f in range(m):
        _facet_box(x, facets, f, 0.0, flo, fhi)
        size = 0.0
        for k in range(d):
            lo[k] = min(lo[k], flo[k])
            hi[k] = max(hi[k], fhi[k])
            size += (fhi[k] - flo[k]) ** 2
        lmax = max(lmax, math.sqrt(size))
    for k in range(d):
        lo[k] -= pad
        hi[k] += pad
    h = max(lmax, pad, 1e-300)
    shape = np.empty(d, np.int64)
    while True:
        total = 1
        for k in range(d):
            shape[k] = int((hi[k] - lo[k]) / h) + 1
            total *= shape[k]
        if total <= 4 * m + 16:
            break
        h *= 2.0
    count = np.zeros(total + 1, np.int64)
    items = np.empty(0, np.int64)
    _register(x, facets, pad, lo, h, shape, count, items, False)
    for c in range(total):
        count[c + 1] += count[c]
    items = np.empty(count[total], np.int64)
    _register(x, facets, pad, lo, h, shape, count, items, True)
    return lo, h, shape, count, items


@njit(cache=True, inline="always", error_model="numpy")
def bin_of(point, origin, h, shape):
    """Flat index of the bin containing ``point``, or -1 outside the bins."""
    c = 0
    for k in range(origin.shape[0] - 1, -1, -1):
        i = int(math.floor((point[k] - origin[k]) / h))
        if i < 0 or i >= shape[k]:
            return -1
        c = c * shape[k] + i
    return c
