"""SLSQP in normalised variables (pipeline.offline.coefficient_basis): the change of basis against
the basis evaluated at the normalised points, the chained gradients against finite differences,
and a constrained least-squares fit that lands on the raw basis' answer."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline.exceptions import InvalidParameterError
from pipeline.offline.coefficient_basis import CoefficientBasis, basis_change, normalised_basis, solve_coefficients
from pipeline.offline.variables import DEFAULT_VARIABLES, Variables, quadratic_design

_CENTRE = np.array([0.2, 0.1, 0.0, 0.56])
_HALF = np.array([0.05, 0.02, 0.03, 0.01])


@settings(max_examples=60, deadline=None)
@given(
    k=st.integers(1, 4),
    centre=st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4),
    half=st.lists(st.floats(1e-3, 1.0), min_size=4, max_size=4),
    seed=st.integers(0, 2**32 - 1),
)
def test_the_change_of_basis_is_the_basis_at_the_normalised_points(
    k: int, centre: list[float], half: list[float], seed: int
) -> None:
    c, h = np.array(centre[:k]), np.array(half[:k])
    v = c + h * np.random.default_rng(seed).uniform(-1.0, 1.0, (20, k))
    expected = quadratic_design((v - c) / h)
    got = quadratic_design(v) @ basis_change(c, h)
    # Each entry of the product sums m terms of size up to (|c| + h)^2 / h^2; rounding is relative to that.
    scale = (np.abs(c).max() + h.max()) ** 2 / h.min() ** 2
    np.testing.assert_allclose(got, expected, rtol=0.0, atol=1e-13 * scale * expected.shape[1])


def test_raw_and_normalised_coefficients_describe_the_same_quadratic() -> None:
    basis = CoefficientBasis(basis_change(_CENTRE, _HALF))
    rng = np.random.default_rng(3)
    g = rng.normal(size=15 * 8)
    v = _CENTRE + _HALF * rng.uniform(-1.0, 1.0, (30, 4))
    raw = quadratic_design(v) @ basis.to_raw(g).reshape(15, 8)
    normalised = quadratic_design((v - _CENTRE) / _HALF) @ g.reshape(15, 8)
    np.testing.assert_allclose(raw, normalised, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(basis.from_raw(basis.to_raw(g)), g, rtol=1e-9, atol=1e-9)


def test_the_spanning_basis_maps_the_box_to_the_unit_cube() -> None:
    points = _CENTRE + _HALF * np.array([[-1.0, -1.0, -1.0, -1.0], [1.0, 1.0, 1.0, 1.0], [0.3, -0.2, 0.1, 0.0]])
    A = CoefficientBasis.spanning(points).matrix
    np.testing.assert_allclose(quadratic_design(points) @ A, quadratic_design((points - _CENTRE) / _HALF), atol=1e-9)


def test_the_chained_gradient_matches_finite_differences() -> None:
    basis = CoefficientBasis(basis_change(_CENTRE[:2], _HALF[:2]))
    rng = np.random.default_rng(5)
    W = rng.normal(size=(3, 6 * 8))

    def constraint(b: np.ndarray) -> np.ndarray:  # nonlinear in b, with its Jacobian
        return np.sin(W @ b)

    def jacobian(b: np.ndarray) -> np.ndarray:
        return np.cos(W @ b)[:, None] * W

    g = rng.normal(scale=0.01, size=6 * 8)
    chained = basis._chain(jacobian(basis.to_raw(g)))
    step = 1e-7
    for column in rng.choice(g.size, 8, replace=False):
        e = np.zeros_like(g)
        e[column] = step
        numeric = (constraint(basis.to_raw(g + e)) - constraint(basis.to_raw(g - e))) / (2 * step)
        np.testing.assert_allclose(chained[:, column], numeric, rtol=1e-5, atol=1e-6)


def test_a_constrained_fit_in_normalised_variables_finds_the_raw_optimum() -> None:
    """Least squares of a quadratic in (L, W, x, d) to noisy data, subject to one linear
    constraint on the prediction at a point: the KKT solution in closed form, against SLSQP in
    the normalised basis."""
    rng = np.random.default_rng(11)
    v = _CENTRE + _HALF * rng.uniform(-1.0, 1.0, (81, 4))
    X = quadratic_design(v)
    Y = rng.normal(size=(81, 8))
    x0 = quadratic_design(_CENTRE + 0.5 * _HALF)  # constraint: sum of the 8 predictions there <= 1
    a = np.kron(x0, np.ones(8))  # d(sum_p (x0 B)_p) / d b, b = B row-major

    def objective(b: np.ndarray) -> tuple[float, np.ndarray]:
        r = X @ b.reshape(15, 8) - Y
        return float(np.sum(r * r)), (2.0 * X.T @ r).ravel()

    constraint = (lambda b: np.array([1.0 - a @ b]), lambda b: -a[None, :])
    H = 2.0 * np.kron(X.T @ X, np.eye(8))  # KKT of min |X B - Y|^2 s.t. a b = 1 (active)
    kkt = np.block([[H, a[:, None]], [a[None, :], np.zeros((1, 1))]])
    exact = np.linalg.solve(kkt, np.concatenate([2.0 * (X.T @ Y).ravel(), [1.0]]))[:-1]
    assert a @ np.linalg.lstsq(X, Y, rcond=None)[0].ravel() > 1.0  # the constraint binds
    basis = normalised_basis(Variables(("L", "W", "x", "d")), v)
    options = {"maxiter": 500, "ftol": 1e-12}
    result = solve_coefficients(objective, np.zeros(120), [constraint], options, basis)
    assert result.success
    np.testing.assert_allclose(X @ result.x.reshape(15, 8), X @ exact.reshape(15, 8), atol=1e-6)
    assert objective(result.x)[0] <= objective(exact)[0] * (1 + 1e-9) + 1e-12


def test_size_only_fits_stay_in_the_raw_basis() -> None:
    assert normalised_basis(DEFAULT_VARIABLES, np.array([[0.1, 0.05], [0.3, 0.2]])) is None


@pytest.mark.parametrize(
    ("centre", "half"),
    [([0.0, 0.0], [0.1]), ([0.0], [0.0]), ([0.0], [-0.1]), ([np.nan], [0.1]), ([0.0], [np.inf])],
)
def test_bad_boxes_are_refused(centre: list[float], half: list[float]) -> None:
    with pytest.raises(InvalidParameterError, match="half_width"):
        basis_change(np.array(centre), np.array(half))
