"""Refinement studies of contact (docs/validation.md, "Refinement studies")."""

import numpy as np
import pytest

from impactfv.validation.refinement import (block_on_slab_study, seed_bars_case,
                                            seed_bars_study)


def test_seed_case_is_the_paper_geometry():
    data = seed_bars_case(0.2e-3)
    left, right = data["body"]
    assert left["mesh"]["divisions"] == [162, 32]
    assert np.isclose(right["mesh"]["origin"][0] - (left["mesh"]["origin"][0] + 32.4e-3),
                      0.2e-3)
    with pytest.raises(ValueError, match="does not divide"):
        seed_bars_case(0.3e-3)


def check_seed(out, force_order, axis_order):
    """Successive differences fall on every refinement; observed orders on the finest pair."""
    for key in ("force_diff", "axis_diff"):
        d = out[key]
        assert all(b < a for a, b in zip(d, d[1:])), (key, d)
    assert out["force_order"][-1] >= force_order, out["force_order"]
    assert out["axis_order"][-1] >= axis_order, out["axis_order"]
    # no spike at the touch: the total force never exceeds the 1D acoustic value
    # rho c_p v0 x width (the free sides' release waves only lower it, towards the much
    # smaller bar-wave level, within a few microseconds)
    assert max(f.max() for f in out["force"]) <= 1.02 * out["p_ref"] * 6.4e-3


def test_seed_bars_converge_fast():
    # 10 us of contact on h = 0.4, 0.2, 0.1 mm (about 30 s on one core)
    out = seed_bars_study((0.4e-3, 0.2e-3, 0.1e-3), after_touch=10e-6)
    check_seed(out, force_order=0.8, axis_order=0.5)


@pytest.mark.slow
def test_seed_bars_converge_full():
    # the paper's snapshot (20 us after the touch) on h = 0.4 .. 0.05 mm (about 6 minutes)
    out = seed_bars_study((0.4e-3, 0.2e-3, 0.1e-3, 0.05e-3))
    check_seed(out, force_order=0.8, axis_order=0.5)


def test_block_on_slab_has_no_grid_scale_pattern():
    # A two-cell (diamond) pattern would keep the grid-scale pressure at a fixed size under
    # refinement (order 0); a smooth field with fronts makes it fall at order 1 to 2.
    out = block_on_slab_study((20, 40, 80))
    g = out["grid_scale"]
    assert all(b < a for a, b in zip(g, g[1:])), g
    assert min(out["order"]) >= 1.0, out["order"]
    assert g[-1] < 0.005, g
