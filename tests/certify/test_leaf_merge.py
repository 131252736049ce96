"""Merging sibling leaves (``pipeline.certify.leaf_merge``) against a brute-force reading of the
leaves: every merged leaf is the union of original leaves, all of one status and one side of the
tolerance, whose bounds it bounds and which differ by at most the spread; the merged leaves tile
the box."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline.certify.leaf_merge import merge_leaves
from pipeline.certify.subpaving import Subpaving
from pipeline.exceptions import InvalidParameterError

RANGES = ((0.2, 0.3), (0.08, 0.12), (-0.03, 0.03))
TOLERANCE_M = 0.002


def _inside(levels: np.ndarray, index: np.ndarray, outer_levels: np.ndarray, outer_index: np.ndarray) -> np.ndarray:
    """(n, m) whether original leaf i lies inside merged leaf j (dyadic boxes: nested or apart)."""
    shift = levels[:, None, :] - outer_levels[None, :, :]
    return np.all((shift >= 0) & ((index[:, None, :] >> np.maximum(shift, 0)) == outer_index[None, :, :]), axis=2)


def _draw(random_leaves, seed: int, cuts: int, k: int = 3):
    rng = np.random.default_rng(seed)
    levels, index = random_leaves(k, cuts, rng)
    n = levels.shape[0]
    status = rng.integers(0, 2, n)  # few codes and bounds on a coarse grid, so that many pairs agree
    clearance = 0.01 + rng.integers(0, 3, n) * 5e-5
    endpoint = 0.0019 + rng.integers(0, 3, n) * 1e-4
    upper = np.where(rng.random(n) < 0.5, np.inf, 0.009 + rng.integers(0, 3, n) * 5e-5)
    return levels, index, status, (clearance, endpoint, upper)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), cuts=st.integers(0, 60), spread=st.sampled_from([0.0, 5e-5, 1e-4, 1.0]))
def test_merged_leaves_tile_the_box_and_bound_what_they_replace(random_leaves, seed: int, cuts: int, spread: float):
    levels, index, status, (clearance, endpoint, upper) = _draw(random_leaves, seed, cuts)
    out = merge_leaves(RANGES, levels, index, status, (clearance, endpoint, upper), TOLERANCE_M, spread)
    Subpaving.from_leaves(RANGES, out.levels, out.index)  # refuses gaps and overlaps
    assert np.sum(2.0 ** -out.levels.sum(axis=1).astype(float)) == pytest.approx(1.0, abs=1e-12)
    inside = _inside(levels, index, out.levels, out.index)
    assert np.all(inside.sum(axis=1) == 1)  # each original leaf in exactly one merged leaf
    owner = np.argmax(inside, axis=1)
    for j in range(out.levels.shape[0]):
        mine = owner == j
        assert np.unique(status[mine]).size == 1
        assert np.unique(endpoint[mine] <= TOLERANCE_M).size == 1
        assert out.clearance_bound_m[j] == clearance[mine].min()
        assert out.endpoint_bound_m[j] == endpoint[mine].max()
        assert out.endpoint_clearance_upper_m[j] == upper[mine].max()
        if mine.sum() > 1:
            assert clearance[mine].max() - clearance[mine].min() <= spread
            assert endpoint[mine].max() - endpoint[mine].min() <= spread


def test_leaves_that_agree_everywhere_become_the_whole_box(random_leaves) -> None:
    levels, index = random_leaves(3, 40, np.random.default_rng(3))
    n = levels.shape[0]
    ones = np.ones(n)
    out = merge_leaves(RANGES, levels, index, np.zeros(n, int), (0.01 * ones, 1e-3 * ones, np.inf * ones), 2e-3, 0.0)
    assert out.levels.tolist() == [[0, 0, 0]] and out.index.tolist() == [[0, 0, 0]]
    assert (out.clearance_bound_m[0], out.endpoint_bound_m[0]) == (0.01, 1e-3)


def test_siblings_of_other_statuses_or_sides_of_the_tolerance_stay_apart() -> None:
    levels = np.array([[1, 0, 0], [1, 0, 0]])
    index = np.array([[0, 0, 0], [1, 0, 0]])
    same = (np.array([0.01, 0.01]), np.array([1e-3, 1e-3]), np.array([np.inf, np.inf]))
    assert merge_leaves(RANGES, levels, index, np.array([0, 0]), same, 2e-3, 1.0).levels.shape[0] == 1
    assert merge_leaves(RANGES, levels, index, np.array([0, 1]), same, 2e-3, 1.0).levels.shape[0] == 2
    sides = (same[0], np.array([1.9e-3, 2.1e-3]), same[2])
    assert merge_leaves(RANGES, levels, index, np.array([0, 0]), sides, 2e-3, 1.0).levels.shape[0] == 2
    apart = (np.array([0.01, 0.0102]), same[1], same[2])
    assert merge_leaves(RANGES, levels, index, np.array([0, 0]), apart, 2e-3, 1e-4).levels.shape[0] == 2
    assert merge_leaves(RANGES, levels, index, np.array([0, 0]), apart, 2e-3, 3e-4).levels.shape[0] == 1


def test_bad_spreads_and_columns_are_refused() -> None:
    levels, index = np.zeros((1, 3), int), np.zeros((1, 3), int)
    one = (np.array([0.01]), np.array([1e-3]), np.array([np.inf]))
    with pytest.raises(InvalidParameterError, match="spread_m"):
        merge_leaves(RANGES, levels, index, np.array([0]), one, 2e-3, -1.0)
    with pytest.raises(InvalidParameterError, match="columns"):
        merge_leaves(RANGES, levels, index, np.array([0, 1]), one, 2e-3, 0.0)
