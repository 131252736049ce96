"""Bisection for the lowest index at which a predicate that turns true once holds, one search per
row, all rows at a time.

Where a predicate of an integer j is false below some j* and true from it on (a quantity sampled at
j that is non-increasing, compared with a floor), :func:`lowest_true` finds j* in [lo, hi] for
every row in about log2(hi - lo) rounds, each round asking the predicate only for the rows still
open.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["lowest_true"]


def lowest_true(lo: np.ndarray, hi: np.ndarray, holds_at: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> np.ndarray:
    """Per row, the lowest j in [lo, hi) with ``holds_at`` true; hi where none is.

    Args:
        lo, hi: The rows' index ranges, integer arrays of one shape (n,); rows with lo >= hi are
            returned as lo.
        holds_at: ``holds_at(rows, j)`` -> bool array: the predicate for the rows ``rows`` (indices
            into the n rows) at their indices ``j``; false below each row's j* and true from it on.
    """
    lo, hi = np.array(lo, dtype=np.int64), np.array(hi, dtype=np.int64)
    while np.any(lo < hi):
        active = np.flatnonzero(lo < hi)
        mid = (lo[active] + hi[active]) // 2
        holds = holds_at(active, mid)
        hi[active[holds]] = mid[holds]
        lo[active[~holds]] = mid[~holds] + 1
    return lo
