"""Shared fixtures of the verifier's tests."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import pytest

from pipeline.certify.region_map import RegionMap


@pytest.fixture
def quadrant_map() -> Callable[[Sequence[float], Sequence[int]], RegionMap]:
    """A region map over the paper's range: three quadrants of depth 1 and four leaves of depth 2 in
    the fourth, with the given clearance bounds [m] and status indices (seven each)."""

    def make(clearance_bound_m: Sequence[float], status: Sequence[int]) -> RegionMap:
        depth = np.array([1, 1, 1, 2, 2, 2, 2])
        return RegionMap.of_leaves(
            ((0.2, 0.3), (0.08, 0.12)),
            np.column_stack([depth, depth]),
            np.column_stack([[0, 1, 0, 2, 3, 2, 3], [0, 0, 1, 2, 2, 3, 3]]),
            family="paper",
            coefficients_source="paper",
            coefficients_sha256="ab" * 32,
            axes=("L", "W"),
            margin_m=0.01,
            endpoint_tolerance_m=0.002,
            clearance_bound_m=np.array(clearance_bound_m, dtype=float),
            endpoint_bound_m=np.full(7, 0.001),
            endpoint_clearance_upper_m=np.full(7, 0.05),
            status=np.array(status),
        )

    return make
