"""The sub-cells' witnesses (``range_certificate._witnessed``) spare only work: on cells near the
infeasibility contour, over (L, W) and over (L, W, x), ``sub_cell_bounds`` equals
``endpoints.infeasibility_upper_bounds`` run on every cell, and every witnessed cell is one that
bound could not prove (+inf)."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.certify.certificate_settings import CertificateSettings
from pipeline.certify.endpoints import infeasibility_upper_bounds
from pipeline.certify.range_certificate import _witnessed, sub_cell_bounds
from pipeline.certify.range_model import RangeModel
from pipeline.online.loading import load_coefficients

MARGIN_M, TOLERANCE_M = 0.01, 0.002


def _cells(model: RangeModel, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """n cells of 1/256 of each side, W in the top 5 % of the range (where the end poses' room
    crosses the margin), the other axes anywhere."""
    rng = np.random.default_rng(seed)
    size = model.range_size / 256.0
    u = rng.uniform(0.0, 1.0, (n, model.k))
    u[:, 1] = rng.uniform(0.95, 1.0, n)
    centre = model.range_lo + size / 2 + u * (model.range_size - size)
    return centre, np.broadcast_to(size / 2, centre.shape).copy()


@pytest.mark.parametrize("axes", ["L, W", "L, W, x"])
def test_witnessed_cells_are_the_ones_no_sub_cell_bound_proves(axes: str, over_x) -> None:
    coefficients = load_coefficients("paper")
    if axes == "L, W, x":
        coefficients = over_x(coefficients, scale=0.2)
    model = RangeModel.from_coefficients(coefficients)
    c, r = _cells(model, 80, seed=5)
    settings = CertificateSettings(margin_m=MARGIN_M, endpoint_tolerance_m=TOLERANCE_M, max_depth=8)
    witnessed = _witnessed(model, c, r, settings)
    every = infeasibility_upper_bounds(model, c, r, TOLERANCE_M, MARGIN_M)
    assert 0 < np.count_nonzero(witnessed) < c.shape[0]  # both kinds drawn
    assert np.any(np.isfinite(every))  # some cells proven: the check can tell
    assert np.all(np.isinf(every[witnessed]))
    assert np.array_equal(sub_cell_bounds(model, c, r, settings), every)
