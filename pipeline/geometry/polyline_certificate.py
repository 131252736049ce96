"""A rigorous continuous clearance certificate for a piecewise-linear joint path (what a
sampling planner returns), on the same core as the sinusoids' (:mod:`pipeline.geometry.motion_certificate`).

====================

The path is timed (:func:`timed_path`): each segment runs at constant joint velocity
``w = dq / h`` (``h`` its duration, by default the least time the URDF's velocity limits
allow). Timing changes nothing geometric: it only names points along the path.

1. **Lipschitz bound per segment.** On a segment the joint rates are constant, so with the
   reach of :class:`pipeline.geometry.link_reach.LinkReach` (``rho_1 = l1 + r1``, ``e = l1``,
   ``rho_2 = l2 + r2``) every point of link 1 moves at most ``V_1 = |w_1| rho_1`` and every
   point of link 2 at most ``V_2 = min(|w_1| (e + rho_2) + |w_2| rho_2, |w_1| e + |w_1 + w_2| rho_2)``
   (:mod:`pipeline.geometry.link_reach`), inflated by a relative 1e-9.
   Per unit of the segment's parameter ``s`` in [0, 1] that is ``|dq_1| (l1 + r1)`` for
   link 1 and ``|dq_1| (l1 + l2 + r2) + |dq_2| (l2 + r2)`` for link 2. The distance of a
   link to the fixed obstacle is 1-Lipschitz in the motion of the link, so
   ``|d(t) - d(s)| <= V |t - s|`` on the segment.
2. **Interval lower bound.** On ``[ta, tb]`` (length ``h``) inside one segment,
   ``min d >= (d(ta) + d(tb) - V h) / 2``. Intervals never straddle a waypoint (the rates
   jump there).
3. **Distance error.** Every sample enters as ``d - distance_error_m`` (Coal:
   :data:`pipeline.geometry.clearance.COAL_DISTANCE_ERROR_M`).
4. **Bisection.** Every interval whose bound is more than ``tolerance_m`` below the smallest
   sampled value is bisected (one more clearance evaluation), until none is or the
   evaluation budget runs out (the bound stays rigorous, only looser).

The certified clearance (the minimum of every interval bound and every sample, minus the
distance error) is a rigorous lower bound on the clearance over the whole continuous path;
the path is *certified collision-free* iff it is > 0. It is returned as a
:class:`pipeline.geometry.motion_certificate.Certificate` whose times are the path's times [s].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.clearance import COAL, COAL_DISTANCE_ERROR_M, ClearanceFunction, ClearanceRoute
from pipeline.geometry.link_reach import LinkReach, link_point_speed_bounds
from pipeline.geometry.motion_certificate import (
    DEFAULT_MAX_EVALUATIONS,
    DEFAULT_RESOLUTION_M,
    DEFAULT_TOLERANCE_M,
    Certificate,
    certify_motion,
)
from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle
from pipeline.validation import check_non_negative, check_positive, check_positive_int


@dataclass(frozen=True, eq=False)
class JointPath:
    """A timed piecewise-linear path in joint space: constant joint velocity on each segment.

    Attributes:
        waypoints_rad: Joint configurations, shape (k, 2) [rad], k >= 2.
        times_s: Time of each waypoint, shape (k,) [s], starting at 0, strictly increasing.
    """

    waypoints_rad: np.ndarray
    times_s: np.ndarray

    def __post_init__(self) -> None:
        waypoints = np.array(self.waypoints_rad, dtype=float)
        times = np.array(self.times_s, dtype=float)
        if waypoints.ndim != 2 or waypoints.shape[1] != 2 or waypoints.shape[0] < 2:
            raise InvalidParameterError("waypoints_rad", waypoints.shape, "shape (k, 2) with k >= 2")
        if times.shape != (waypoints.shape[0],):
            raise InvalidParameterError("times_s", times.shape, f"shape ({waypoints.shape[0]},)")
        if not (np.all(np.isfinite(waypoints)) and np.all(np.isfinite(times))):
            raise InvalidParameterError("waypoints_rad / times_s", "non-finite values", "finite numbers")
        if times[0] != 0.0 or np.any(np.diff(times) <= 0.0):
            raise InvalidParameterError("times_s", times.tolist(), "starting at 0 and strictly increasing")
        waypoints.setflags(write=False)
        times.setflags(write=False)
        object.__setattr__(self, "waypoints_rad", waypoints)
        object.__setattr__(self, "times_s", times)

    @property
    def duration_s(self) -> float:
        """Total duration [s]."""
        return float(self.times_s[-1])

    @property
    def segments(self) -> int:
        """Number of linear segments."""
        return int(self.waypoints_rad.shape[0] - 1)

    @property
    def joint_velocities_rad_s(self) -> np.ndarray:
        """Constant joint velocity of each segment, shape (k - 1, 2) [rad/s]."""
        return np.diff(self.waypoints_rad, axis=0) / np.diff(self.times_s)[:, None]

    def q(self, t_s: float | np.ndarray) -> np.ndarray:
        """Joint angles [rad] at t [s] (clipped to [0, T]): shape (2,) for a scalar, (m, 2) for m times."""
        t = np.asarray(t_s, dtype=float)
        flat = np.clip(np.atleast_1d(t), 0.0, self.duration_s)
        out = np.stack([np.interp(flat, self.times_s, self.waypoints_rad[:, j]) for j in (0, 1)], -1)
        return out[0] if t.ndim == 0 else out

    def joint_space_length_rad(self) -> float:
        """Sum of the Euclidean lengths of the segments in joint space [rad]."""
        return float(np.sum(np.linalg.norm(np.diff(self.waypoints_rad, axis=0), axis=1)))


def timed_path(
    waypoints_rad: np.ndarray, velocity_limits_rad_s: tuple[float, float], *, min_step_rad: float = 1e-12
) -> JointPath:
    """Time a waypoint sequence: each segment takes the least time the joint velocity limits allow.

    Args:
        waypoints_rad: Joint configurations, shape (k, 2) [rad].
        velocity_limits_rad_s: Per-joint speed limits [rad/s] (the URDF's).
        min_step_rad: Consecutive waypoints closer than this in every joint are merged [rad].

    Raises:
        InvalidParameterError: fewer than two distinct waypoints, or non-positive limits.
    """
    points = np.asarray(waypoints_rad, dtype=float).reshape(-1, 2)
    limits = np.array([check_positive("velocity_limits_rad_s", v) for v in velocity_limits_rad_s])
    if limits.shape != (2,):
        raise InvalidParameterError("velocity_limits_rad_s", velocity_limits_rad_s, "two positive values")
    keep = [0]
    for i in range(1, len(points)):
        if np.max(np.abs(points[i] - points[keep[-1]])) > min_step_rad:
            keep.append(i)
    if len(keep) < 2:
        raise InvalidParameterError("waypoints_rad", points.tolist(), "at least two distinct waypoints")
    points = points[keep]
    durations = np.max(np.abs(np.diff(points, axis=0)) / limits, axis=1)
    return JointPath(points, np.concatenate([[0.0], np.cumsum(durations)]))


def segment_speed_bounds(path: JointPath, reach: LinkReach) -> np.ndarray:
    """Upper bound [m/s] on the speed of every point of each link on each segment.

    Returns:
        Shape (k - 1, 2): column j bounds the point speeds of link j + 1 (module docstring, step 1).
    """
    w = np.abs(path.joint_velocities_rad_s)
    sum_rate = np.abs(np.sum(path.joint_velocities_rad_s, axis=1))
    return link_point_speed_bounds(w[:, 0], w[:, 1], sum_rate, reach)


def certify_joint_path(
    path: JointPath,
    clearance: ClearanceFunction,
    reach: LinkReach,
    *,
    samples_per_segment: int | None = None,
    resolution_m: float = DEFAULT_RESOLUTION_M,
    distance_error_m: float = COAL_DISTANCE_ERROR_M,
    tolerance_m: float = DEFAULT_TOLERANCE_M,
    decide_above_m: float | None = None,
    max_evaluations: int = DEFAULT_MAX_EVALUATIONS,
) -> Certificate:
    """Certify a lower bound on the clearance of a piecewise-linear joint path, over the whole path.

    Args:
        path: The timed path (:func:`timed_path`).
        clearance: Per-link clearance function, (m, 2) [rad] -> (m, 2) [m], e.g.
            ``CoalClearance(arm, obstacle).link_clearance``.
        reach: Reach of the links' collision geometry (:meth:`LinkReach.from_arm`).
        samples_per_segment: Initial uniform samples per segment, ends included (>= 2); default
            from ``resolution_m``.
        resolution_m: Default initial sampling: no link point moves more than this between samples [m].
        distance_error_m: Bound on the error of ``clearance`` [m].
        tolerance_m: Refine until the bound is within this of the smallest sample [m].
        decide_above_m: If given, only decide whether the clearance exceeds this value [m] (as in
            :func:`pipeline.geometry.sinusoid_certificate.certify`).
        max_evaluations: Cap on refinement evaluations (configurations) beyond the initial samples.

    Returns:
        A :class:`pipeline.geometry.motion_certificate.Certificate`; its times are the path's times [s].
    """
    check_positive("resolution_m", resolution_m)
    check_non_negative("distance_error_m", distance_error_m)
    check_positive("tolerance_m", tolerance_m)
    check_positive_int("max_evaluations", max_evaluations, minimum=0)
    if samples_per_segment is not None:
        check_positive_int("samples_per_segment", samples_per_segment, minimum=2)

    seg_ta = path.times_s[:-1]
    seg_h = np.diff(path.times_s)
    speeds = segment_speed_bounds(path, reach)

    # Initial samples: per segment, ends included; a waypoint is sampled once and shared.
    times_list = [np.array([0.0])]
    for j in range(path.segments):
        if samples_per_segment is not None:
            count = samples_per_segment
        else:
            count = max(2, math.ceil(float(np.max(speeds[j])) * seg_h[j] / resolution_m) + 1)
        local = seg_ta[j] + np.linspace(0.0, 1.0, count)[1:] * seg_h[j]
        local[-1] = path.times_s[j + 1]
        times_list.append(local)

    def speed_bound(ta: np.ndarray, tb: np.ndarray) -> np.ndarray:
        # Intervals never cross a waypoint: each lies on the segment holding its midpoint.
        segment = np.clip(np.searchsorted(path.times_s, (ta + tb) / 2.0, side="right") - 1, 0, path.segments - 1)
        return speeds[segment]

    return certify_motion(
        path.q,
        np.concatenate(times_list),
        clearance,
        speed_bound,
        distance_error_m=distance_error_m,
        tolerance_m=tolerance_m,
        decide_above_m=decide_above_m,
        max_evaluations=max_evaluations,
    )


def certify_path(
    path: JointPath,
    arm: PlanarArm,
    obstacle: Obstacle,
    *,
    route: ClearanceRoute = COAL,
    samples_per_segment: int | None = None,
    resolution_m: float = DEFAULT_RESOLUTION_M,
    tolerance_m: float = DEFAULT_TOLERANCE_M,
    decide_above_m: float | None = None,
    max_evaluations: int = DEFAULT_MAX_EVALUATIONS,
) -> Certificate:
    """Certify one joint path against one obstacle (the path analogue of
    :func:`pipeline.geometry.sinusoid_certificate.certify_trajectory`).

    Args:
        path: The timed piecewise-linear path.
        arm: The arm (collision geometry and reach).
        obstacle: The rounded box.
        route: ``"coal"`` (Pinocchio + Coal, canonical) or ``"analytic"`` (planar capsules only).
        samples_per_segment, resolution_m, tolerance_m, decide_above_m, max_evaluations: as in
            :func:`certify_joint_path`.

    Raises:
        InvalidParameterError: unknown route or bad settings.
    """
    function, error = route.function(arm, obstacle), route.distance_error_m
    reach = LinkReach.from_arm(arm)
    return certify_joint_path(
        path,
        function,
        reach,
        samples_per_segment=samples_per_segment,
        resolution_m=resolution_m,
        distance_error_m=error,
        tolerance_m=tolerance_m,
        decide_above_m=decide_above_m,
        max_evaluations=max_evaluations,
    )


# --------------------------------------------------------------------------------------------
# OMPL RRT-Connect
