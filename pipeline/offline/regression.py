"""Second-order regression of each parameter on the obstacle size (the paper's Eq. 9).

p(L, W) = b0 + b1 L + b2 W + b3 L^2 + b4 L W + b5 W^2, fitted by least squares per
parameter, with R^2 and the leave-one-out (PRESS) error reported per parameter.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from pipeline.exceptions import InvalidParameterError

BASIS: tuple[str, ...] = ("1", "L", "W", "L^2", "L*W", "W^2")


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
    """

    coefficients: dict[str, tuple[float, ...]]
    r_squared: dict[str, float]
    loo_rmse: dict[str, float]
    max_residual: dict[str, float]


def fit_quadratic(length_m: np.ndarray, width_m: np.ndarray, values: Mapping[str, np.ndarray]) -> QuadraticFit:
    """Least-squares fit of every parameter in ``values`` on the basis of :data:`BASIS`.

    Raises:
        InvalidParameterError: fewer than 6 distinct experiments, or a rank-deficient design
            (e.g. every experiment at the same W), or non-finite data.
    """
    X = design_matrix(length_m, width_m)
    if X.ndim != 2 or X.shape[0] < len(BASIS):
        raise InvalidParameterError("experiments", X.shape[0] if X.ndim == 2 else X.shape, "at least 6 (L, W) points")
    if not np.all(np.isfinite(X)):
        raise InvalidParameterError("(L, W)", "non-finite", "finite sizes")
    if np.linalg.matrix_rank(X) < len(BASIS):
        raise InvalidParameterError(
            "experiments", "rank-deficient design", "at least 3 levels of L and of W (a full quadratic in L and W)"
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
    return QuadraticFit(coefficients, r_squared, loo, max_residual)


def predict(coefficients: Mapping[str, tuple[float, ...]], length_m: np.ndarray, width_m: np.ndarray) -> np.ndarray:
    """Evaluate every fitted parameter at (L, W): shape (..., number of parameters), in mapping order."""
    X = design_matrix(length_m, width_m)
    B = np.array([coefficients[name] for name in coefficients])
    return X @ B.T
