"""The region map's leaves as drawn (verify.acceptance.map_leaves): rectangles equal to the map's
own cells and tiling the range, colours from each status's hue, darkest at its smallest bound."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pipeline.certify.region_map import STATUSES, RegionMap
from verify.acceptance.map_leaves import STATUS_SHADES, leaf_drawing, leaf_rectangles_m, shade


@pytest.fixture
def small_map(quadrant_map) -> RegionMap:
    """Every status present, one leaf with no bound (-inf)."""
    return quadrant_map([0.012, 0.020, 0.008, 0.009, -math.inf, 0.003, 0.015], [0, 0, 1, 1, 3, 2, 0])


def test_rectangles_are_the_maps_cells_and_tile_the_range(small_map: RegionMap) -> None:
    region_map = small_map
    rectangles = leaf_rectangles_m(region_map)
    for leaf, (l0, l1, w0, w1) in enumerate(rectangles):
        cell = region_map.cell(leaf)
        assert_allclose([l0, l1], cell.range_of("L"), rtol=0, atol=1e-15)
        assert_allclose([w0, w1], cell.range_of("W"), rtol=0, atol=1e-15)
    areas = (rectangles[:, 1] - rectangles[:, 0]) * (rectangles[:, 3] - rectangles[:, 2])
    assert areas.sum() == pytest.approx(0.1 * 0.04, rel=1e-12)


def test_colours_follow_status_and_bound(small_map: RegionMap) -> None:
    drawing = leaf_drawing(small_map)
    dark = {name: np.array(STATUS_SHADES[name][0]) for name in STATUSES}
    light = {name: np.array(STATUS_SHADES[name][1]) for name in STATUSES}
    # margin: bounds 0.012, 0.020, 0.015 -> 0.012 darkest, 0.020 lightest, 0.015 at 3/8 of the way.
    assert_allclose(drawing.rgb[0], dark["margin"], atol=1e-12)
    assert_allclose(drawing.rgb[1], light["margin"], atol=1e-12)
    assert_allclose(drawing.rgb[6], dark["margin"] + 0.375 * (light["margin"] - dark["margin"]), atol=1e-12)
    assert drawing.bound_range_m["margin"] == (0.012, 0.020)
    # collision-free: 0.008 darkest, 0.009 lightest.
    assert_allclose(drawing.rgb[[2, 3]], np.stack([dark["collision_free"], light["collision_free"]]), atol=1e-12)
    # A single finite bound (infeasible) is drawn light; -inf (undecided) darkest, with no scale.
    assert_allclose(drawing.rgb[5], light["infeasible"], atol=1e-12)
    assert_allclose(drawing.rgb[4], dark["undecided"], atol=1e-12)
    assert drawing.bound_range_m["undecided"] is None
    assert np.all((drawing.rgb >= 0) & (drawing.rgb <= 1))


def test_shade_clips_to_the_scale() -> None:
    assert_allclose(shade("margin", np.array([-1.0, 2.0])), [STATUS_SHADES["margin"][0], STATUS_SHADES["margin"][1]])
