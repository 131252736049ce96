"""Endpoint-constrained regression (pipeline.offline.endpoint_regression), on the paper's own Table 2:
its plain fit (Eq. 9) misses P1/P5 by more than the tolerance between the DOE points, the
constrained fit does not, checked by Pinocchio's kinematics (not Eq. 2) through the online
generator; the constraint's Jacobian against finite differences; an inactive constraint gives
back the plain fit; bad settings and non-convergence are reported."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from pipeline.exceptions import EndpointConstraintWarning, InvalidParameterError
from pipeline.motion.families import EXACT_ENDPOINTS
from pipeline.motion.trajectory import PARAMETER_NAMES
from pipeline.offline.coefficients import fit_coefficients, paper_data_path
from pipeline.offline.doe import load_doe
from pipeline.offline.endpoint_regression import (
    EndpointConstraint,
    endpoint_errors_m,
    endpoint_slack,
    endpoint_slack_jacobian,
    endpoint_targets,
    fit_with_endpoints,
)
from pipeline.offline.regression import design_matrix, predict
from pipeline.online.generator import generate

RANGE = {"L": (0.2, 0.3), "W": (0.08, 0.12)}
TOLERANCE_M = 0.002


@pytest.fixture(scope="module")
def table2():
    return load_doe(paper_data_path("paper_table2_doe.json"))


@pytest.fixture(scope="module")
def targets(table2):
    return endpoint_targets(RANGE, table2.scene, table2.link_lengths_m, 21)


@pytest.fixture(scope="module")
def constrained(table2):
    """(coefficients file, plain-fit coefficients file) of Table 2."""
    plain, _ = fit_coefficients(table2)
    ours, _ = fit_coefficients(table2, endpoint_constraint=EndpointConstraint(tolerance_m=TOLERANCE_M))
    return ours, plain


def grid_parameters(coefficients, targets) -> np.ndarray:
    ordered = {name: coefficients.parameters[name] for name in PARAMETER_NAMES}
    return predict(ordered, targets.lengths_m, targets.widths_m)


def test_constraint_holds_on_the_grid_where_the_plain_fit_breaks_it(constrained, targets) -> None:
    ours, plain = constrained
    plain_errors = endpoint_errors_m(grid_parameters(plain, targets), targets)
    assert plain_errors.max() > 2 * TOLERANCE_M  # Eq. 9 misses by > 4 mm somewhere in its own range
    errors = endpoint_errors_m(grid_parameters(ours, targets), targets)
    assert errors.max() <= TOLERANCE_M * (1 + 1e-6)
    report = ours.extra["fit"]["endpoint_constraint"]
    assert report["converged"] is True
    assert_allclose(report["grid_endpoint_error_max_m"], errors.max(), rtol=1e-9)
    assert_allclose(report["grid_endpoint_error_max_plain_m"], plain_errors.max(), rtol=1e-9)
    assert ours.extra["fit"]["regression"] == "least squares + endpoint constraint"


@settings(max_examples=25, deadline=None)
@given(st.floats(0.2, 0.3), st.floats(0.08, 0.12))
def test_generated_trajectory_starts_and_ends_within_tolerance_by_pinocchio(constrained, arm, L, W) -> None:
    """Between grid points too, by Pinocchio's frame placement of the URDF's end effector
    (independent of the Eq. 2 the fit uses): the fit keeps 3 % of the tolerance free."""
    ours, _ = constrained
    generated = generate(ours, L, W, out_of_range="error")
    ends = arm.to_plane(
        np.array([arm.end_effector_position(q) for q in generated.q(np.array([0.0, generated.duration_s]))])
    )
    errors = np.linalg.norm(ends - generated.path.points_m[[0, -1]], axis=-1)
    assert errors.max() <= TOLERANCE_M * (1 - 0.5 * EndpointConstraint().headroom) + 1e-9


def test_fit_keeps_its_headroom_on_the_grid_and_the_check_grid(constrained, table2) -> None:
    ours, _ = constrained
    report = ours.extra["fit"]["endpoint_constraint"]
    constraint = EndpointConstraint(tolerance_m=TOLERANCE_M)
    assert report["fit_tolerance_m"] == pytest.approx(TOLERANCE_M * (1 - constraint.headroom), rel=1e-12)
    assert report["grid_endpoint_error_max_m"] <= report["fit_tolerance_m"] * (1 + 1e-6)
    check = endpoint_targets(RANGE, table2.scene, table2.link_lengths_m, constraint.check_points)
    errors = endpoint_errors_m(grid_parameters(ours, check), check)
    assert_allclose(report["check_grid_endpoint_error_max_m"], errors.max(), rtol=1e-9)
    assert errors.max() <= constraint.check_tolerance_m


def test_constraint_generation_closes_the_gaps_between_grid_points(table2) -> None:
    """Without headroom a 5 x 5 grid leaves the error above the tolerance between its points; the
    check grid's worst points are added until a 41 x 41 grid (and a 97 x 97 one, checked here) is
    within it."""
    coarse = endpoint_targets(RANGE, table2.scene, table2.link_lengths_m, 5)
    check = endpoint_targets(RANGE, table2.scene, table2.link_lengths_m, 41)
    dense = endpoint_targets(RANGE, table2.scene, table2.link_lengths_m, 97)
    args = (table2.lengths_m, table2.widths_m, table2.free_parameters(), coarse)
    without = EndpointConstraint(grid_points=5, headroom=0.0, check_points=0)
    fit, report = fit_with_endpoints(*args, without)
    errors = endpoint_errors_m(grid_parameters(_file(fit), check), check)
    assert errors.max() > TOLERANCE_M * 1.01
    assert "check_grid_endpoint_error_max_m" not in report
    with_check = EndpointConstraint(grid_points=5, headroom=0.02, check_points=41, check_rounds=10)
    fit, report = fit_with_endpoints(*args, with_check, check)
    assert report["converged"] and report["check_points_added"] > 0 and report["check_rounds"] >= 1
    errors = endpoint_errors_m(grid_parameters(_file(fit), check), check)
    assert errors.max() <= with_check.check_tolerance_m
    assert endpoint_errors_m(grid_parameters(_file(fit), dense), dense).max() <= TOLERANCE_M


def _file(fit):
    """An object with the fit's ``parameters``, as :func:`grid_parameters` takes."""
    return dataclasses.make_dataclass("Fit", ["parameters"])(fit.coefficients)


def test_fit_stays_close_to_the_doe_optima(constrained, table2) -> None:
    ours, plain = constrained
    deviation = ours.extra["fit"]["endpoint_constraint"]["max_deviation_from_doe"]
    fitted = predict({n: ours.parameters[n] for n in PARAMETER_NAMES}, table2.lengths_m, table2.widths_m)
    observed = np.stack([table2.free_parameters()[n] for n in PARAMETER_NAMES], -1)
    assert_allclose(np.abs(fitted - observed).max(), deviation, rtol=1e-9)
    assert 0 < deviation < 0.1  # rad or rad/s: a correction, not a different motion
    assert ours.parameters != plain.parameters


def test_slack_jacobian_matches_finite_differences(constrained, targets) -> None:
    ours, _ = constrained
    b = np.stack([ours.parameters[n] for n in PARAMETER_NAMES], -1).ravel()
    X = design_matrix(targets.lengths_m, targets.widths_m)
    analytic = endpoint_slack_jacobian(b, X, targets, TOLERANCE_M)
    numeric = np.empty_like(analytic)
    step = 1e-7
    for k in range(b.size):
        bump = np.zeros_like(b)
        bump[k] = step
        numeric[:, k] = (
            endpoint_slack(b + bump, X, targets, TOLERANCE_M) - endpoint_slack(b - bump, X, targets, TOLERANCE_M)
        ) / (2 * step)
    assert_allclose(analytic, numeric, rtol=1e-5, atol=1e-3 * np.abs(analytic).max())


def test_slack_is_one_minus_squared_error_ratio(constrained, targets) -> None:
    ours, _ = constrained
    b = np.stack([ours.parameters[n] for n in PARAMETER_NAMES], -1).ravel()
    X = design_matrix(targets.lengths_m, targets.widths_m)
    errors = endpoint_errors_m(X @ b.reshape(6, 8), targets)
    assert_allclose(endpoint_slack(b, X, targets, 0.004), 1 - (errors.ravel() / 0.004) ** 2, atol=1e-12)


def test_loose_tolerance_gives_back_the_plain_fit(table2, targets) -> None:
    plain, _ = fit_coefficients(table2)
    fit, report = fit_with_endpoints(
        table2.lengths_m, table2.widths_m, table2.free_parameters(), targets, EndpointConstraint(tolerance_m=1.0)
    )
    for name in PARAMETER_NAMES:
        assert_allclose(fit.coefficients[name], plain.parameters[name], rtol=1e-9, atol=1e-9)
    assert report["max_deviation_from_doe"] == pytest.approx(max(plain.extra["fit"]["max_residual"].values()))


def test_tighter_tolerance_moves_further_from_the_data(table2, targets) -> None:
    deviations = []
    for tolerance in (0.004, 0.002, 0.001):
        _, report = fit_with_endpoints(
            table2.lengths_m, table2.widths_m, table2.free_parameters(), targets, EndpointConstraint(tolerance)
        )
        assert report["grid_endpoint_error_max_m"] <= tolerance * (1 + 1e-6)
        deviations.append(report["max_deviation_from_doe"])
    assert deviations[0] < deviations[1] < deviations[2]


def test_same_input_same_coefficients(table2) -> None:
    a, _ = fit_coefficients(table2, endpoint_constraint=EndpointConstraint())
    b, _ = fit_coefficients(table2, endpoint_constraint=EndpointConstraint())
    assert a.parameters == b.parameters


def test_non_convergence_warns_and_says_so(table2, targets) -> None:
    with pytest.warns(EndpointConstraintWarning, match="did not converge"):
        _, report = fit_with_endpoints(
            table2.lengths_m, table2.widths_m, table2.free_parameters(), targets, EndpointConstraint(max_iterations=1)
        )
    assert report["converged"] is False


@pytest.mark.parametrize(
    ("status", "message"), [(9, "Iteration limit reached"), (8, "Positive directional derivative for linesearch")]
)
def test_a_feasible_stalled_iterate_is_used_and_said(table2, targets, monkeypatch, status: int, message: str) -> None:
    """SLSQP stalled (status 9: its iteration budget; 8: no descent): an iterate within the fit
    tolerance on the grid is used (converged, the report's ``solver`` says how it stopped), one
    outside it is not."""
    import scipy.optimize

    minimize = scipy.optimize.minimize
    stop_at = {}

    def at_budget(*args, **kwargs):
        result = minimize(*args, **kwargs)
        x = result.x if stop_at["optimum"] else args[1]  # the optimum, or the plain fit it started from
        return scipy.optimize.OptimizeResult(x=x, success=False, status=status, message=message)

    monkeypatch.setattr(scipy.optimize, "minimize", at_budget)
    args = (table2.lengths_m, table2.widths_m, table2.free_parameters(), targets)
    stop_at["optimum"] = True
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _, report = fit_with_endpoints(*args, EndpointConstraint(check_points=0))
    assert report["converged"] is True and report["grid_endpoint_error_max_m"] <= report["fit_tolerance_m"] * (1 + 1e-6)
    assert report["solver"].startswith(f"{message} at an iterate within the fit tolerance")
    stop_at["optimum"] = False
    with pytest.warns(EndpointConstraintWarning, match=message):
        _, report = fit_with_endpoints(*args, EndpointConstraint(check_points=0))
    assert report["converged"] is False and "solver" not in report
    assert report["grid_endpoint_error_max_m"] > report["tolerance_m"]  # the plain fit's


def test_converged_fit_does_not_warn(table2, targets) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fit_with_endpoints(table2.lengths_m, table2.widths_m, table2.free_parameters(), targets, EndpointConstraint())


@pytest.mark.parametrize(
    "kwargs",
    [
        {"tolerance_m": 0.0},
        {"tolerance_m": -0.001},
        {"tolerance_m": float("nan")},
        {"grid_points": 1},
        {"grid_points": 2.5},
        {"max_iterations": 0},
        {"headroom": -0.01},
        {"headroom": 0.5},
        {"headroom": float("nan")},
        {"check_points": 1},
        {"check_points": -3},
        {"check_rounds": 0},
        {"points_per_round": 0},
    ],
)
def test_bad_settings_are_refused(kwargs: dict) -> None:
    with pytest.raises(InvalidParameterError):
        EndpointConstraint(**kwargs)


def test_only_the_paper_family_takes_the_constraint(table2, targets) -> None:
    values = dict(table2.free_parameters())
    values.pop("A1")
    with pytest.raises(InvalidParameterError, match="paper family"):
        fit_with_endpoints(table2.lengths_m, table2.widths_m, values, targets, EndpointConstraint())


def test_exact_endpoints_doe_refuses_a_constraint(table2) -> None:
    exact = dataclasses.replace(table2, family=EXACT_ENDPOINTS)
    with pytest.raises(InvalidParameterError, match="exact by construction"):
        fit_coefficients(exact, endpoint_constraint=EndpointConstraint())
