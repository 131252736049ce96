"""Each axis's share of the endpoint bound's gap (pipeline.certify.endpoints.endpoint_bounds_and_shares),
the refinement's choice of axis: the bounds are endpoint_error_bounds' own, and moving an
obstacle from a cell's centre to the cell's face along one axis moves each end's tip error
(Pinocchio's tip against the path's P1 and P5) by at most that axis's share (the mean value
theorem, component by component); halving a cell does not raise a share above half."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline import load_coefficients
from pipeline.certify.endpoints import endpoint_bounds_and_shares, endpoint_error_bounds
from pipeline.certify.range_model import RangeModel
from pipeline.model.arm import PlanarArm
from pipeline.offline.coefficients import Coefficients
from pipeline.online.generator import generate


@pytest.fixture(scope="module")
def eq9() -> Coefficients:
    return load_coefficients("paper")


def _errors(coefficients: Coefficients, arm: PlanarArm, L: float, W: float) -> np.ndarray:
    """The tip's error vectors at both ends (2, 2) [m], by Pinocchio's forward kinematics."""
    answer = generate(coefficients, L, W, out_of_range="ignore")
    ends = [arm.end_effector_position(answer.q(t))[:2] for t in (0.0, answer.duration_s)]
    return np.array([ends[0] - answer.path.points_m[0], ends[1] - answer.path.points_m[-1]])


def test_shares_bound_the_error_moving_along_each_axis(eq9: Coefficients, arm: PlanarArm) -> None:
    model = RangeModel.from_coefficients(eq9)
    rng = np.random.default_rng(12)
    centre = np.column_stack([rng.uniform(0.21, 0.29, 25), rng.uniform(0.085, 0.115, 25)])
    radius = np.column_stack([rng.uniform(1e-4, 5e-3, 25), rng.uniform(1e-4, 4e-3, 25)])
    bounds, shares = endpoint_bounds_and_shares(model, centre, radius)
    np.testing.assert_array_equal(bounds, endpoint_error_bounds(model, centre, radius))
    assert shares.shape == (25, 2) and np.all(shares >= 0.0)
    tightest = 0.0
    for c, r, share in zip(centre, radius, shares, strict=True):
        at_centre = _errors(eq9, arm, *c)
        for axis in range(2):
            for sign in (-1.0, 1.0):
                moved = c.copy()
                moved[axis] += sign * r[axis]
                change = np.abs(_errors(eq9, arm, *moved) - at_centre).sum(axis=1)  # |dex| + |dey| per end
                assert np.all(change <= share[axis] + 1e-9)
                tightest = max(tightest, float(change.max() / share[axis]))
    assert tightest > 0.02  # a share is a bound on the change, not a number of another scale
    _, halves = endpoint_bounds_and_shares(model, centre, radius / 2)
    assert np.all(halves <= shares / 2 + 1e-15)
