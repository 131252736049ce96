"""The regression over k scene variables (pipeline.offline.regression, pipeline.offline.endpoint_regression):
an exact quadratic in (L, W, x) is recovered from a 3^3 design; for (L, W) the k-variable route
gives the paper's fit to the bit; the endpoint targets of a moved obstacle are those of the centred
one moved by x; and the endpoint-constrained fit holds its constraint over (L, W, x)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from pipeline import load_coefficients
from pipeline.exceptions import InvalidParameterError, UnreachableObstacleError
from pipeline.motion.trajectory import PARAMETER_NAMES
from pipeline.offline.coefficients import paper_data_path
from pipeline.offline.doe import load_doe
from pipeline.offline.endpoint_regression import (
    EndpointConstraint,
    endpoint_errors_m,
    endpoint_slack,
    endpoint_slack_jacobian,
    endpoint_targets,
    fit_points_with_endpoints,
    targets_at,
)
from pipeline.offline.regression import fit_quadratic, fit_quadratic_points, predict, predict_points
from pipeline.offline.variables import Variables

LWX = Variables(("L", "W", "x"))
RANGE = {"L": (0.2, 0.3), "W": (0.08, 0.12), "x": (-0.02, 0.02)}


def design_3x3x3() -> np.ndarray:
    """The 27 runs of a three-level full factorial in (L, W, x)."""
    return np.array(list(itertools.product(*(np.linspace(*RANGE[name], 3) for name in LWX.names))))


@pytest.fixture(scope="module")
def table2():
    return load_doe(paper_data_path("paper_table2_doe.json"))


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-10.0, 10.0), min_size=20, max_size=20))
def test_an_exact_quadratic_in_three_variables_is_recovered(values) -> None:
    """Two parameters, each an exact quadratic in (L, W, x) with random coefficients: the fit on
    the 3^3 design reproduces them, and their predictions anywhere in the range, to 1e-10."""
    points = design_3x3x3()
    truth = {"p": tuple(values[:10]), "q": tuple(values[10:])}
    data = {name: LWX.design(points) @ np.array(b) for name, b in truth.items()}
    fit = fit_quadratic_points(points, data, LWX)
    assert fit.variables == LWX
    rng = np.random.default_rng(0)
    probe = np.column_stack([rng.uniform(*RANGE[name], 200) for name in LWX.names])
    assert_allclose(predict_points(fit.coefficients, probe), predict_points(truth, probe), rtol=0, atol=1e-10)
    assert_allclose(predict_points(fit.coefficients, points), np.column_stack(list(data.values())), atol=1e-10)
    for name in truth:
        assert fit.max_residual[name] <= 1e-10
        assert_allclose(fit.coefficients[name], truth[name], rtol=0, atol=1e-6 * (1 + max(map(abs, values))))


def test_the_two_variable_route_is_the_papers_fit_to_the_bit(table2) -> None:
    points = np.column_stack([table2.lengths_m, table2.widths_m])
    old = fit_quadratic(table2.lengths_m, table2.widths_m, table2.free_parameters())
    new = fit_quadratic_points(points, table2.free_parameters(), ("L", "W"))
    assert new.coefficients == old.coefficients
    assert new.r_squared == old.r_squared and new.max_residual == old.max_residual
    np.testing.assert_array_equal(list(new.loo_rmse.values()), list(old.loo_rmse.values()))
    L, W = np.meshgrid(np.linspace(0.2, 0.3, 7), np.linspace(0.08, 0.12, 5))
    assert np.array_equal(predict_points(old.coefficients, np.stack([L, W], -1)), predict(old.coefficients, L, W))


def test_degenerate_designs_are_refused_by_name() -> None:
    points = design_3x3x3()
    two_levels = points[points[:, 2] != 0.0]  # x at -0.02 and 0.02 only: no x^2
    data = {"p": np.ones(len(two_levels))}
    with pytest.raises(InvalidParameterError, match="at least 3 levels of L and of W and of x"):
        fit_quadratic_points(two_levels, data, LWX)
    with pytest.raises(InvalidParameterError, match=r"at least 10 \(L, W, x\) points"):
        fit_quadratic_points(points[:9], {"p": np.ones(9)}, LWX)
    with pytest.raises(InvalidParameterError, match="one column per variable"):
        fit_quadratic_points(points[:, :2], {"p": np.ones(27)}, LWX)


def test_targets_of_a_moved_obstacle_are_the_centred_ones_moved(table2) -> None:
    """P1 and P5 shift by exactly x, T does not change (to the bit)."""
    targets = endpoint_targets(RANGE, table2.scene, table2.link_lengths_m, 3, LWX)
    assert targets.variables == LWX and targets.extra_m.shape == (27, 1)
    assert np.array_equal(targets.points[:, 2], targets.extra_m[:, 0])
    centred = endpoint_targets(RANGE, table2.scene, table2.link_lengths_m, 3)
    for row in range(27):
        L, W, x = targets.points[row]
        match = np.flatnonzero((centred.lengths_m == L) & (centred.widths_m == W))
        assert match.size == 1
        i = match[0]
        assert np.array_equal(targets.start_m[row], centred.start_m[i] + [x, 0.0])
        assert np.array_equal(targets.end_m[row], centred.end_m[i] + [x, 0.0])
        assert targets.duration_s[row] == centred.duration_s[i]
    with pytest.raises(UnreachableObstacleError, match="P1"):
        targets_at(np.array([[0.3, 0.08, 0.2]]), LWX, table2.scene, table2.link_lengths_m)


@pytest.fixture(scope="module")
def moved_doe():
    """Eq. 9's parameters at 27 runs over (L, W, x): they ignore x, so the plain fit misses the
    moved P1 and P5 by up to about 2 cm, and the constraint has work to do."""
    paper = load_coefficients("paper")
    points = design_3x3x3()
    values = paper.predict_free(points[:, 0], points[:, 1])
    return points, {name: values[:, i] for i, name in enumerate(PARAMETER_NAMES)}


def test_the_endpoint_constrained_fit_holds_its_constraint_over_three_variables(table2, moved_doe) -> None:
    points, values = moved_doe
    constraint = EndpointConstraint(tolerance_m=0.002, grid_points=5, check_points=9)
    targets = endpoint_targets(RANGE, table2.scene, table2.link_lengths_m, constraint.grid_points, LWX)
    check = endpoint_targets(RANGE, table2.scene, table2.link_lengths_m, constraint.check_points, LWX)
    fit, report = fit_points_with_endpoints(points, values, targets, constraint, check)
    assert fit.variables == LWX and all(len(b) == 10 for b in fit.coefficients.values())
    assert report["converged"] is True
    assert report["grid_endpoint_error_max_plain_m"] > 5 * constraint.tolerance_m
    ordered = {name: fit.coefficients[name] for name in PARAMETER_NAMES}
    errors = endpoint_errors_m(predict_points(ordered, targets.points), targets)
    assert errors.max() <= constraint.fit_tolerance_m * (1 + 1e-6)
    assert report["grid_endpoint_error_max_m"] == pytest.approx(errors.max(), rel=1e-12)
    assert report["check_grid_endpoint_error_max_m"] <= constraint.tolerance_m


def test_the_slack_jacobian_over_three_variables_matches_finite_differences(table2, moved_doe) -> None:
    points, values = moved_doe
    targets = endpoint_targets(RANGE, table2.scene, table2.link_lengths_m, 3, LWX)
    fit = fit_quadratic_points(points, values, LWX)
    b = np.stack([fit.coefficients[n] for n in PARAMETER_NAMES], -1).ravel()
    X = targets.design()
    analytic = endpoint_slack_jacobian(b, X, targets, 0.002)
    assert analytic.shape == (2 * 27, 80)
    numeric = np.empty_like(analytic)
    step = 1e-7
    for k in range(b.size):
        bump = np.zeros_like(b)
        bump[k] = step
        numeric[:, k] = (endpoint_slack(b + bump, X, targets, 0.002) - endpoint_slack(b - bump, X, targets, 0.002)) / (
            2 * step
        )
    assert_allclose(analytic, numeric, rtol=1e-5, atol=1e-3 * np.abs(analytic).max())


def test_mismatched_check_grid_is_refused(table2, moved_doe) -> None:
    points, values = moved_doe
    targets = endpoint_targets(RANGE, table2.scene, table2.link_lengths_m, 3, LWX)
    check = endpoint_targets(RANGE, table2.scene, table2.link_lengths_m, 3)
    with pytest.raises(InvalidParameterError, match="check"):
        fit_points_with_endpoints(points, values, targets, EndpointConstraint(), check)
