"""The subpaving (pipeline.certify.subpaving) and its compiled tree (pipeline.certify.lookup):
for random subpavings cut one axis at a time, the tree found from the leaves gives them back, both
lookups place every point in the one leaf whose box a brute-force search finds, the volume
fractions add up, and leaves that leave a gap or overlap, or a malformed tree, are refused."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline.certify.lookup import LOOKUP_HEADER, LOOKUP_TREE, leaf_of
from pipeline.certify.subpaving import Subpaving
from pipeline.exceptions import InvalidParameterError


def ranges_of(k: int, rng: np.random.Generator) -> tuple[tuple[float, float], ...]:
    lo = rng.uniform(-1.0, 1.0, k)
    return tuple((float(a), float(a + s)) for a, s in zip(lo, rng.uniform(0.01, 2.0, k), strict=True))


def brute_force(ranges, levels, indices, points) -> np.ndarray:
    """Per point, the leaves whose closed box holds it, as an (m, n) mask."""
    r = np.array(ranges)
    side = (r[:, 1] - r[:, 0]) / 2.0**levels
    lo, hi = r[:, 0] + indices * side, r[:, 0] + (indices + 1) * side
    return np.all((points[:, None, :] >= lo[None]) & (points[:, None, :] <= hi[None]), -1)


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 4), st.integers(0, 120), st.integers(0, 2**31 - 1))
def test_the_tree_gives_back_the_leaves_and_finds_every_point(random_leaves, k: int, cuts: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    levels, indices = random_leaves(k, cuts, rng)
    ranges = ranges_of(k, rng)
    tree = Subpaving.from_leaves(ranges, levels, indices)
    stored = Subpaving(tree.ranges, tree.cut_axis, tree.cut_level, tree.children)  # as read from a file
    assert np.array_equal(stored.levels, levels) and np.array_equal(stored.indices, indices)
    assert stored.size == cuts + 1 and math.isclose(float(stored.volume_fraction.sum()), 1.0, rel_tol=1e-12)
    r = np.array(ranges)
    points = r[:, 0] + (r[:, 1] - r[:, 0]) * rng.random((200, k))
    inside = brute_force(ranges, levels, indices, points)
    found = stored.leaf_indices(tuple(points.T))
    assert np.all(inside[np.arange(200), found])  # the leaf found holds the point
    interior = inside.sum(1) == 1  # a point on no face: exactly one leaf
    assert np.array_equal(found[interior], np.argmax(inside[interior], 1))
    assert np.array_equal(stored.leaf_indices(tuple(stored.centres().T)), np.arange(stored.size))
    index = stored.lookup_index(LOOKUP_TREE, LOOKUP_HEADER)
    bounds = np.concatenate([r.reshape(-1), np.zeros(3 * stored.size)])
    padded = np.column_stack([points, np.zeros((200, 4 - k))])
    compiled = [leaf_of(index, bounds, k, *p) for p in padded.tolist()]
    assert compiled == found.tolist()


def test_points_outside_or_not_numbers_have_no_leaf(random_leaves) -> None:
    rng = np.random.default_rng(2)
    tree = Subpaving.from_leaves(((0.0, 1.0), (2.0, 3.0)), *random_leaves(2, 30, rng))
    points = np.array([[math.nextafter(1.0, 2.0), 2.5], [0.5, math.nextafter(2.0, 0.0)], [math.nan, 2.5]])
    assert tree.leaf_indices(tuple(points.T)).tolist() == [-1, -1, -1]
    corner = tree.leaf_indices((np.array([1.0]), np.array([3.0])))[0]
    assert tree.box(int(corner))[0][1] == 1.0 and tree.box(int(corner))[1][1] == 3.0


def test_a_single_leaf_is_the_whole_box() -> None:
    tree = Subpaving.from_leaves(((0.0, 1.0),), np.zeros((1, 1)), np.zeros((1, 1)))
    assert tree.size == 1 and tree.top == 0 and tree.leaf_indices((np.array([0.0, 0.5, 1.0]),)).tolist() == [0, 0, 0]
    index = tree.lookup_index(LOOKUP_TREE, LOOKUP_HEADER)
    assert leaf_of(index, np.array([0.0, 1.0, 0.0, 0.0, 0.0]), 1, 0.3, 0.0, 0.0, 0.0) == 0


def test_gaps_overlaps_and_bad_leaves_are_refused(random_leaves) -> None:
    rng = np.random.default_rng(3)
    levels, indices = random_leaves(3, 40, rng)
    ranges = ((0.0, 1.0),) * 3
    with pytest.raises(InvalidParameterError, match="gaps"):
        Subpaving.from_leaves(ranges, levels[1:], indices[1:])
    with pytest.raises(InvalidParameterError, match="overlaps"):
        Subpaving.from_leaves(ranges, np.vstack([levels, levels[:1]]), np.vstack([indices, indices[:1]]))
    parent_level, parent_index = levels[:1].copy(), indices[:1].copy()
    a = int(np.argmax(parent_level[0]))
    parent_level[0, a] -= 1
    parent_index[0, a] //= 2
    with pytest.raises(InvalidParameterError, match="overlaps"):  # a leaf and its parent
        Subpaving.from_leaves(ranges, np.vstack([levels, parent_level]), np.vstack([indices, parent_index]))
    with pytest.raises(InvalidParameterError, match="cell indices"):
        Subpaving.from_leaves(ranges, levels, indices + 2**levels)
    with pytest.raises(InvalidParameterError, match="cells"):
        Subpaving.from_leaves(ranges[:2], levels, indices)
    with pytest.raises(InvalidParameterError, match="ranges"):
        Subpaving.from_leaves(((0.0, 1.0), (1.0, 1.0), (0.0, 1.0)), levels, indices)


def test_malformed_trees_are_refused(random_leaves) -> None:
    rng = np.random.default_rng(4)
    tree = Subpaving.from_leaves(((0.0, 1.0),) * 2, *random_leaves(2, 20, rng))
    axis, level, children = tree.cut_axis, tree.cut_level, tree.children.copy()
    for bad_children in (children[::-1], np.where(children == -1, -2, children), children[:-1]):
        with pytest.raises(InvalidParameterError, match="tree"):
            Subpaving(tree.ranges, axis[: bad_children.shape[0]], level[: bad_children.shape[0]], bad_children)
    with pytest.raises(InvalidParameterError, match="tree"):
        Subpaving(tree.ranges, np.full_like(axis, 2), level, children)
    with pytest.raises(InvalidParameterError, match="tree"):
        Subpaving(tree.ranges, axis, np.full_like(level, -1), children)
