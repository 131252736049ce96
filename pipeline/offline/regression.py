"""Second-order regression of each parameter on the scene variables (the paper's Eq. 9).

p(L, W) = b0 + b1 L + b2 W + b3 L^2 + b4 L W + b5 W^2, fitted by least squares per
parameter, with R^2 and the leave-one-out (PRESS) error reported per parameter. Over k
variables (:class:`pipeline.offline.variables.Variables`, e.g. (L, W, x)) the same full
quadratic: 1, v1..vk, then v_i v_j for i <= j (:func:`fit_quadratic_points`,
:func:`predict_points`); for (L, W) it is the paper's basis, term for term, and gives the same
floats as :func:`fit_quadratic` and :func:`predict`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from pipeline.exceptions import InvalidParameterError
from pipeline.offline.variables import DEFAULT_VARIABLES, Variables, quadratic_design

#: The basis of the (L, W) regression; :attr:`Variables.basis` gives it for k variables.
BASIS: tuple[str, ...] = DEFAULT_VARIABLES.basis


def design_matrix(length_m: np.ndarray, width_m: np.ndarray) -> np.ndarray:
    """Rows [1, L, W, L^2, LW, W^2] for sizes L, W [m] of any (equal) shape: (..., 6)."""
    L = np.asarray(length_m, dtype=float)
    W = np.asarray(width_m, dtype=float)
    return np.stack([np.ones_like(L), L, W, L * L, L * W, W * W], -1)


def coefficient_of_determination(observed: np.ndarray, residual: np.ndarray) -> float:
    """R^2 = 1 - SS_residual / SS_total of one parameter's fit (1 for a constant parameter)."""
    total = float(np.sum((observed - observed.mean()) ** 2))
    return 1.0 - float(np.sum(residual**2)) / total if total > 0 else 1.0


@dataclass(frozen=True)
class QuadraticFit:
    """Fitted coefficients and quality per parameter.

    Attributes:
        coefficients: name -> (b0..b5) in :data:`BASIS` order.
        r_squared: name -> coefficient of determination (1 for a constant parameter).
        loo_rmse: name -> root-mean-square leave-one-out prediction error (NaN if undefined).
        max_residual: name -> largest |fitted - observed| over the data.
        variables: The scene variables of the fit; the coefficients are in the order of its basis.
    """

    coefficients: dict[str, tuple[float, ...]]
    r_squared: dict[str, float]
    loo_rmse: dict[str, float]
    max_residual: dict[str, float]
    variables: Variables = DEFAULT_VARIABLES


def fit_quadratic(length_m: np.ndarray, width_m: np.ndarray, values: Mapping[str, np.ndarray]) -> QuadraticFit:
    """Least-squares fit of every parameter in ``values`` on the basis of :data:`BASIS`.

    Raises:
        InvalidParameterError: fewer than 6 distinct experiments, or a rank-deficient design
            (e.g. every experiment at the same W), or non-finite data.
    """
    return _fit(design_matrix(length_m, width_m), values, DEFAULT_VARIABLES)


def fit_quadratic_points(
    points: np.ndarray, values: Mapping[str, np.ndarray], variables: Variables | tuple[str, ...] | None = None
) -> QuadraticFit:
    """Least-squares fit of every parameter in ``values`` on the full quadratic in k variables.

    Args:
        points: The design's variable values, (n runs, k), columns in ``variables``' order.
        values: Parameter name -> (n,) values at the runs.
        variables: The k variables (default (L, W)).

    Raises:
        InvalidParameterError: ``points`` not (n, k); fewer runs than basis terms, a
            rank-deficient design (fewer than 3 levels of a variable), or non-finite data.
    """
    variables = Variables.of(variables)
    P = np.asarray(points, dtype=float)
    if P.ndim != 2 or P.shape[1] != variables.k:
        raise InvalidParameterError("points", P.shape, f"(n, {variables.k}): one column per variable {variables.names}")
    return _fit(variables.design(P), values, variables)


def _fit(X: np.ndarray, values: Mapping[str, np.ndarray], variables: Variables) -> QuadraticFit:
    size, names = variables.basis_size, ", ".join(variables.names)
    if X.ndim != 2 or X.shape[0] < size:
        raise InvalidParameterError(
            "experiments", X.shape[0] if X.ndim == 2 else X.shape, f"at least {size} ({names}) points"
        )
    if not np.all(np.isfinite(X)):
        raise InvalidParameterError(f"({names})", "non-finite", "finite values")
    if np.linalg.matrix_rank(X) < size:
        raise InvalidParameterError(
            "experiments",
            "rank-deficient design",
            f"at least 3 levels of {' and of '.join(variables.names)} (a full quadratic in {names})",
        )
    hat = X @ np.linalg.pinv(X)
    leverage = np.diag(hat)
    coefficients, r_squared, loo, max_residual = {}, {}, {}, {}
    for name, raw in values.items():
        y = np.asarray(raw, dtype=float)
        if y.shape != (X.shape[0],) or not np.all(np.isfinite(y)):
            raise InvalidParameterError(name, raw, f"{X.shape[0]} finite values")
        beta, *_ = np.linalg.lstsq(X, y, rcond=None)
        residual = y - X @ beta
        r_squared[name] = coefficient_of_determination(y, residual)
        with np.errstate(divide="ignore", invalid="ignore"):
            press = residual / (1.0 - leverage)
        loo[name] = float(np.sqrt(np.mean(press**2))) if np.all(leverage < 1 - 1e-9) else float("nan")
        coefficients[name] = tuple(float(b) for b in beta)
        max_residual[name] = float(np.max(np.abs(residual)))
    return QuadraticFit(coefficients, r_squared, loo, max_residual, variables)


def predict(coefficients: Mapping[str, tuple[float, ...]], length_m: np.ndarray, width_m: np.ndarray) -> np.ndarray:
    """Evaluate every fitted parameter at (L, W): shape (..., number of parameters), in mapping order."""
    X = design_matrix(length_m, width_m)
    B = np.array([coefficients[name] for name in coefficients])
    return X @ B.T


def predict_points(coefficients: Mapping[str, tuple[float, ...]], points: np.ndarray) -> np.ndarray:
    """Evaluate every fitted parameter at ``points`` (..., k), the coefficients being on the
    k-variable basis (:class:`pipeline.offline.variables.Variables`): shape (..., number of
    parameters), in mapping order. For k = 2 the same floats as :func:`predict`."""
    B = np.array([coefficients[name] for name in coefficients])
    return quadratic_design(points, None) @ B.T
