"""The row-wise bisection against a linear scan of the same predicate."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline.certify.bisection import lowest_true


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 50), st.integers(0, 70), st.integers(-5, 80)), min_size=1, max_size=20))
def test_lowest_true_is_the_linear_scans_first_true(rows: list[tuple[int, int, int]]) -> None:
    lo = np.array([r[0] for r in rows])
    hi = lo + np.array([r[1] for r in rows])
    first = np.array([r[2] for r in rows])
    asked: list[int] = []

    def holds_at(active: np.ndarray, j: np.ndarray) -> np.ndarray:
        assert np.all((lo[active] <= j) & (j < hi[active]))  # only asked inside the open range
        asked.append(active.size)
        return j >= first[active]

    found = lowest_true(lo, hi, holds_at)
    expected = [next((j for j in range(a, b) if j >= f), b) for a, b, f in zip(lo, hi, first, strict=True)]
    np.testing.assert_array_equal(found, expected)
    assert len(asked) <= int(np.ceil(np.log2(max(int(np.max(hi - lo)), 1) + 1)))  # bisection, not a scan


def test_lowest_true_leaves_its_inputs_and_empty_ranges_alone() -> None:
    lo, hi = np.array([3, 5]), np.array([3, 9])
    found = lowest_true(lo, hi, lambda active, j: j >= 7)
    np.testing.assert_array_equal(found, [3, 7])
    np.testing.assert_array_equal(lo, [3, 5])
    np.testing.assert_array_equal(hi, [3, 9])
