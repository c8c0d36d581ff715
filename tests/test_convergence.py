"""Observed order of accuracy on the smooth standing wave (docs/validation.md)."""

import numpy as np
import pytest

from impactfv import load_case, run
from impactfv.validation.standing_wave import case_dict, errors


def observed(order, limiter, divisions):
    rows = []
    for n in divisions:
        data = case_dict(n, order=order, limiter=limiter)
        ev, es = errors(run(load_case(data)), data)
        rows.append((n, ev, es))
    rates = [(np.log2(a[1] / b[1]), np.log2(a[2] / b[2])) for a, b in zip(rows, rows[1:])]
    return rows, rates


def check(rows, rates, minimum):
    """Errors fall on every refinement; the observed order (two finest meshes) >= minimum."""
    for field in (1, 2):
        assert all(b[field] < a[field] for a, b in zip(rows, rows[1:])), rows
    assert rates[-1][0] >= minimum and rates[-1][1] >= minimum, (rows, rates)


@pytest.mark.parametrize("order,minimum", [(2, 1.8), (1, 0.9)])
def test_convergence_order_fast(order, minimum):
    rows, rates = observed(order, "none", [16, 32, 64])
    check(rows, rates, minimum)


@pytest.mark.slow
@pytest.mark.parametrize("order,minimum", [(2, 1.8), (1, 0.9)])
def test_convergence_order_full(order, minimum):
    rows, rates = observed(order, "none", [16, 32, 64, 128])
    check(rows, rates, minimum)
    assert min(min(r) for r in rates[1:]) >= minimum, (rows, rates)
