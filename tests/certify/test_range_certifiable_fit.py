"""The certifiable regression's pieces (pipeline.certify.certifiable_regression): the clearance
it constrains against the generator and the analytic route, its Jacobian against finite
differences, and one refit lifting the clearance at its constraint points."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.certify.certifiable_regression import (
    CertifiableFitConfig,
    _clearance_points,
    clearance_at,
    clearance_jacobian,
    refit,
)
from pipeline.geometry.clearance import analytic_link_clearance
from pipeline.model.arm import PlanarArm
from pipeline.motion.trajectory import PARAMETER_NAMES
from pipeline.offline.coefficients import Coefficients, load_coefficients, paper_data_path
from pipeline.offline.doe import load_doe
from pipeline.offline.endpoint_regression import EndpointConstraint, endpoint_targets
from pipeline.online.generator import generate


@pytest.fixture(scope="module")
def eq9() -> Coefficients:
    return load_coefficients("paper")


def _matrix(coefficients: Coefficients) -> np.ndarray:
    return np.stack([coefficients.parameters[name] for name in PARAMETER_NAMES], -1).ravel()


def _points(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(0.2, 0.3, n), rng.uniform(0.08, 0.12, n), rng.uniform(0.0, 1.0, n)])


def test_constrained_clearance_is_the_generators(eq9: Coefficients, arm: PlanarArm) -> None:
    points = _points(50, 0)
    values = clearance_at(_matrix(eq9), _clearance_points(eq9, points), eq9)
    for (L, W, s), value in zip(points, values, strict=True):
        answer = generate(eq9, L, W)
        expected = analytic_link_clearance(answer.q(s * answer.duration_s), arm, answer.obstacle).min()
        assert value == pytest.approx(expected, abs=1e-12)


def test_clearance_jacobian_matches_finite_differences(eq9: Coefficients) -> None:
    data = _clearance_points(eq9, _points(20, 1))
    b = _matrix(eq9)
    jacobian = clearance_jacobian(b, data, eq9)
    step = 1e-7
    for k in np.random.default_rng(2).choice(48, 8, replace=False):
        e = np.zeros(48)
        e[k] = step
        numeric = (clearance_at(b + e, data, eq9) - clearance_at(b - e, data, eq9)) / (2 * step)
        assert jacobian[:, k] == pytest.approx(numeric, rel=1e-4, abs=1e-6)


def test_refit_lifts_the_clearance_at_its_points(eq9: Coefficients) -> None:
    """Eq. 9 dips below the margin near W = 0.12 m; one refit on Table 2's optima with those
    points as constraints (endpoint tolerance loose, so only the clearance binds) lifts them."""
    doe = load_doe(paper_data_path("paper_table2_doe.json"))
    points = np.array([[L, 0.117, s] for L in (0.2, 0.25) for s in np.linspace(0.9, 1.0, 4)])
    data = _clearance_points(eq9, points)
    before = clearance_at(_matrix(eq9), data, eq9)
    assert np.min(before) < 0.0105
    config = CertifiableFitConfig(endpoint=EndpointConstraint(tolerance_m=0.02, grid_points=3, max_iterations=100))
    targets = endpoint_targets(eq9.fitted_range_m, eq9.scene, eq9.link_lengths_m, 3)
    fitted, _ = refit(eq9, doe.lengths_m, doe.widths_m, doe.free_parameters(), targets, data, 0.0105, config)
    after = clearance_at(_matrix(fitted), data, fitted)
    assert np.min(after) >= 0.0105 + config.cushion_m - 1e-6
