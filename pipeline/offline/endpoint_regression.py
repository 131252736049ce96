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

Between the grid points the error can exceed the value held at them (by 0.0045 mm on the
21 x 21 grid of the default build), and the range certificate, which bounds the error over
whole cells, needs room to prove the tolerance. So the fit holds a slightly smaller tolerance,
tolerance (1 - headroom), and checks a denser grid (``check_points`` per axis): the check
points where the error exceeds it are added to the constrained obstacles, worst first, and the
fit is repeated from where it stopped (constraint generation) until the check grid's maximum
is within tolerance (1 - headroom / 2) or ``check_rounds`` is reached. The report gives both
grids' maxima.

Over k scene variables (:class:`pipeline.offline.variables.Variables`, e.g. (L, W, x)) the model
is the full quadratic in k variables and the grids have ``grid_points`` (``check_points``) per
variable, grid_points^k obstacles in all (:func:`fit_points_with_endpoints`). An obstacle moved
by x has the path of x = 0 moved by x: P1 and P5 shift by x, T does not change (the generator's
T, to the bit).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass, replace
from types import MappingProxyType

import numpy as np

from pipeline.exceptions import EndpointConstraintWarning, InvalidParameterError, UnreachableObstacleError
from pipeline.model.kinematics import forward_kinematics, reach_annulus_m
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.motion.path import desired_path
from pipeline.motion.trajectory import PARAMETER_NAMES
from pipeline.offline.coefficient_basis import normalised_basis, solve_coefficients
from pipeline.offline.regression import (
    QuadraticFit,
    coefficient_of_determination,
    design_matrix,
    fit_quadratic,
    fit_quadratic_points,
)
from pipeline.offline.variables import DEFAULT_VARIABLES, SIZE, Variables
from pipeline.validation import check_positive, check_positive_int

#: (grid_points, check_points) of the endpoint constraint over k > 2 variables, per number of
#: variables (the largest entry beyond the table), in place of the (L, W) fit's 21 and 101 per axis
#: (21^3 and 101^3 obstacles would cost minutes and gigabytes). SLSQP's cost per iteration grows
#: with the constrained obstacles: over (L, W, x, d) on the default build's DOE, 9^4 took 286 s
#: and 5^4 13 s, both with the check grid's 21^4 within the check tolerance without adding a
#: point (1.323 and 1.393 mm against 1.65 mm); the range certificate bounds the error between.
K_ENDPOINT_GRID: Mapping[int, tuple[int, int]] = MappingProxyType({3: (9, 21), 4: (5, 21)})
#: SLSQP's precision goal of the endpoint-constrained fit over k > 2 variables (the (L, W) fit's
#: 1e-12 is not reached within its iteration budget there: ``EndpointConstraint.ftol``).
K_ENDPOINT_FTOL = 1e-9
#: Headroom of the endpoint-constrained fit over k > 2 variables, per number of variables: the
#: error between the grid points, and the range certificate's endpoint bound above the error over
#: its cells, must stay within the headroom (the map cuts a leaf while its bound exceeds the
#: tolerance, down to its smallest cell: ``range_certificate.DEFAULT_CELLS``). Headroom is room
#: the end poses lose near W = 0.12 m, where the margin is lost.
#: k = 3 (cells down to 1/256): on the default (L, W, x) build
#: (python -m pipeline.build --vary x -0.03 0.03), with 0.05 the map's endpoint bound is within
#: 2 mm on 100 % of the box (largest 2.000 mm) and, with a refit of 400 points per round and no
#: strips, the margin holds on 98.60 % of it (98.51 % with 0.1, whose errors the fit holds at
#: 1.8 mm; docs/results.md, "Over the obstacle's centre x").
#: k = 4: 0.35; with 0.1 the first fit over d in [0.55, 0.57] m collides on the sampled check
#: (down to -0.32 mm at x = 0.03 m, d = 0.55 m, L = 0.30 m, W = 0.12 m), which refuses a build
#: without the certifiable regression (with it, the check judges the refit). The certifiable
#: regression's refit, whose clearance constraints keep it off the obstacle, has its own headroom
#: (``pipeline.certify.certifiable_regression.REFIT_ENDPOINT_HEADROOM``).
K_ENDPOINT_HEADROOM: Mapping[int, float] = MappingProxyType({3: 0.05, 4: 0.35})
#: SLSQP's exit statuses that stop at an iterate which may be usable (scipy.optimize's SLSQP): 9,
#: its iteration budget; 8, no descent along its search direction (in normalised variables, a
#: restart from a converged fit with a few check points added can end there, at the optimum to
#: within the precision goal).
_STALLED = (8, 9)
#: A stalled iterate (:data:`_STALLED`) is usable when its largest endpoint error on the grid is
#: within the fit tolerance times (1 + this): SLSQP holds inequality constraints to about 1e-7
#: relative (1.3000001 mm for 1.3 mm), far inside the headroom to the tolerance.
_FEASIBLE_ROUNDING = 1e-6
#: How the report's ``solver`` says that the fit stalled at a usable iterate.
_FEASIBLE_STOP = "at an iterate within the fit tolerance"


@dataclass(frozen=True)
class EndpointConstraint:
    """Settings of the endpoint-constrained regression.

    Attributes:
        tolerance_m: Endpoint error allowed without penalty at every grid point [m].
        grid_points: Grid points per axis over the fitted range (grid_points^2 in all).
        max_iterations: SLSQP iteration budget.
        headroom: Fraction of the tolerance kept free [-]: the fit holds tolerance (1 - headroom)
            at its constrained obstacles, so that the error between them stays below the
            tolerance and a certificate over cells has room to prove it.
        check_points: Points per axis of the denser check grid (module docstring); 0: none.
        check_rounds: Rounds of constraint generation from the check grid.
        points_per_round: Cap on check points added per round.
        ftol: SLSQP's precision goal on the objective (sum of squared residuals [rad^2]). Over
            three variables the default's 1e-12 is not reached in 1,000 iterations on the
            default (L, W, x) DOE (the iterates cycle with the grid's constraints active), 1e-9
            is, in 574 (python -m pipeline.build --vary x -0.03 0.03).
    """

    tolerance_m: float = 0.002
    grid_points: int = 21
    max_iterations: int = 1000
    headroom: float = 0.03
    check_points: int = 101
    check_rounds: int = 6
    points_per_round: int = 64
    ftol: float = 1e-12

    def __post_init__(self) -> None:
        check_positive("tolerance_m", self.tolerance_m)
        check_positive("ftol", self.ftol)
        check_positive_int("grid_points", self.grid_points, minimum=2)
        check_positive_int("max_iterations", self.max_iterations)
        if not (isinstance(self.headroom, int | float) and 0.0 <= self.headroom < 0.5):
            raise InvalidParameterError("headroom", self.headroom, "a fraction in [0, 0.5)")
        if isinstance(self.check_points, bool) or not isinstance(self.check_points, int) or self.check_points < 0:
            raise InvalidParameterError("check_points", self.check_points, "0 (no check grid) or an integer >= 2")
        if self.check_points == 1:
            raise InvalidParameterError("check_points", self.check_points, "0 (no check grid) or an integer >= 2")
        check_positive_int("check_rounds", self.check_rounds)
        check_positive_int("points_per_round", self.points_per_round)

    def for_variables(self, variables: Variables) -> EndpointConstraint:
        """This constraint as a fit over ``variables`` runs it: itself over (L, W); over more
        variables on the coarser grids of :data:`K_ENDPOINT_GRID`, with the precision goal
        :data:`K_ENDPOINT_FTOL` and the headroom :data:`K_ENDPOINT_HEADROOM` of their number (the
        largest one beyond the table; or this constraint's, where coarser or larger)."""
        if variables.is_size_only:
            return self
        grid, check = K_ENDPOINT_GRID.get(variables.k, K_ENDPOINT_GRID[max(K_ENDPOINT_GRID)])
        return replace(
            self,
            grid_points=min(grid, self.grid_points),
            check_points=min(check, self.check_points),
            ftol=max(K_ENDPOINT_FTOL, self.ftol),
            headroom=max(K_ENDPOINT_HEADROOM.get(variables.k, max(K_ENDPOINT_HEADROOM.values())), self.headroom),
        )

    @property
    def fit_tolerance_m(self) -> float:
        """The tolerance held at the constrained obstacles [m]: tolerance (1 - headroom)."""
        return self.tolerance_m * (1.0 - self.headroom)

    @property
    def check_tolerance_m(self) -> float:
        """The check grid's maximum that ends the constraint generation [m]."""
        return self.tolerance_m * (1.0 - 0.5 * self.headroom)


@dataclass(frozen=True, eq=False)
class EndpointTargets:
    """P1, P5 and T on a grid of obstacles.

    Attributes:
        lengths_m, widths_m: Grid sizes [m], shape (G,).
        start_m, end_m: P1 and P5 (x, y) [m], shape (G, 2).
        duration_s: T [s], shape (G,).
        link_lengths_m: (l1, l2) [m].
        extra_m: The values of ``variables.extra`` (e.g. x) [m], shape (G, k - 2); None for (L, W).
        variables: The scene variables of the grid (default (L, W)).
    """

    lengths_m: np.ndarray
    widths_m: np.ndarray
    start_m: np.ndarray
    end_m: np.ndarray
    duration_s: np.ndarray
    link_lengths_m: tuple[float, float]
    extra_m: np.ndarray | None = None
    variables: Variables = DEFAULT_VARIABLES

    @property
    def points(self) -> np.ndarray:
        """The grid's variable values (G, k), columns in ``variables``' order."""
        if self.extra_m is None:
            return np.column_stack([self.lengths_m, self.widths_m])
        return np.column_stack([self.lengths_m, self.widths_m, self.extra_m])

    def design(self) -> np.ndarray:
        """The quadratic basis at the grid's obstacles, (G, basis size); for (L, W) :func:`design_matrix`."""
        if self.extra_m is None:
            return design_matrix(self.lengths_m, self.widths_m)
        return self.variables.design(self.points)


def endpoint_targets(
    fitted_range_m: Mapping[str, tuple[float, float]],
    scene: Scene,
    link_lengths_m: tuple[float, float],
    grid_points: int,
    variables: Variables | tuple[str, ...] | None = None,
) -> EndpointTargets:
    """The grid with ``grid_points`` per variable over the fitted range (one (lo, hi) per
    variable), with each obstacle's P1, P5, T.

    Raises:
        UnreachableObstacleError: a grid obstacle's path leaves the arm's reach.
    """
    variables = Variables.of(variables)
    axes = [np.linspace(*fitted_range_m[name], grid_points) for name in variables.names]
    if variables.is_size_only:
        reach_m = reach_annulus_m(link_lengths_m)
        lengths, widths = np.meshgrid(*axes)
        lengths, widths = lengths.ravel(), widths.ravel()
        paths = [
            desired_path(Obstacle.in_scene(L, W, scene), scene, reach_m) for L, W in zip(lengths, widths, strict=True)
        ]
        return EndpointTargets(
            lengths_m=lengths,
            widths_m=widths,
            start_m=np.array([p.points_m[0] for p in paths]),
            end_m=np.array([p.points_m[-1] for p in paths]),
            duration_s=np.array([p.duration_s for p in paths]),
            link_lengths_m=(float(link_lengths_m[0]), float(link_lengths_m[1])),
        )
    points = np.column_stack([axis.ravel() for axis in np.meshgrid(*axes)])
    return targets_at(points, variables, scene, link_lengths_m)


def targets_at(
    points: np.ndarray, variables: Variables, scene: Scene, link_lengths_m: tuple[float, float]
) -> EndpointTargets:
    """P1, P5 and T of the obstacles at ``points`` (G, k) of ``variables`` (which hold L and W).

    x moves the obstacle and its path rigidly: P1 and P5 are those of the path at x = 0 plus x,
    T that path's. The other variables replace their scene field (:meth:`Variables.scene_for`).

    Raises:
        InvalidParameterError: ``variables`` without L or W, or ``points`` not (G, k).
        UnreachableObstacleError: a constraint point leaves the arm's reach.
    """
    variables = Variables.of(variables)
    if variables.names[:2] != SIZE:
        raise InvalidParameterError("variables", variables.names, "variables that hold L and W")
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or points.shape[1] != variables.k:
        raise InvalidParameterError("points", points.shape, f"(G, {variables.k}): one column per variable")
    reach_m = reach_annulus_m(link_lengths_m)
    extra = variables.extra
    shift = extra.index("x") if "x" in extra else None
    paths: dict[tuple[float, ...], object] = {}
    starts, ends, durations = np.empty((len(points), 2)), np.empty((len(points), 2)), np.empty(len(points))
    for row, values in enumerate(points.tolist()):
        L, W, rest = values[0], values[1], values[2:]
        key = (L, W, *(v for i, v in enumerate(rest) if i != shift))
        path = paths.get(key)
        if path is None:
            fixed = {name: v for i, (name, v) in enumerate(zip(extra, rest, strict=True)) if i != shift}
            moved = variables.scene_for(scene, {**fixed, "x": 0.0} if shift is not None else fixed)
            path = paths[key] = desired_path(Obstacle.in_scene(L, W, moved), moved)
        offset = 0.0 if shift is None else rest[shift]
        shifted = path.points_m + np.array([offset, 0.0])
        for name, point in zip(("P1", "P2", "P3", "P4", "P5"), shifted, strict=True):
            radius = float(np.hypot(*point))
            if not reach_m[0] <= radius <= reach_m[1]:
                raise UnreachableObstacleError(name, radius, reach_m)
        starts[row], ends[row], durations[row] = shifted[0], shifted[-1], path.duration_s
    return EndpointTargets(
        lengths_m=points[:, 0].copy(),
        widths_m=points[:, 1].copy(),
        start_m=starts,
        end_m=ends,
        duration_s=durations,
        link_lengths_m=(float(link_lengths_m[0]), float(link_lengths_m[1])),
        extra_m=points[:, 2:].copy(),
        variables=variables,
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
    error e is within the tolerance. ``b`` is the (m, 8) coefficient matrix, row-major
    (basis x parameter; m = 6 for (L, W)); ``X_grid`` the design matrix of the grid (G, m)."""
    delta, _, _ = _ends(X_grid @ np.reshape(b, (X_grid.shape[-1], 8)), targets)
    return (1.0 - np.sum(delta * delta, -1) / tolerance_m**2).ravel()


def endpoint_slack_jacobian(
    b: np.ndarray, X_grid: np.ndarray, targets: EndpointTargets, tolerance_m: float
) -> np.ndarray:
    """d :func:`endpoint_slack` / d b, shape (2 G, 8 m), in closed form (48 for (L, W))."""
    delta, theta, d_theta = _ends(X_grid @ np.reshape(b, (X_grid.shape[-1], 8)), targets)
    d_theta_sq = np.einsum("gex,gexj->gej", delta, _tip_jacobian(theta, targets.link_lengths_m))
    d_p = (d_theta_sq[..., None] * d_theta).reshape(*delta.shape[:2], 8)  # joint-major = names order
    return (-2.0 / tolerance_m**2 * np.einsum("gep,gk->gekp", d_p, X_grid)).reshape(-1, 8 * X_grid.shape[-1])


def merge_targets(first: EndpointTargets, second: EndpointTargets) -> EndpointTargets:
    """The obstacles of both, ``first``'s then ``second``'s (same arm and variables)."""
    extra = None if first.extra_m is None else np.concatenate([first.extra_m, second.extra_m])
    return EndpointTargets(
        *(np.concatenate([getattr(first, f), getattr(second, f)]) for f in _TARGET_ARRAYS),
        link_lengths_m=first.link_lengths_m,
        extra_m=extra,
        variables=first.variables,
    )


def select_targets(targets: EndpointTargets, rows: np.ndarray) -> EndpointTargets:
    """The obstacles ``rows`` (indices or mask) of ``targets``."""
    return EndpointTargets(
        *(getattr(targets, f)[rows] for f in _TARGET_ARRAYS),
        link_lengths_m=targets.link_lengths_m,
        extra_m=None if targets.extra_m is None else targets.extra_m[rows],
        variables=targets.variables,
    )


_TARGET_ARRAYS = ("lengths_m", "widths_m", "start_m", "end_m", "duration_s")


def _solve(
    objective, start: np.ndarray, targets: EndpointTargets, constraint: EndpointConstraint
) -> tuple[np.ndarray, bool, str]:
    """One SLSQP solve: least squares subject to the endpoint slack >= 0 at ``targets`` (with
    ``constraint``'s fit tolerance, iteration budget and precision goal). Returns the iterate,
    whether it is usable and SLSQP's message: converged, or stalled (:data:`_STALLED`) at an
    iterate that holds every endpoint error within the fit tolerance (plus
    :data:`_FEASIBLE_ROUNDING`, relative; the message then says so). The least squares are the
    fit's preference, the endpoint errors its contract. Over k > 2 variables SLSQP works in
    normalised variables (:mod:`pipeline.offline.coefficient_basis`): in the raw basis, over four
    variables, it crept along the constraints' boundary for its whole budget."""
    X_grid = targets.design()
    slack = (
        lambda b: endpoint_slack(b, X_grid, targets, constraint.fit_tolerance_m),
        lambda b: endpoint_slack_jacobian(b, X_grid, targets, constraint.fit_tolerance_m),
    )
    options = {"maxiter": constraint.max_iterations, "ftol": constraint.ftol}
    result = solve_coefficients(objective, start, [slack], options, normalised_basis(targets.variables, targets.points))
    if result.success or result.status not in _STALLED:
        return result.x, bool(result.success), str(result.message)
    reached = float(_grid_max(result.x, targets).max())
    feasible = reached <= constraint.fit_tolerance_m * (1.0 + _FEASIBLE_ROUNDING)
    if feasible:
        return result.x, True, f"{result.message} {_FEASIBLE_STOP} ({reached * 1e3:.4f} mm)"
    return result.x, False, str(result.message)


def _grid_max(b: np.ndarray, targets: EndpointTargets) -> np.ndarray:
    """max(|tip(0) - P1|, |tip(T) - P5|) [m] per obstacle of ``targets`` for coefficients ``b``."""
    X = targets.design()
    return endpoint_errors_m(X @ b.reshape(X.shape[-1], 8), targets).max(1)


def _generate_constraints(
    objective, b: np.ndarray, targets: EndpointTargets, check: EndpointTargets, constraint: EndpointConstraint
) -> tuple[np.ndarray, bool, str, int, int]:
    """Refit with the worst check points added until the check grid is within
    ``constraint.check_tolerance_m`` (module docstring); returns (b, converged, message, points
    added, rounds)."""
    added, converged, message = 0, True, ""
    for rounds in range(1, constraint.check_rounds + 1):
        errors = _grid_max(b, check)
        over = np.flatnonzero(errors > constraint.fit_tolerance_m)
        if errors.max() <= constraint.check_tolerance_m or over.size == 0:
            return b, converged, message, added, rounds - 1
        worst = over[np.argsort(-errors[over], kind="stable")][: constraint.points_per_round]
        targets = merge_targets(targets, select_targets(check, np.sort(worst)))
        added += worst.size
        b, converged, message = _solve(objective, b, targets, constraint)
        if not converged:
            break
    return b, converged, message, added, rounds


def fit_with_endpoints(
    length_m: np.ndarray,
    width_m: np.ndarray,
    values: Mapping[str, np.ndarray],
    targets: EndpointTargets,
    constraint: EndpointConstraint,
    check: EndpointTargets | None = None,
) -> tuple[QuadraticFit, dict]:
    """Fit the paper family's 8 parameters with the endpoint errors held within
    ``constraint.fit_tolerance_m`` at every obstacle of ``targets``, and at the points of the
    ``check`` grid that exceed it (module docstring).

    Returns:
        (the fit: coefficients, R^2 and max residual of the constrained fit, and the plain
        fit's leave-one-out errors; a report: grid endpoint error max of the plain and of the
        constrained fit [m] on ``targets`` and on ``check``, largest deviation from a DOE
        optimum [rad or rad/s], whether SLSQP converged).

    Warns:
        EndpointConstraintWarning: SLSQP stopped without converging (the report says how
            far the endpoint errors got).

    Raises:
        InvalidParameterError: ``values`` is not the paper family's 8 parameters; or as
            :func:`pipeline.offline.regression.fit_quadratic`.
    """
    if tuple(values) != PARAMETER_NAMES:
        raise InvalidParameterError("parameters", tuple(values), f"the paper family's {PARAMETER_NAMES}")
    if not targets.variables.is_size_only:
        raise InvalidParameterError(
            "targets", targets.variables.names, "(L, W) targets (fit_points_with_endpoints fits k variables)"
        )
    plain = fit_quadratic(length_m, width_m, values)
    return _fit_with_endpoints(design_matrix(length_m, width_m), plain, values, targets, constraint, check)


def fit_points_with_endpoints(
    points: np.ndarray,
    values: Mapping[str, np.ndarray],
    targets: EndpointTargets,
    constraint: EndpointConstraint,
    check: EndpointTargets | None = None,
) -> tuple[QuadraticFit, dict]:
    """:func:`fit_with_endpoints` over the k variables of ``targets`` (e.g. (L, W, x)): the DOE's
    runs ``points`` (n, k), columns in ``targets.variables``' order; ``targets`` and ``check``
    from :func:`endpoint_targets` with those variables. For (L, W) the same floats as
    :func:`fit_with_endpoints`.

    Raises:
        InvalidParameterError: as :func:`fit_with_endpoints`, or ``check`` over other variables.
    """
    if tuple(values) != PARAMETER_NAMES:
        raise InvalidParameterError("parameters", tuple(values), f"the paper family's {PARAMETER_NAMES}")
    variables = targets.variables
    if check is not None and check.variables != variables:
        raise InvalidParameterError("check", check.variables.names, f"a check grid over {variables.names}")
    points = np.asarray(points, dtype=float)
    if variables.is_size_only:
        return fit_with_endpoints(points[:, 0], points[:, 1], values, targets, constraint, check)
    plain = fit_quadratic_points(points, values, variables)
    return _fit_with_endpoints(variables.design(points), plain, values, targets, constraint, check)


def _fit_with_endpoints(
    X_data: np.ndarray,
    plain: QuadraticFit,
    values: Mapping[str, np.ndarray],
    targets: EndpointTargets,
    constraint: EndpointConstraint,
    check: EndpointTargets | None,
) -> tuple[QuadraticFit, dict]:
    """The fit of :func:`fit_with_endpoints` from the design ``X_data`` (n, m) and the plain fit."""
    m = X_data.shape[-1]
    Y = np.stack([np.asarray(values[name], dtype=float) for name in PARAMETER_NAMES], -1)  # (n, 8)

    def objective(b: np.ndarray) -> tuple[float, np.ndarray]:
        residual = X_data @ b.reshape(m, 8) - Y
        return float(np.sum(residual * residual)), (2.0 * X_data.T @ residual).ravel()

    start = np.stack([plain.coefficients[name] for name in PARAMETER_NAMES], -1).ravel()  # (m, 8) row-major
    b, converged, message = _solve(objective, start, targets, constraint)
    added, rounds = 0, 0
    if converged and check is not None:
        b, converged, later, added, rounds = _generate_constraints(objective, b, targets, check, constraint)
        message = later or message  # the first solve's, if no check point was added
    B = b.reshape(m, 8)
    fitted = X_data @ B
    coefficients, r_squared, max_residual = {}, {}, {}
    for i, name in enumerate(PARAMETER_NAMES):
        residual = Y[:, i] - fitted[:, i]
        r_squared[name] = coefficient_of_determination(Y[:, i], residual)
        max_residual[name] = float(np.max(np.abs(residual)))
        coefficients[name] = tuple(float(v) for v in B[:, i])
    after = float(_grid_max(b, targets).max())
    report = {
        "tolerance_m": constraint.tolerance_m,
        "fit_tolerance_m": constraint.fit_tolerance_m,
        "grid_points": constraint.grid_points,
        "grid_endpoint_error_max_plain_m": float(_grid_max(start, targets).max()),
        "grid_endpoint_error_max_m": after,
        "max_deviation_from_doe": float(np.max(np.abs(fitted - Y))),
        "converged": converged,
        "loo_rmse_of": "the plain least-squares fit",
    }
    if _FEASIBLE_STOP in message:  # absent where SLSQP converged, so such files keep their bytes
        report["solver"] = message
    if check is not None:
        report["check_grid_points"] = constraint.check_points
        report["check_grid_endpoint_error_max_m"] = float(_grid_max(b, check).max())
        report["check_points_added"] = added
        report["check_rounds"] = rounds
    if not converged:
        warnings.warn(
            f"endpoint-constrained regression did not converge ({message}); grid endpoint error max "
            f"{after * 1e3:.3f} mm against a tolerance of {constraint.tolerance_m * 1e3:.3f} mm",
            EndpointConstraintWarning,
            stacklevel=3,
        )
    return QuadraticFit(coefficients, r_squared, plain.loo_rmse, max_residual, plain.variables), report
