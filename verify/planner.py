"""A general-purpose planner to compare with, and a rigorous certificate for what it returns.

Two parts:

* :func:`plan_rrt_connect`: OMPL's RRT-Connect (``ompl`` from PyPI, the optional ``bench``
  extra) in the arm's joint space (bounds: the URDF's position limits), from the analytic IK
  of P1 to that of P5, with a Coal validity checker on the same geometry as ours: a state is
  valid iff the Pinocchio + Coal clearance of both links is **>= margin** (the scene's safety
  margin, 0.01 m by default, the margin our generator is held to). ``ompl`` is imported
  lazily inside the functions, so this module imports without it.
* :func:`certify_joint_path`: a continuous clearance certificate for a **piecewise-linear
  joint path** (what a sampling planner returns), built on the ideas and pieces of
  :mod:`pipeline.certificate`.

The path certificate
====================

The path is timed (:func:`timed_path`): each segment runs at constant joint velocity
``w = dq / h`` (``h`` its duration, by default the least time the URDF's velocity limits
allow). Timing changes nothing geometric: it only names points along the path.

1. **Lipschitz bound per segment.** On a segment the joint rates are constant, so with the
   reach of :class:`pipeline.certificate.LinkReach` (``rho_1 = l1 + r1``, ``e = l1``,
   ``rho_2 = l2 + r2``) every point of link 1 moves at most ``V_1 = |w_1| rho_1`` and every
   point of link 2 at most ``V_2 = min(|w_1| (e + rho_2) + |w_2| rho_2, |w_1| e + |w_1 + w_2| rho_2)``
   (the two bounds of :mod:`pipeline.certificate`, step 2), inflated by a relative 1e-9.
   Per unit of the segment's parameter ``s`` in [0, 1] that is ``|dq_1| (l1 + r1)`` for
   link 1 and ``|dq_1| (l1 + l2 + r2) + |dq_2| (l2 + r2)`` for link 2. The distance of a
   link to the fixed obstacle is 1-Lipschitz in the motion of the link, so
   ``|d(t) - d(s)| <= V |t - s|`` on the segment.
2. **Interval lower bound.** On ``[ta, tb]`` (length ``h``) inside one segment,
   ``min d >= (d(ta) + d(tb) - V h) / 2``. Intervals never straddle a waypoint (the rates
   jump there).
3. **Distance error.** Every sample enters as ``d - distance_error_m`` (Coal:
   :data:`pipeline.certificate.COAL_DISTANCE_ERROR_M`).
4. **Bisection.** Every interval whose bound is more than ``tolerance_m`` below the smallest
   sampled value is bisected (one more clearance evaluation), until none is or the
   evaluation budget runs out (the bound stays rigorous, only looser).

The certified clearance (the minimum of every interval bound and every sample, minus the
distance error) is a rigorous lower bound on the clearance over the whole continuous path;
the path is *certified collision-free* iff it is > 0. It is returned as a
:class:`pipeline.certificate.Certificate` whose times are the path's times [s].
"""

from __future__ import annotations

import importlib.util
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pipeline.certificate import (
    COAL_DISTANCE_ERROR_M,
    DEFAULT_MAX_EVALUATIONS,
    DEFAULT_RESOLUTION_M,
    DEFAULT_TOLERANCE_M,
    Certificate,
    LinkReach,
    certify_motion,
    clearance_route,
)
from pipeline.clearance import CoalClearance
from pipeline.exceptions import InvalidParameterError
from pipeline.family import inverse_kinematics, reach_annulus_m
from pipeline.obstacle import Obstacle
from pipeline.path import desired_path
from pipeline.robot import PlanarArm
from pipeline.scene import Scene
from pipeline.validation import check_non_negative, check_positive, check_positive_int

_SPEED_SLACK = 1.0 + 1e-9

#: A clearance function: joint configurations (m, 2) [rad] -> per-link clearance (m, 2) [m].
ClearanceFunction = Callable[[np.ndarray], np.ndarray]

#: OMPL's own default state validity checking resolution (fraction of the space's extent).
OMPL_DEFAULT_RESOLUTION = 0.01
#: OMPL console log levels by name (OMPL's default prints every Info line on stdout).
OMPL_LOG_LEVELS = ("none", "error", "warn", "info")


# --------------------------------------------------------------------------------------------
# Piecewise-linear joint paths


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
    rho1, e, rho2 = reach.link1_radius_m, reach.elbow_distance_m, reach.link2_radius_m
    v1 = w[:, 0] * rho1
    v2 = np.minimum(w[:, 0] * (e + rho2) + w[:, 1] * rho2, w[:, 0] * e + sum_rate * rho2)
    return np.stack([v1, v2], -1) * _SPEED_SLACK


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
            :func:`pipeline.certificate.certify`).
        max_evaluations: Cap on refinement evaluations (configurations) beyond the initial samples.

    Returns:
        A :class:`pipeline.certificate.Certificate`; its times are the path's times [s].
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
    route: str = "coal",
    samples_per_segment: int | None = None,
    resolution_m: float = DEFAULT_RESOLUTION_M,
    tolerance_m: float = DEFAULT_TOLERANCE_M,
    decide_above_m: float | None = None,
    max_evaluations: int = DEFAULT_MAX_EVALUATIONS,
) -> Certificate:
    """Certify one joint path against one obstacle (the path analogue of
    :func:`pipeline.certificate.certify_trajectory`).

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
    function, error = clearance_route(arm, obstacle, route)
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


def ompl_available() -> bool:
    """True if the ``ompl`` Python bindings can be imported."""
    return importlib.util.find_spec("ompl") is not None


def ompl_version() -> str | None:
    """Installed version of the ``ompl`` distribution, or None."""
    from importlib import metadata

    try:
        return metadata.version("ompl")
    except metadata.PackageNotFoundError:
        return None


_SEEDED: list[int] = []


def seed_ompl(seed: int) -> bool:
    """Seed OMPL's global random generator, once per process (OMPL only honours the first seed,
    before any sampler exists). Returns True if this call set the seed."""
    check_positive_int("seed", seed, minimum=0)
    if _SEEDED:
        return False
    from ompl import util as ou

    ou.RNG.setSeed(seed + 1)  # OMPL treats seed 0 as "pick one at random"
    _SEEDED.append(seed)
    return True


@dataclass(frozen=True)
class PlannerConfig:
    """How RRT-Connect is run.

    Attributes:
        time_limit_s: Planning time budget per query [s] (OMPL stops at the first solution).
        margin_m: A state is valid iff both links' Coal clearance is >= this [m].
        simplify: Shortcut the solution with OMPL's path simplifier (as a user would), within
            another ``time_limit_s``.
        resolution: OMPL's state validity checking resolution along motions, as a fraction of
            the joint space's extent (OMPL's default 0.01).
        range_rad: RRT-Connect's maximum step [rad]; None lets OMPL choose (20% of the extent).
        log_level: OMPL's console output: "none", "error", "warn" or "info" (set process-wide).
    """

    time_limit_s: float = 1.0
    margin_m: float = 0.01
    simplify: bool = True
    resolution: float = OMPL_DEFAULT_RESOLUTION
    range_rad: float | None = None
    log_level: str = "warn"

    def __post_init__(self) -> None:
        if self.log_level not in OMPL_LOG_LEVELS:
            raise InvalidParameterError("log_level", self.log_level, f"one of {OMPL_LOG_LEVELS}")
        check_positive("time_limit_s", self.time_limit_s)
        check_non_negative("margin_m", self.margin_m)
        check_positive("resolution", self.resolution)
        if self.range_rad is not None:
            check_positive("range_rad", self.range_rad)


@dataclass(frozen=True, eq=False)
class PlanResult:
    """One RRT-Connect query.

    Attributes:
        solved: True if OMPL found an exact solution (an approximate one counts as failure).
        status: OMPL's planner status, as text.
        waypoints_rad: The solution's states, shape (k, 2) [rad] (empty if none).
        path: The timed path (URDF velocity limits), or None if not solved.
        plan_seconds: Wall time of setup + solve [s].
        simplify_seconds: Wall time of the simplification [s].
        validity_checks: Calls of the validity checker.
        coal_queries: Coal distance queries made by the validity checker.
        start_valid, goal_valid: Whether the start and goal states are valid.
    """

    solved: bool
    status: str
    waypoints_rad: np.ndarray
    path: JointPath | None
    plan_seconds: float
    simplify_seconds: float
    validity_checks: int
    coal_queries: int
    start_valid: bool
    goal_valid: bool

    @property
    def seconds(self) -> float:
        """Wall time of the whole query (setup, solve, simplification) [s]."""
        return self.plan_seconds + self.simplify_seconds


def start_goal_configurations(
    obstacle: Obstacle, scene: Scene, link_lengths_m: tuple[float, float], elbow: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """Joint angles [rad] at P1 and P5 of the obstacle's desired path (analytic IK, one elbow branch)."""
    path = desired_path(obstacle, scene, reach_annulus_m(link_lengths_m))
    start = inverse_kinematics(path.points_m[0], link_lengths_m, elbow)
    goal = inverse_kinematics(path.points_m[-1], link_lengths_m, elbow)
    return start, goal


def plan_rrt_connect(
    arm: PlanarArm,
    obstacle: Obstacle,
    start_rad: np.ndarray,
    goal_rad: np.ndarray,
    config: PlannerConfig | None = None,
) -> PlanResult:
    """Plan from ``start_rad`` to ``goal_rad`` with OMPL's RRT-Connect and a Coal validity checker.

    Everything a user would do per obstacle is inside the timing: building the Coal checker,
    the state space and the SimpleSetup, solving, and (if configured) simplifying.

    Raises:
        ModuleNotFoundError: ``ompl`` is not installed.
    """
    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou

    config = config or PlannerConfig()
    ou.setLogLevel(getattr(ou, f"LOG_{config.log_level.upper()}"))
    started = time.perf_counter()
    checker = CoalClearance(arm, obstacle)
    margin = config.margin_m
    checks = [0]

    def is_valid(state) -> bool:
        checks[0] += 1
        values = checker.link_clearance(np.array([state[0], state[1]]))
        return bool(values[0] >= margin and values[1] >= margin)

    space = ob.RealVectorStateSpace(2)
    bounds = ob.RealVectorBounds(2)
    for joint, (low, high) in enumerate(arm.position_limits_rad):
        bounds.setLow(joint, float(low))
        bounds.setHigh(joint, float(high))
    space.setBounds(bounds)
    setup = og.SimpleSetup(space)
    setup.setStateValidityChecker(is_valid)
    information = setup.getSpaceInformation()
    information.setStateValidityCheckingResolution(config.resolution)
    start, goal = space.allocState(), space.allocState()
    for j in (0, 1):
        start[j] = float(start_rad[j])
        goal[j] = float(goal_rad[j])
    setup.setStartAndGoalStates(start, goal)
    planner = og.RRTConnect(information)
    if config.range_rad is not None:
        planner.setRange(config.range_rad)
    setup.setPlanner(planner)
    start_valid = is_valid(start)
    goal_valid = is_valid(goal)
    status = setup.solve(config.time_limit_s)
    solved = bool(setup.haveExactSolutionPath())
    plan_seconds = time.perf_counter() - started
    simplify_seconds = 0.0
    waypoints = np.zeros((0, 2))
    path = None
    if solved:
        if config.simplify:
            begun = time.perf_counter()
            setup.simplifySolution(config.time_limit_s)
            simplify_seconds = time.perf_counter() - begun
        solution = setup.getSolutionPath()
        waypoints = np.array(
            [[solution.getState(i)[0], solution.getState(i)[1]] for i in range(solution.getStateCount())]
        )
        path = timed_path(waypoints, arm.velocity_limits_rad_s)
    return PlanResult(
        solved=solved,
        status=str(status),
        waypoints_rad=waypoints,
        path=path,
        plan_seconds=plan_seconds,
        simplify_seconds=simplify_seconds,
        validity_checks=checks[0],
        coal_queries=int(checker.queries),
        start_valid=start_valid,
        goal_valid=goal_valid,
    )
