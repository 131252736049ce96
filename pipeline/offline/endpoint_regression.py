"""Second-order regression that keeps the end effector within a tolerance of P1 and P5.

The plain regression (:mod:`pipeline.offline.regression`, the paper's Eq. 9) fits each of the eight
parameters to the DOE optima on its own. For the paper family the tip's start and end points
depend on all eight at once (a 10 mrad error in gamma1 moves the tip by up to 6.5 mm), so the
small residuals of eight independent fits add up to endpoint errors between the DOE points
larger than at the DOE points themselves (``python -m pipeline.build --plain`` then
``python -m verify.sweep`` shows it). This fit keeps the model
p(L, W) = b0 + b1 L + b2 W + b3 L^2 + b4 L W + b5 W^2 and its data term, and constrains the
endpoint errors on a grid over the fitted range:

    minimise  sum_DOE |p(L_i, W_i) - p_i|^2   subject to   |tip(0) - P1|, |tip(T) - P5| <= tolerance

at every grid obstacle (scipy's SLSQP from the plain fit, analytic gradients). The result is
still a closed-form quadratic in (L, W).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from pipeline.exceptions import EndpointConstraintWarning, InvalidParameterError
from pipeline.model.kinematics import forward_kinematics, reach_annulus_m
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.motion.path import desired_path
from pipeline.motion.trajectory import PARAMETER_NAMES
from pipeline.offline.regression import QuadraticFit, coefficient_of_determination, design_matrix, fit_quadratic
from pipeline.validation import check_positive, check_positive_int


@dataclass(frozen=True)
class EndpointConstraint:
    """Settings of the endpoint-constrained regression.

    Attributes:
        tolerance_m: Endpoint error allowed without penalty at every grid point [m].
        grid_points: Grid points per axis over the fitted range (grid_points^2 in all).
        max_iterations: SLSQP iteration budget.
    """

    tolerance_m: float = 0.002
    grid_points: int = 21
    max_iterations: int = 1000

    def __post_init__(self) -> None:
        check_positive("tolerance_m", self.tolerance_m)
        check_positive_int("grid_points", self.grid_points, minimum=2)
        check_positive_int("max_iterations", self.max_iterations)


@dataclass(frozen=True, eq=False)
class EndpointTargets:
    """P1, P5 and T on a grid of obstacle sizes.

    Attributes:
        lengths_m, widths_m: Grid sizes [m], shape (G,).
        start_m, end_m: P1 and P5 (x, y) [m], shape (G, 2).
        duration_s: T [s], shape (G,).
        link_lengths_m: (l1, l2) [m].
    """

    lengths_m: np.ndarray
    widths_m: np.ndarray
    start_m: np.ndarray
    end_m: np.ndarray
    duration_s: np.ndarray
    link_lengths_m: tuple[float, float]


def endpoint_targets(
    fitted_range_m: Mapping[str, tuple[float, float]],
    scene: Scene,
    link_lengths_m: tuple[float, float],
    grid_points: int,
) -> EndpointTargets:
    """The grid_points x grid_points grid over the fitted range, with each obstacle's P1, P5, T.

    Raises:
        UnreachableObstacleError: a grid obstacle's path leaves the arm's reach.
    """
    reach_m = reach_annulus_m(link_lengths_m)
    axes = [np.linspace(*fitted_range_m[name], grid_points) for name in ("L", "W")]
    lengths, widths = np.meshgrid(*axes)
    lengths, widths = lengths.ravel(), widths.ravel()
    paths = [desired_path(Obstacle.in_scene(L, W, scene), scene, reach_m) for L, W in zip(lengths, widths, strict=True)]
    return EndpointTargets(
        lengths_m=lengths,
        widths_m=widths,
        start_m=np.array([p.points_m[0] for p in paths]),
        end_m=np.array([p.points_m[-1] for p in paths]),
        duration_s=np.array([p.duration_s for p in paths]),
        link_lengths_m=(float(link_lengths_m[0]), float(link_lengths_m[1])),
    )


def _ends(parameters: np.ndarray, targets: EndpointTargets) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tip-minus-target (G, 2 ends, 2) [m], joint angles (G, 2 ends, 2 joints) [rad], and
    d theta / d (A, w, phi, gamma) (G, 2 ends, 2 joints, 4)."""
    A, w, phi, gamma = (parameters[:, i::4] for i in range(4))  # (G, 2 joints) each
    times = np.stack([np.zeros_like(targets.duration_s), targets.duration_s], -1)[:, :, None]  # (G, 2, 1)
    angle = w[:, None, :] * times + phi[:, None, :]
    theta = A[:, None, :] * np.sin(angle) + gamma[:, None, :]
    d_theta = np.stack(
        [np.sin(angle), A[:, None, :] * times * np.cos(angle), A[:, None, :] * np.cos(angle), np.ones_like(angle)], -1
    )
    delta = forward_kinematics(theta, targets.link_lengths_m) - np.stack([targets.start_m, targets.end_m], 1)
    return delta, theta, d_theta


def endpoint_errors_m(parameters: np.ndarray, targets: EndpointTargets) -> np.ndarray:
    """|tip(0) - P1| and |tip(T) - P5| [m] for the 8 parameters (G, 8) at each grid point: (G, 2)."""
    delta, _, _ = _ends(np.asarray(parameters, dtype=float), targets)
    return np.linalg.norm(delta, axis=-1)


def _tip_jacobian(theta: np.ndarray, link_lengths_m: tuple[float, float]) -> np.ndarray:
    """d tip / d theta by Eq. 2 for joint angles (..., 2): shape (..., xy, joint)."""
    l1, l2 = link_lengths_m
    s1, c1 = np.sin(theta[..., 0]), np.cos(theta[..., 0])
    s12, c12 = np.sin(theta.sum(-1)), np.cos(theta.sum(-1))
    return np.stack([np.stack([-l1 * s1 - l2 * s12, -l2 * s12], -1), np.stack([l1 * c1 + l2 * c12, l2 * c12], -1)], -2)


def endpoint_slack(b: np.ndarray, X_grid: np.ndarray, targets: EndpointTargets, tolerance_m: float) -> np.ndarray:
    """1 - (e / tolerance)^2 for every grid obstacle and end, (2 G,): >= 0 where the endpoint
    error e is within the tolerance. ``b`` is the (6, 8) coefficient matrix, row-major
    (basis x parameter); ``X_grid`` the design matrix of the grid."""
    delta, _, _ = _ends(X_grid @ np.reshape(b, (6, 8)), targets)
    return (1.0 - np.sum(delta * delta, -1) / tolerance_m**2).ravel()


def endpoint_slack_jacobian(
    b: np.ndarray, X_grid: np.ndarray, targets: EndpointTargets, tolerance_m: float
) -> np.ndarray:
    """d :func:`endpoint_slack` / d b, shape (2 G, 48), in closed form."""
    delta, theta, d_theta = _ends(X_grid @ np.reshape(b, (6, 8)), targets)
    d_theta_sq = np.einsum("gex,gexj->gej", delta, _tip_jacobian(theta, targets.link_lengths_m))
    d_p = (d_theta_sq[..., None] * d_theta).reshape(*delta.shape[:2], 8)  # joint-major = names order
    return (-2.0 / tolerance_m**2 * np.einsum("gep,gk->gekp", d_p, X_grid)).reshape(-1, 48)


def fit_with_endpoints(
    length_m: np.ndarray,
    width_m: np.ndarray,
    values: Mapping[str, np.ndarray],
    targets: EndpointTargets,
    constraint: EndpointConstraint,
) -> tuple[QuadraticFit, dict]:
    """Fit the paper family's 8 parameters with the endpoint errors held within the tolerance
    at every obstacle of ``targets``.

    Returns:
        (the fit: coefficients, R^2 and max residual of the constrained fit, and the plain
        fit's leave-one-out errors; a report: grid endpoint error max of the plain and of the
        constrained fit [m], largest deviation from a DOE optimum [rad or rad/s], whether
        SLSQP converged).

    Warns:
        EndpointConstraintWarning: SLSQP stopped without converging (the report says how
            far the endpoint errors got).

    Raises:
        InvalidParameterError: ``values`` is not the paper family's 8 parameters; or as
            :func:`pipeline.offline.regression.fit_quadratic`.
    """
    if tuple(values) != PARAMETER_NAMES:
        raise InvalidParameterError("parameters", tuple(values), f"the paper family's {PARAMETER_NAMES}")
    plain = fit_quadratic(length_m, width_m, values)
    X_data = design_matrix(length_m, width_m)  # (n, 6)
    X_grid = design_matrix(targets.lengths_m, targets.widths_m)  # (G, 6)
    Y = np.stack([np.asarray(values[name], dtype=float) for name in PARAMETER_NAMES], -1)  # (n, 8)

    def objective(b: np.ndarray) -> tuple[float, np.ndarray]:
        residual = X_data @ b.reshape(6, 8) - Y
        return float(np.sum(residual * residual)), (2.0 * X_data.T @ residual).ravel()

    start = np.stack([plain.coefficients[name] for name in PARAMETER_NAMES], -1).ravel()  # (6, 8) row-major
    result = minimize(
        objective,
        start,
        jac=True,
        method="SLSQP",
        constraints=[
            {
                "type": "ineq",
                "fun": endpoint_slack,
                "jac": endpoint_slack_jacobian,
                "args": (X_grid, targets, constraint.tolerance_m),
            }
        ],
        options={"maxiter": constraint.max_iterations, "ftol": 1e-12},
    )
    B = result.x.reshape(6, 8)
    fitted = X_data @ B
    coefficients, r_squared, max_residual = {}, {}, {}
    for i, name in enumerate(PARAMETER_NAMES):
        residual = Y[:, i] - fitted[:, i]
        r_squared[name] = coefficient_of_determination(Y[:, i], residual)
        max_residual[name] = float(np.max(np.abs(residual)))
        coefficients[name] = tuple(float(v) for v in B[:, i])
    after = float(endpoint_errors_m(X_grid @ B, targets).max())
    report = {
        "tolerance_m": constraint.tolerance_m,
        "grid_points": constraint.grid_points,
        "grid_endpoint_error_max_plain_m": float(endpoint_errors_m(X_grid @ start.reshape(6, 8), targets).max()),
        "grid_endpoint_error_max_m": after,
        "max_deviation_from_doe": float(np.max(np.abs(fitted - Y))),
        "converged": bool(result.success),
        "loo_rmse_of": "the plain least-squares fit",
    }
    if not result.success:
        warnings.warn(
            f"endpoint-constrained regression did not converge ({result.message}); grid endpoint error max "
            f"{after * 1e3:.3f} mm against a tolerance of {constraint.tolerance_m * 1e3:.3f} mm",
            EndpointConstraintWarning,
            stacklevel=2,
        )
    return QuadraticFit(coefficients, r_squared, plain.loo_rmse, max_residual), report
