"""Many obstacles at once: the generator vectorised over (L, W), and the certificate over many trajectories.

For sweeps (``verify.sweep`` and the like), where per-query Python overhead would dominate:

* :func:`generate_batch` gives, for n obstacles, the eight parameters (n, 8), T (n,) and the
  out-of-range flags in a handful of NumPy operations (paper family; a family that needs each
  obstacle's inverse kinematics is expanded per obstacle). The numbers equal :func:`generate`'s
  to rounding (its compiled core adds in another order: the bounds are in
  ``pipeline.online.kernel``; tests compare them); sizes :func:`generate` would refuse are reported per obstacle in
  ``error`` instead of raising, so one bad case does not stop a sweep. Coefficients over more
  scene variables than (L, W) take their values by keyword, one per obstacle
  (``generate_batch(coefficients, L, W, x=xs)``), as :func:`generate` does, and carry the bounds
  of a map over the same variables, looked up at (L, W, x, ...).

:func:`pipeline.online.batch_certify.certify_batch` certifies such a batch with Coal. NumPy only here.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pipeline.certify.region_map import RegionMap
from pipeline.exceptions import InvalidParameterError, PipelineError
from pipeline.motion.path import symmetric_quartic, symmetric_quartic_lengths_m
from pipeline.motion.trajectory import JointTrajectory
from pipeline.offline.coefficients import Coefficients
from pipeline.offline.variables import quadratic_design
from pipeline.online.generator import ATTACHED, _Attached, check_region_map, generate
from pipeline.online.query_state import QueryPlan, state_of


@dataclass(frozen=True, eq=False)
class GeneratedBatch:
    """The generator's answers for n obstacles.

    Attributes:
        lengths_m, widths_m: L, W [m], shape (n,).
        parameters: The 8 parameters (n, 8) (NaN where ``error`` is set).
        durations_s: T [s], shape (n,) (NaN where ``error`` is set).
        extrapolated: (n,) True outside the fitted range.
        error: (n,) None, or why :func:`generate` would refuse this obstacle.
        certified_clearance_m: (n,) the range certificate's clearance bound [m] (NaN without a
            region map, outside its range, or where ``error`` is set).
        endpoint_error_bound_m: (n,) its endpoint-error bound [m] (NaN likewise).
        range_status: (n,) index into :data:`pipeline.certify.STATUSES` (-1 likewise).
        leaf: (n,) the map's leaf holding each obstacle (-1 likewise).
        variables: The extra variables' values per obstacle, name -> (n,) (e.g. {"x": ...}); {} for (L, W).
    """

    lengths_m: np.ndarray
    widths_m: np.ndarray
    parameters: np.ndarray
    durations_s: np.ndarray
    extrapolated: np.ndarray
    error: tuple[str | None, ...]
    certified_clearance_m: np.ndarray | None = None
    endpoint_error_bound_m: np.ndarray | None = None
    range_status: np.ndarray | None = None
    leaf: np.ndarray | None = None
    variables: dict[str, np.ndarray] = field(default_factory=dict)

    def trajectory(self, i: int) -> JointTrajectory:
        """Obstacle ``i``'s joint trajectory."""
        if self.error[i] is not None:
            raise InvalidParameterError("i", i, f"an obstacle with an answer ({self.error[i]})")
        return JointTrajectory.trusted(tuple(self.parameters[i].tolist()), float(self.durations_s[i]))


def generate_batch(
    coefficients: Coefficients,
    lengths_m: np.ndarray,
    widths_m: np.ndarray,
    *,
    x: np.ndarray | None = None,
    d: np.ndarray | None = None,
    region_map: RegionMap | _Attached | None = ATTACHED,
) -> GeneratedBatch:
    """:func:`pipeline.online.generator.generate` for n obstacles at once (range checks off: see ``extrapolated``).

    Args:
        coefficients: The regression coefficients.
        lengths_m, widths_m: Obstacle sizes L, W [m], one-dimensional, equal length n (a scalar is n = 1).
        x, d: The obstacle's centre x and far edge y [m] per obstacle (length n, or a scalar for
            all), for coefficients that vary them; as :func:`pipeline.online.generator.generate`.
        region_map: :data:`pipeline.online.generator.ATTACHED` (default) the map attached to the
            coefficients, None no bounds, or another map of these coefficients: the answers then
            carry its bounds.

    Raises:
        InvalidParameterError: ``coefficients`` is not a Coefficients, or the arrays are not
            numbers of equal one-dimensional shape; a variable of the coefficients without
            values, or values for one they do not vary.
        RegionMapMismatchError: ``region_map`` was made for other coefficients.
    """
    plan = state_of(coefficients).plan
    if region_map is ATTACHED:
        region_map = coefficients.region_map
    elif region_map is not None:
        check_region_map(region_map, coefficients)
    try:
        L = np.atleast_1d(np.asarray(lengths_m, dtype=float))
        W = np.atleast_1d(np.asarray(widths_m, dtype=float))
    except (TypeError, ValueError):
        raise InvalidParameterError("lengths_m / widths_m", "not numbers", "arrays of sizes [m]") from None
    if L.ndim != 1 or W.ndim != 1:
        raise InvalidParameterError(
            "lengths_m / widths_m", (L.shape, W.shape), "one-dimensional arrays (flatten a grid with .ravel())"
        )
    if L.shape != W.shape:
        raise InvalidParameterError("lengths_m / widths_m", (L.shape, W.shape), "arrays of equal length")
    if plan.extra or x is not None or d is not None:
        return _generate_moved_batch(coefficients, plan, L, W, {"x": x, "d": d}, region_map)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        x1, x2 = L / 2.0 + plan.start_dx, L / 2.0 + plan.approach_dx
        bottom = plan.top - W
        y2, y3 = bottom - plan.approach_dy, bottom - plan.apex_dy
        lo, hi = plan.reach
        radii = np.stack([np.hypot(x1, plan.y1), np.hypot(x2, y2), np.abs(y3)], -1)
        valid = (
            np.isfinite(L)
            & np.isfinite(W)
            & (L >= plan.smallest)
            & (W >= plan.smallest)
            & (plan.height >= plan.smallest)
            & ~((bottom <= 0.0) & (plan.top >= 0.0))
            & np.all((radii >= lo) & (radii <= hi), axis=-1)
            & (x1 > x2)
        )
        # The symmetric quartic and its length, as the generator's scalar route, for every obstacle.
        c4, c2, _ = symmetric_quartic(x1, plan.y1, x2, y2, y3)
        durations = symmetric_quartic_lengths_m(x1, c4, c2) / plan.speed
    free = np.stack([np.ones_like(L), L, W, L * L, L * W, W * W], -1) @ plan.matrix_t
    if coefficients.family.uses_endpoint_context or not np.all(valid):
        parameters, errors = _one_by_one(coefficients, L, W, {}, durations)
    else:
        parameters, errors = coefficients.family.expand(free, None), [None] * L.size
    (l_lo, l_hi), (w_lo, w_hi) = plan.l_range, plan.w_range
    extrapolated = ~((L >= l_lo) & (L <= l_hi) & (W >= w_lo) & (W <= w_hi))
    bounds = _map_bounds(region_map, errors, extrapolated, L, W)
    return GeneratedBatch(L, W, np.asarray(parameters, dtype=float), durations, extrapolated, tuple(errors), *bounds)


def _map_bounds(
    region_map: RegionMap | None, errors: list[str | None], extrapolated: np.ndarray, *points: np.ndarray
) -> tuple[np.ndarray | None, ...]:
    """The map's clearance bound, endpoint bound, status and leaf per obstacle at ``points`` (L,
    W, then the extra variables' values in the map's axes order), masked where the obstacle was
    refused or lies outside the fitted range; four Nones without a map."""
    if region_map is None:
        return (None, None, None, None)
    cells = region_map.cells_at(*points)
    bad = np.array([e is not None for e in errors], dtype=bool) | extrapolated
    return (
        np.where(bad, np.nan, cells["clearance_bound_m"]),
        np.where(bad, np.nan, cells["endpoint_bound_m"]),
        np.where(bad, -1, cells["status"]),
        np.where(bad, -1, cells["leaf"]),
    )


def _variable_array(value: object, name: str, n: int) -> np.ndarray:
    """An extra variable's values as a float array (n,) (a scalar is repeated)."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InvalidParameterError(name, "not numbers", f"an array of {n} values [m] or one value") from None
    if array.ndim == 0:
        return np.full(n, float(array))
    if array.shape != (n,):
        raise InvalidParameterError(name, array.shape, f"{n} values, one per obstacle, or one value")
    return array


def _generate_moved_batch(
    coefficients: Coefficients,
    plan: QueryPlan,
    L: np.ndarray,
    W: np.ndarray,
    given: dict,
    region_map: RegionMap | None,
) -> GeneratedBatch:
    """:func:`generate_batch` for coefficients over more variables than (L, W): the same numbers
    as :func:`pipeline.online.generator.generate` with the variables' values, and the bounds of
    ``region_map`` (a map over the same variables) at them."""
    values = {name: _variable_array(v, name, L.size) for name, v in plan.variables.take(given).items()}
    scene = coefficients.scene
    top = values.get("d", np.full(L.size, plan.top))
    y1 = top if scene.start_y_m is None else np.full(L.size, float(scene.start_y_m))
    c = values.get("x", np.zeros(L.size))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        x1, x2 = L / 2.0 + plan.start_dx, L / 2.0 + plan.approach_dx
        bottom = top - W
        y2, y3 = bottom - plan.approach_dy, bottom - plan.apex_dy
        lo, hi = plan.reach
        radii = np.stack(
            [
                np.hypot(x1 + c, y1),
                np.hypot(x2 + c, y2),
                np.hypot(c, y3),
                np.hypot(-x2 + c, y2),
                np.hypot(-x1 + c, y1),
            ],
            -1,
        )
        valid = (
            np.isfinite(L)
            & np.isfinite(W)
            & np.all([np.isfinite(v) for v in values.values()], axis=0)
            & (L >= plan.smallest)
            & (W >= plan.smallest)
            & (plan.height >= plan.smallest)
            & ~((bottom <= 0.0) & (top >= 0.0))
            & np.all((radii >= lo) & (radii <= hi), axis=-1)
            & (x1 > x2)
        )
        # T of the path at x = 0, as the scalar route (the moved path is the same curve).
        c4, c2, _ = symmetric_quartic(x1, y1, x2, y2, y3)
        durations = symmetric_quartic_lengths_m(x1, c4, c2) / plan.speed
    free = quadratic_design(np.stack([L, W, *values.values()], -1)) @ plan.matrix_t
    if coefficients.family.uses_endpoint_context or not np.all(valid):
        parameters, errors = _one_by_one(coefficients, L, W, values, durations)
    else:
        parameters, errors = coefficients.family.expand(free, None), [None] * L.size
    (l_lo, l_hi), (w_lo, w_hi) = plan.l_range, plan.w_range
    inside = (L >= l_lo) & (L <= l_hi) & (W >= w_lo) & (W <= w_hi)
    for (b_lo, b_hi), v in zip(plan.extra_ranges, values.values(), strict=True):
        inside &= (v >= b_lo) & (v <= b_hi)
    if region_map is not None and region_map.axes != plan.variables.names:
        region_map = None
    bounds = _map_bounds(region_map, errors, ~inside, L, W, *values.values())
    return GeneratedBatch(
        L, W, np.asarray(parameters, dtype=float), durations, ~inside, tuple(errors), *bounds, variables=values
    )


def _one_by_one(
    coefficients: Coefficients, L: np.ndarray, W: np.ndarray, values: dict, durations: np.ndarray
) -> tuple[np.ndarray, list[str | None]]:
    """The scalar generator per obstacle (families that need each obstacle's inverse kinematics,
    or a batch with sizes it refuses): parameters (n, 8) and the refusal of each obstacle (None:
    answered); ``durations`` takes each answer's T, NaN where refused. ``values``: the extra
    variables' arrays by name."""
    parameters = np.full((L.size, 8), np.nan)
    errors: list[str | None] = [None] * L.size
    for i in range(L.size):
        extra = {name: float(v[i]) for name, v in values.items()}
        try:
            answer = generate(coefficients, float(L[i]), float(W[i]), out_of_range="ignore", **extra)
        except PipelineError as exc:
            errors[i] = f"{type(exc).__name__}: {exc}"
            durations[i] = np.nan
            continue
        parameters[i] = answer.trajectory.parameters
        durations[i] = answer.duration_s
    return parameters, errors
