"""Fixtures of the online tests: the paper's Eq. 9, a small exact-endpoints coefficient set, and
region maps made from given leaves."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline import load_coefficients
from pipeline.certify.region_map import RegionMap
from pipeline.motion.families import EXACT_ENDPOINTS
from pipeline.offline.coefficients import Coefficients, fit_coefficients, paper_data_path
from pipeline.offline.doe import DoeData, load_doe


@pytest.fixture(scope="module")
def paper() -> Coefficients:
    return load_coefficients("paper")


@pytest.fixture(scope="module")
def exact() -> Coefficients:
    """Exact-endpoints coefficients fitted on a small synthetic DOE (smooth free parameters)."""
    base = load_doe(paper_data_path("paper_table2_doe.json"))
    L, W = base.lengths_m, base.widths_m
    free = np.column_stack([0.95 + 0.4 * (0.3 - L), 0.45 - 2.0 * (W - 0.1), 1.4 + 2 * L * W, 0.8 + 0.5 * W])
    doe = DoeData(
        family=EXACT_ENDPOINTS,
        lengths_m=L,
        widths_m=W,
        parameters=np.zeros((9, 8)),
        free=free,
        scene=base.scene,
        link_lengths_m=base.link_lengths_m,
        link_radii_m=base.link_radii_m,
        elbow=1,
        document={},
        source="synthetic",
    )
    coefficients, fit = fit_coefficients(doe)
    assert all(r > 0.999999 for r in fit.r_squared.values())  # the synthetic data are exactly quadratic
    return coefficients


@pytest.fixture(scope="session")
def leaf_map():
    """The function making a region map from given leaves (:func:`_leaf_map`)."""
    return _leaf_map


def _leaf_map(
    coefficients: Coefficients,
    depth: np.ndarray,
    index: np.ndarray,
    clearance_bound_m: np.ndarray,
    status: np.ndarray,
    axes: tuple[str, ...],
    extra_ranges_m: tuple[tuple[float, float], ...],
    split_w: np.ndarray | None = None,
) -> RegionMap:
    """A map over the fitted (L, W) of ``coefficients`` and ``extra_ranges_m``, linked to their
    sha256, with the leaves (``depth`` (n,), ``index`` (n, k)), the given clearance bounds and
    statuses, an endpoint bound of 1 mm and an end-pose upper bound of 5 cm."""
    n = depth.size
    levels = np.repeat(np.asarray(depth)[:, None], len(axes), axis=1)
    if split_w is not None:
        levels[:, 1] += split_w
    ranges = (tuple(coefficients.fitted_range_m["L"]), tuple(coefficients.fitted_range_m["W"]), *extra_ranges_m)
    return RegionMap.of_leaves(
        ranges,
        levels,
        index,
        family=coefficients.family.name,
        coefficients_source="test",
        coefficients_sha256=coefficients.source_sha256,
        axes=axes,
        margin_m=0.01,
        endpoint_tolerance_m=0.002,
        clearance_bound_m=clearance_bound_m,
        endpoint_bound_m=np.full(n, 1e-3),
        endpoint_clearance_upper_m=np.full(n, 0.05),
        status=status,
    )
