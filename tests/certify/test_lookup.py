"""The compiled lookups of a region map (pipeline.certify.lookup): the leaf of every point, one at a
time (leaf_of) and in a batch (leaves_of, RegionMap.leaf_indices), is the NumPy route's
(Subpaving.leaf_indices), the stored bounds are the map's columns, no map
and points outside the box give -1, and values past the map's axes are not read."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline import load_coefficients
from pipeline.certify.lookup import COMPILED, LOOKUP_TREE, NO_TABLES, leaf_of
from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
from pipeline.certify.region_map import RegionMap


@pytest.fixture(scope="module")
def small_map() -> RegionMap:
    return certify_range(load_coefficients("paper"), RangeCertificateConfig(min_cell=1 / 16, boundary_cell=1 / 8))


def test_leaves_are_the_vectorised_lookups_and_bounds_the_maps_columns(small_map: RegionMap) -> None:
    tables = small_map.lookup_tables
    assert tables.index[0] == LOOKUP_TREE and tables.index.dtype == np.int32 and tables.bounds.dtype == float
    rng = np.random.default_rng(4)
    (l_lo, l_hi), (w_lo, w_hi) = small_map.ranges_m
    cells = 2**small_map.subpaving.top
    L = np.concatenate([rng.uniform(l_lo, l_hi, 500), l_lo + (l_hi - l_lo) * rng.integers(0, cells + 1, 500) / cells])
    W = np.concatenate([rng.uniform(w_lo, w_hi, 500), w_lo + (w_hi - w_lo) * rng.integers(0, cells + 1, 500) / cells])
    expected = small_map.subpaving.leaf_indices((L, W))  # the NumPy route
    np.testing.assert_array_equal(small_map.leaf_indices(L, W), expected)  # the compiled batch
    for scalar in (leaf_of, COMPILED["leaf_of"]):  # the source's JIT, and the route the map calls
        found = [scalar(*tables, 2, length, width, math.nan, math.nan) for length, width in zip(L, W, strict=True)]
        np.testing.assert_array_equal(found, expected)  # NaN past the two axes: never read
    for leaf in np.unique(expected).tolist():
        clearance, endpoint, status = tables.leaf_bounds(2, leaf)
        assert clearance == small_map.clearance_bound_m[leaf] and endpoint == small_map.endpoint_bound_m[leaf]
        assert status == small_map.status[leaf]


def test_outside_the_box_and_without_a_map_there_is_no_leaf(small_map: RegionMap) -> None:
    tables = small_map.lookup_tables
    l_hi, (w_lo, w_hi) = small_map.range_of("L")[1], small_map.range_of("W")
    for scalar in (leaf_of, COMPILED["leaf_of"]):
        for length, width in ((math.nextafter(l_hi, 1.0), 0.1), (0.25, math.nextafter(w_lo, 0.0)), (math.nan, 0.1)):
            assert scalar(*tables, 2, length, width, 0.0, 0.0) == -1
        assert scalar(*tables, 2, l_hi, w_hi, 0.0, 0.0) >= 0  # the box's far corner is in it
        assert scalar(*NO_TABLES, 2, 0.25, 0.1, 0.0, 0.0) == -1
