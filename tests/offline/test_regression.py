"""Second-order regression (pipeline.offline.regression): the key cross-check that least squares on the
paper's Table 2 reproduces the paper's Eq. 9 within the rounding of Table 2, exact recovery of
a known quadratic, leave-one-out errors against brute force, and rank-deficient designs."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pipeline import load_coefficients
from pipeline.exceptions import InvalidParameterError
from pipeline.motion.trajectory import PARAMETER_NAMES
from pipeline.offline.coefficients import paper_data_path
from pipeline.offline.doe import load_doe
from pipeline.offline.regression import BASIS, design_matrix, fit_quadratic, predict

HALF_UNIT = 0.0005  # Table 2 prints three decimals: each value is within +-0.0005 of PSO's


@pytest.fixture(scope="module")
def paper_doe():
    return load_doe(paper_data_path("paper_table2_doe.json"))


@pytest.fixture(scope="module")
def eq9() -> dict[str, tuple[float, ...]]:
    return load_coefficients("paper").parameters


@pytest.fixture(scope="module")
def ours(paper_doe):
    return fit_quadratic(paper_doe.lengths_m, paper_doe.widths_m, paper_doe.free_parameters())


def printed_half_unit(value: float) -> float:
    """Half a unit in the last printed digit of a coefficient of Eq. 9 (4 significant figures,
    e.g. -19.07 -> 0.005, 0.4736 -> 0.00005, 1.6 -> 0.0005 since '1.6' is 1.600)."""
    digits = 4 - 1 - math.floor(math.log10(abs(value)))
    return 0.5 * 10.0 ** (-digits)


def test_paper_doe_is_table_2(paper_doe, table2: np.ndarray) -> None:
    assert paper_doe.family.name == "paper"
    assert_allclose(paper_doe.lengths_m, table2[:, 8], rtol=0, atol=0)
    assert_allclose(paper_doe.widths_m, table2[:, 9], rtol=0, atol=0)
    free = paper_doe.free_parameters()
    assert list(free) == list(PARAMETER_NAMES)
    assert_allclose(np.column_stack([free[n] for n in PARAMETER_NAMES]), table2[:, :8], rtol=0, atol=0)


def test_table_2_regression_predicts_eq9_within_rounding(paper_doe, ours, eq9) -> None:
    """Predictions of our fit and of Eq. 9 agree on the DOE grid and over the whole range to
    < 1e-3 rad (rad/s), which is what Table 2's three decimals and Eq. 9's four figures allow."""
    names = list(PARAMETER_NAMES)
    paper = {n: eq9[n] for n in names}
    L, W = np.meshgrid(np.linspace(0.20, 0.30, 121), np.linspace(0.08, 0.12, 121))
    dense = np.abs(predict(ours.coefficients, L, W) - predict(paper, L, W))
    grid = np.abs(
        predict(ours.coefficients, paper_doe.lengths_m, paper_doe.widths_m)
        - predict(paper, paper_doe.lengths_m, paper_doe.widths_m)
    )
    assert dense.max() < 1e-3
    assert grid.max() < 1e-3
    # The bound a rounding of Table 2 can move a prediction by: HALF_UNIT * ||x^T X^+||_1, plus
    # the rounding of Eq. 9's printed coefficients: sum_k half-unit_k |x_k|.
    X = design_matrix(paper_doe.lengths_m, paper_doe.widths_m)
    x = design_matrix(L, W)
    table_bound = HALF_UNIT * np.sum(np.abs(x @ np.linalg.pinv(X)), axis=-1)
    for i, name in enumerate(names):
        printed = np.abs(x) @ np.array([printed_half_unit(b) for b in eq9[name]])
        assert np.all(dense[..., i] <= table_bound + printed), name


def test_table_2_regression_coefficients_within_the_spread_of_rounding(paper_doe, ours, eq9) -> None:
    """Each coefficient is linear in Table 2: b = X^+ y. Perturbing Table 2 by +-0.0005 (its
    rounding) moves b_k by at most 0.0005 * sum_i |X^+_ki|, reached by the perturbation
    0.0005 * sign(X^+_k). Our coefficients must lie within that spread (plus Eq. 9's own
    printing) of the paper's, and the rounding perturbations must reach that far."""
    X = design_matrix(paper_doe.lengths_m, paper_doe.widths_m)
    pinv = np.linalg.pinv(X)
    free = paper_doe.free_parameters()
    spread = np.zeros((len(PARAMETER_NAMES), len(BASIS)))
    for i, name in enumerate(PARAMETER_NAMES):
        for k in range(len(BASIS)):
            # The extreme perturbations of Table 2's rounding for coefficient k, refitted.
            for sign in (1.0, -1.0):
                perturbed = free[name] + sign * HALF_UNIT * np.sign(pinv[k])
                assert np.all(np.abs(perturbed - free[name]) <= HALF_UNIT + 1e-15)
                refit = fit_quadratic(paper_doe.lengths_m, paper_doe.widths_m, {name: perturbed})
                spread[i, k] = max(spread[i, k], abs(refit.coefficients[name][k] - ours.coefficients[name][k]))
    assert_allclose(spread, np.broadcast_to(HALF_UNIT * np.sum(np.abs(pinv), axis=1), spread.shape), rtol=1e-9)
    # Random roundings stay inside the extreme ones.
    rng = np.random.default_rng(0)
    for _ in range(200):
        noise = rng.uniform(-HALF_UNIT, HALF_UNIT, size=len(paper_doe.lengths_m))
        refit = fit_quadratic(paper_doe.lengths_m, paper_doe.widths_m, {"A1": free["A1"] + noise})
        assert np.all(np.abs(np.subtract(refit.coefficients["A1"], ours.coefficients["A1"])) <= spread[0] + 1e-12)
    for i, name in enumerate(PARAMETER_NAMES):
        difference = np.abs(np.subtract(ours.coefficients[name], eq9[name]))
        printed = np.array([printed_half_unit(b) for b in eq9[name]])
        assert np.all(difference <= spread[i] + printed), (name, difference, spread[i] + printed)
    # In absolute terms the constant terms agree to about 1e-2.
    constants = np.array([[ours.coefficients[n][0], eq9[n][0]] for n in PARAMETER_NAMES])
    assert_allclose(constants[:, 0], constants[:, 1], rtol=0, atol=1.1e-2)


def test_table_2_fit_quality(ours) -> None:
    for name in PARAMETER_NAMES:
        assert 0.7 < ours.r_squared[name] <= 1.0
        assert ours.max_residual[name] < 0.05
        assert math.isfinite(ours.loo_rmse[name]) and ours.loo_rmse[name] > 0


# --------------------------------------------------------------------------------------------
# Known quadratics, leave-one-out, rank.


def grid(levels: int, lengths=(0.2, 0.3), widths=(0.08, 0.12)) -> tuple[np.ndarray, np.ndarray]:
    L, W = np.meshgrid(np.linspace(*lengths, levels), np.linspace(*widths, levels))
    return L.ravel(), W.ravel()


def test_exact_recovery_of_a_known_quadratic() -> None:
    L, W = grid(4)
    truth = {"p": (1.5, -2.0, 3.0, 4.0, -5.0, 6.0), "q": (-0.3, 0.0, 0.0, 10.0, 0.0, -20.0)}
    values = {
        name: b[0] + b[1] * L + b[2] * W + b[3] * L * L + b[4] * L * W + b[5] * W * W for name, b in truth.items()
    }
    fit = fit_quadratic(L, W, values)
    assert list(fit.coefficients) == ["p", "q"]
    for name, b in truth.items():
        assert_allclose(fit.coefficients[name], b, rtol=0, atol=1e-8)
        assert fit.r_squared[name] == pytest.approx(1.0, abs=1e-12)
        assert fit.max_residual[name] < 1e-12
        assert fit.loo_rmse[name] < 1e-12
    L2, W2 = np.array([0.17, 0.33]), np.array([0.05, 0.15])
    assert_allclose(
        predict(fit.coefficients, L2, W2)[:, 0],
        1.5 - 2 * L2 + 3 * W2 + 4 * L2**2 - 5 * L2 * W2 + 6 * W2**2,
        rtol=1e-9,
        atol=1e-12,
    )


def test_constant_parameter_has_r_squared_one() -> None:
    L, W = grid(3)
    fit = fit_quadratic(L, W, {"c": np.full(9, 0.25)})
    assert fit.r_squared["c"] == 1.0
    assert_allclose(fit.coefficients["c"], [0.25, 0, 0, 0, 0, 0], rtol=0, atol=1e-10)


@pytest.mark.parametrize("levels", [3, 4])
def test_loo_rmse_equals_brute_force_refits(levels: int) -> None:
    L, W = grid(levels)
    rng = np.random.default_rng(levels)
    values = {
        "smooth": 1.0 + L - 2 * W + 3 * L * W + rng.normal(scale=0.01, size=L.size),
        "noise": rng.normal(size=L.size),
    }
    fit = fit_quadratic(L, W, values)
    for name, y in values.items():
        errors = []
        for i in range(L.size):
            keep = np.arange(L.size) != i
            X = design_matrix(L[keep], W[keep])
            beta = np.linalg.lstsq(X, y[keep], rcond=None)[0]
            errors.append(y[i] - design_matrix(L[i], W[i]) @ beta)
        assert_allclose(fit.loo_rmse[name], np.sqrt(np.mean(np.square(errors))), rtol=1e-9)
        residual = y - design_matrix(L, W) @ np.array(fit.coefficients[name])
        assert_allclose(fit.r_squared[name], 1 - np.sum(residual**2) / np.sum((y - y.mean()) ** 2), rtol=1e-12)
        assert_allclose(fit.max_residual[name], np.abs(residual).max(), rtol=1e-12)


def test_loo_on_table_2_equals_brute_force(paper_doe, ours) -> None:
    L, W, free = paper_doe.lengths_m, paper_doe.widths_m, paper_doe.free_parameters()
    for name in PARAMETER_NAMES:
        errors = []
        for i in range(L.size):
            keep = np.arange(L.size) != i
            single = fit_quadratic(L[keep], W[keep], {name: free[name][keep]})
            errors.append(free[name][i] - predict(single.coefficients, L[i], W[i])[0])
        assert_allclose(ours.loo_rmse[name], np.sqrt(np.mean(np.square(errors))), rtol=1e-9)


def test_exactly_six_points_interpolate_and_have_no_loo() -> None:
    """Six points in general position: the fit interpolates, leverages are 1, LOO is undefined."""
    L = np.array([0.2, 0.25, 0.3, 0.2, 0.25, 0.22])
    W = np.array([0.08, 0.08, 0.08, 0.12, 0.10, 0.11])
    y = np.array([1.0, 2.0, 0.5, -1.0, 3.0, 0.2])
    fit = fit_quadratic(L, W, {"y": y})
    assert fit.max_residual["y"] < 1e-9
    assert math.isnan(fit.loo_rmse["y"])


@pytest.mark.parametrize(
    ("lengths", "widths"),
    [
        (np.linspace(0.2, 0.3, 9), np.full(9, 0.1)),  # one level of W
        (np.repeat([0.2, 0.3], 4), np.tile([0.08, 0.09, 0.1, 0.12], 2)),  # two levels of L
        (*[a.ravel() for a in np.meshgrid([0.2, 0.3], [0.08, 0.12])],),  # 4 points < 6
        (np.linspace(0.2, 0.3, 9), 0.4 * np.linspace(0.2, 0.3, 9)),  # collinear: W = 0.4 L
    ],
)
def test_rank_deficient_designs_raise(lengths: np.ndarray, widths: np.ndarray) -> None:
    with pytest.raises(InvalidParameterError):
        fit_quadratic(lengths, widths, {"p": np.arange(len(lengths), dtype=float)})


@pytest.mark.parametrize(
    "values",
    [
        {"p": np.array([1.0] * 8 + [float("nan")])},
        {"p": np.array([1.0] * 8 + [float("inf")])},
        {"p": np.ones(8)},  # wrong length
    ],
)
def test_bad_values_raise(values: dict) -> None:
    L, W = grid(3)
    with pytest.raises(InvalidParameterError):
        fit_quadratic(L, W, values)


def test_non_finite_sizes_raise() -> None:
    L, W = grid(3)
    L[4] = float("nan")
    with pytest.raises(InvalidParameterError):
        fit_quadratic(L, W, {"p": np.ones(9)})


def test_design_matrix_columns_follow_the_basis() -> None:
    assert BASIS == ("1", "L", "W", "L^2", "L*W", "W^2")
    assert_allclose(design_matrix(0.3, 0.1), [1.0, 0.3, 0.1, 0.09, 0.03, 0.01], rtol=1e-15, atol=0)
    rows = design_matrix(*grid(3))
    assert rows.shape == (9, 6)
    assert_allclose(rows[0], [1, 0.2, 0.08, 0.04, 0.016, 0.0064], rtol=1e-15)
