"""Observed order of accuracy on the smooth standing wave (numerics.md H.4)."""

import json
import os

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


@pytest.mark.parametrize("order,minimum", [(2, 1.8), (1, 0.9)])
def test_convergence_order_fast(order, minimum):
    rows, rates = observed(order, "none", [8, 16, 32])
    assert min(r[0] for r in rates) >= minimum, (rows, rates)
    assert min(r[1] for r in rates) >= minimum, (rows, rates)


@pytest.mark.slow
@pytest.mark.parametrize("order,minimum", [(2, 1.8), (1, 0.9)])
def test_convergence_order_full(order, minimum):
    rows, rates = observed(order, "none", [8, 16, 32, 64, 128])
    assert min(r[0] for r in rates[-3:]) >= minimum, (rows, rates)
    assert min(r[1] for r in rates[-3:]) >= minimum, (rows, rates)
