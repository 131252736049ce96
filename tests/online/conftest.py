"""Fixtures of the online tests: the paper's Eq. 9 and a small exact-endpoints coefficient set."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline import load_coefficients
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
