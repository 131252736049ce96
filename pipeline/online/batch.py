"""Many obstacles at once: the generator vectorised over (L, W), and the certificate over many trajectories.

For sweeps (``verify.sweep`` and the like), where per-query Python overhead would dominate:

* :func:`generate_batch` gives, for n obstacles, the eight parameters (n, 8), T (n,) and the
  out-of-range flags in a handful of NumPy operations (paper family; a family that needs each
  obstacle's inverse kinematics is expanded per obstacle). The numbers equal :func:`generate`'s
  (tests compare them); sizes :func:`generate` would refuse are reported per obstacle in
  ``error`` instead of raising, so one bad case does not stop a sweep.
* :func:`certify_batch` runs the adaptive certificate (Coal) on each of them and returns the bounds
  and evaluation counts as arrays.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.certify.region_map import RegionMap
from pipeline.exceptions import InvalidParameterError, PipelineError, RegionMapMismatchError
from pipeline.geometry.clearance import COAL, ClearanceRoute
from pipeline.geometry.motion_certificate import DEFAULT_TOLERANCE_M
from pipeline.geometry.sinusoid_certificate import certify_trajectory
from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle
from pipeline.motion.path import symmetric_quartic, symmetric_quartic_lengths_m
from pipeline.motion.trajectory import JointTrajectory
from pipeline.offline.coefficients import Coefficients
from pipeline.online.arm_check import check_arm_matches
from pipeline.online.generator import generate, query_plan


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

    def trajectory(self, i: int) -> JointTrajectory:
        """Obstacle ``i``'s joint trajectory."""
        if self.error[i] is not None:
            raise InvalidParameterError("i", i, f"an obstacle with an answer ({self.error[i]})")
        return JointTrajectory.trusted(tuple(self.parameters[i].tolist()), float(self.durations_s[i]))


def generate_batch(
    coefficients: Coefficients, lengths_m: np.ndarray, widths_m: np.ndarray, *, region_map: RegionMap | None = None
) -> GeneratedBatch:
    """:func:`pipeline.online.generator.generate` for n obstacles at once (range checks off: see ``extrapolated``).

    Args:
        coefficients: The regression coefficients.
        lengths_m, widths_m: Obstacle sizes L, W [m], equal shapes (n,).
        region_map: The coefficients' range certificate: the answers then carry its bounds.

    Raises:
        InvalidParameterError: the arrays are not numbers of equal one-dimensional shape.
        RegionMapMismatchError: ``region_map`` was made for other coefficients.
    """
    if region_map is not None and not region_map.belongs_to(coefficients):
        raise RegionMapMismatchError(region_map.coefficients_sha256, coefficients.source_sha256)
    try:
        L = np.asarray(lengths_m, dtype=float).ravel()
        W = np.asarray(widths_m, dtype=float).ravel()
    except (TypeError, ValueError):
        raise InvalidParameterError("lengths_m / widths_m", "not numbers", "arrays of sizes [m]") from None
    if L.shape != W.shape:
        raise InvalidParameterError("lengths_m / widths_m", (L.shape, W.shape), "arrays of equal length")
    plan = query_plan(coefficients)
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
    errors: list[str | None] = [None] * L.size
    if coefficients.family.uses_endpoint_context or not np.all(valid):
        parameters = np.full((L.size, 8), np.nan)
        for i in range(L.size):
            try:
                answer = generate(coefficients, float(L[i]), float(W[i]), out_of_range="ignore")
            except PipelineError as exc:
                errors[i] = f"{type(exc).__name__}: {exc}"
                durations[i] = np.nan
                continue
            parameters[i] = answer.trajectory.parameters
            durations[i] = answer.duration_s
    else:
        parameters = coefficients.family.expand(free, None)
    (l_lo, l_hi), (w_lo, w_hi) = plan.l_range, plan.w_range
    extrapolated = ~((L >= l_lo) & (L <= l_hi) & (W >= w_lo) & (W <= w_hi))
    bounds: tuple[np.ndarray | None, ...] = (None, None, None)
    if region_map is not None:
        cells = region_map.cells_at(L, W)
        bad = np.array([e is not None for e in errors], dtype=bool) | extrapolated
        bounds = (
            np.where(bad, np.nan, cells["clearance_bound_m"]),
            np.where(bad, np.nan, cells["endpoint_bound_m"]),
            np.where(bad, -1, cells["status"]),
        )
    return GeneratedBatch(L, W, np.asarray(parameters, dtype=float), durations, extrapolated, tuple(errors), *bounds)


@dataclass(frozen=True, eq=False)
class CertifiedBatch:
    """The adaptive certificate of n trajectories (NaN / 0 where the batch had no answer).

    Attributes:
        certified_clearance_m: Rigorous lower bounds over [0, T] [m], shape (n,).
        sampled_clearance_m: Minimum over the initial samples [m], shape (n,).
        evaluations: Clearance evaluations (configurations) per trajectory, shape (n,).
        decide_above_m: The decide-mode threshold used [m], or None (tolerance mode).
    """

    certified_clearance_m: np.ndarray
    sampled_clearance_m: np.ndarray
    evaluations: np.ndarray
    decide_above_m: float | None


def certify_batch(
    coefficients: Coefficients,
    batch: GeneratedBatch,
    arm: PlanarArm,
    *,
    route: ClearanceRoute = COAL,
    decide_above_m: float | None = None,
    tolerance_m: float = DEFAULT_TOLERANCE_M,
) -> CertifiedBatch:
    """Certify every answer of ``batch`` (the adaptive route of
    :func:`pipeline.geometry.sinusoid_certificate.certify`), after one arm check.

    Args:
        coefficients: The coefficients of the batch (their scene places the obstacles).
        batch: From :func:`generate_batch`.
        arm: The arm the coefficients were fitted for.
        route: Clearance route (Coal, canonical).
        decide_above_m: Only decide whether each clearance exceeds this [m] (fastest). A bound above
            it also certifies the case collision-free; a case at or below it (where refinement
            stopped at the first sample below the threshold) is certified again deciding 0, so that
            ``certified_clearance_m > 0`` always answers "collision-free?" and ``> decide_above_m``
            "keeps the margin?". None: tolerance mode (bounds within ``tolerance_m`` of the sampled
            minimum; several times slower).
        tolerance_m: Tolerance of the bound [m].

    Raises:
        ArmMismatchError: the arm differs from the coefficients'.
    """
    check_arm_matches(coefficients, arm)
    n = batch.lengths_m.size
    certified, sampled, evaluations = np.full(n, np.nan), np.full(n, np.nan), np.zeros(n, dtype=int)
    scene = coefficients.scene
    for i in range(n):
        if batch.error[i] is not None:
            continue
        obstacle = Obstacle.in_scene(float(batch.lengths_m[i]), float(batch.widths_m[i]), scene)
        certificate = certify_trajectory(
            batch.trajectory(i), arm, obstacle, route=route, decide_above_m=decide_above_m, tolerance_m=tolerance_m
        )
        evaluations[i] = certificate.evaluations
        if decide_above_m is not None and decide_above_m > 0.0 and certificate.certified_clearance_m <= decide_above_m:
            certificate = certify_trajectory(
                batch.trajectory(i), arm, obstacle, route=route, decide_above_m=0.0, tolerance_m=tolerance_m
            )
            evaluations[i] += certificate.evaluations
        certified[i] = certificate.certified_clearance_m
        sampled[i] = certificate.sampled_clearance_m
    return CertifiedBatch(certified, sampled, evaluations, decide_above_m)
