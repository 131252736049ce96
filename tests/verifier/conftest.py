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
        return RegionMap(
            family="paper",
            coefficients_source="paper",
            coefficients_sha256="ab" * 32,
            length_range_m=(0.2, 0.3),
            width_range_m=(0.08, 0.12),
            margin_m=0.01,
            endpoint_tolerance_m=0.002,
            depth=np.array([1, 1, 1, 2, 2, 2, 2]),
            index_l=np.array([0, 1, 0, 2, 3, 2, 3]),
            index_w=np.array([0, 0, 1, 2, 2, 3, 3]),
            clearance_bound_m=np.array(clearance_bound_m, dtype=float),
            endpoint_bound_m=np.full(7, 0.001),
            endpoint_clearance_upper_m=np.full(7, 0.05),
            status=np.array(status),
        )

    return make
