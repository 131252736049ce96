"""A continuous-time clearance certificate for the paper's sinusoidal joint trajectories.

Coal's Python API has no continuous collision check, so this module derives one. Given a
clearance function ``d(q)`` (per link, [m]) and a trajectory
``theta_i(t) = A_i sin(w_i t + phi_i) + gamma_i`` on ``[0, T]``, it returns a number that is
a *rigorous lower bound* on ``min_t d_k(q(t))`` over the whole continuous interval and
both links, not only at the samples.

Derivation
==========

1. **Distance is 1-Lipschitz in the motion of the geometry.** If every material point of
   a link moves by at most ``delta`` between times ``s`` and ``t``, the two placed
   geometries are within Hausdorff distance ``delta`` of each other, so the (non-negative)
   distance from the link to a fixed obstacle changes by at most ``delta``:
   ``|d(t) - d(s)| <= delta <= V |t - s|`` with ``V`` a bound on the speed of every point
   of the link over ``[s, t]``.

2. **Point speeds of a planar 2R arm.** Joint axes are parallel (z). Let ``rho_1`` bound the
   distance of any point of link 1's collision geometry from joint axis 1 (a capsule of
   length ``l1`` and radius ``r1``: ``rho_1 = l1 + r1``), ``e`` the distance between the
   two joint axes (``l1``) and ``rho_2`` the same bound for link 2 about joint axis 2
   (``l2 + r2``). With ``w_i = dtheta_i/dt``:

   * a point p of link 1 moves at ``|w_1| |p|_perp <= |w_1| rho_1``;
   * a point p of link 2 moves at ``v = w_1 z x (p - o) + w_2 z x (p - elbow)``, so
     ``|v| <= |w_1| (e + rho_2) + |w_2| rho_2`` (the bound of the issue), and also, writing
     ``v = w_1 z x (elbow - o) + (w_1 + w_2) z x (p - elbow)``,
     ``|v| <= |w_1| e + |w_1 + w_2| rho_2``. The smaller of the two is used.

   For the sinusoids ``|w_i(t)| = |A_i w_i cos(w_i t + phi_i)|``; its maximum over an
   interval ``[ta, tb]`` is known in closed form (``|A_i w_i|`` if the phase crosses a
   multiple of pi, else the larger end value). ``|w_1 + w_2|`` on the interval is bounded
   by ``min(W_1 + W_2, |w_1(tm) + w_2(tm)| + (tb - ta)/2 * (Acc_1 + Acc_2))`` with ``W_i``
   and ``Acc_i`` the closed-form interval maxima of ``|w_i|`` and ``|dw_i/dt|`` and ``tm``
   the midpoint (the sum of rates is Lipschitz with constant ``Acc_1 + Acc_2``). Every
   speed bound is inflated by a relative ``1e-9`` against rounding.

3. **Interval lower bound.** On ``[ta, tb]`` (length ``h``) with speed bound ``V``,
   ``d(t) >= max(d(ta) - V (t - ta), d(tb) - V (tb - t))``, whose minimum over the interval is
   ``(d(ta) + d(tb) - V h) / 2``, reached at ``ta + (d(ta) - d(tb) + V h) / (2 V)``.

4. **Distance error.** Coal's GJK returns an upper estimate of the exact distance (measured
   here: at most about 1.1e-6 m above the analytic distance for these shapes, its default
   ``gjk_tolerance`` being 1e-6). Every sampled value therefore enters the bound as
   ``d - distance_error_m`` (default :data:`COAL_DISTANCE_ERROR_M` = 1e-5 m for the Coal
   route, 1e-12 m for the analytic route).

5. **Adaptive bisection.** Start from a uniform grid; every interval whose bound is more
   than ``tolerance_m`` below the smallest sampled value (so the bound is too loose to say
   anything better) is bisected: one more clearance evaluation at its midpoint, two
   intervals with smaller ``h`` and tighter closed-form speed bounds. Since the gap
   between the bound and the sampled values shrinks like ``V h / 2``, refinement ends.

The certified clearance is the minimum of all interval bounds and all sampled values
(minus the distance error). It is a rigorous lower bound whenever it is positive; where a
sample is in contact (``d <= 0``; Coal then reports a penetration depth) the certified
value is at most that sample and the case is in collision. A trajectory is *certified
collision-free* only if the certified clearance is ``> 0``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from .clearance import CoalClearance, analytic_link_clearance, check_fast_route
from .exceptions import InvalidParameterError
from .obstacle import Obstacle
from .robot import PlanarArm
from .trajectory import JointTrajectory
from .validation import check_non_negative, check_positive, check_positive_int

#: Error bound [m] on Coal's distances (GJK upper estimate; measured <= 1.2e-6 m, bound 10x that).
COAL_DISTANCE_ERROR_M = 1e-5
#: Error bound [m] on the analytic planar distance (floating-point rounding only).
ANALYTIC_DISTANCE_ERROR_M = 1e-12
#: Default motion resolution [m]: no point of either link moves more than this between samples.
DEFAULT_RESOLUTION_M = 1e-3
#: Default certificate tolerance [m]: stop refining once the bound is this close to the samples.
DEFAULT_TOLERANCE_M = 1e-5
#: Default cap on clearance evaluations (configurations) spent on refinement per trajectory.
DEFAULT_MAX_EVALUATIONS = 200_000

_SPEED_SLACK = 1.0 + 1e-9

#: A clearance function: joint configurations (m, 2) [rad] -> per-link clearance (m, 2) [m].
ClearanceFunction = Callable[[np.ndarray], np.ndarray]
#: A speed bound: interval ends ta, tb (m,) [s] -> bound on every link point's speed (m, 2) [m/s].
SpeedBound = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class LinkReach:
    """Geometry of the speed bound: how far each link's collision geometry reaches.

    Attributes:
        link1_radius_m: rho_1, max distance of a point of link 1's geometry from joint axis 1 [m].
        elbow_distance_m: e, distance between joint axis 1 and joint axis 2 [m].
        link2_radius_m: rho_2, max distance of a point of link 2's geometry from joint axis 2 [m].
    """

    link1_radius_m: float
    elbow_distance_m: float
    link2_radius_m: float

    def __post_init__(self) -> None:
        check_positive("link1_radius_m", self.link1_radius_m)
        check_non_negative("elbow_distance_m", self.elbow_distance_m)
        check_positive("link2_radius_m", self.link2_radius_m)

    @classmethod
    def from_arm(cls, arm: PlanarArm) -> LinkReach:
        """Read the reach off the arm's collision geometry (capsules exactly, other shapes by AABB)."""
        data = arm.model.createData()
        pin.forwardKinematics(arm.model, data, np.zeros(arm.model.nq))
        radii = []
        for joint_id, ids in zip((1, 2), arm.link_geometry_ids, strict=True):
            axis = data.oMi[joint_id].rotation.T @ arm.axis
            radii.append(max(_geometry_reach(arm.collision_model.geometryObjects[i], axis) for i in ids))
        return cls(radii[0], float(arm.link_lengths_m[0]), radii[1])


def _perp(points: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Distance of points (..., 3) from the line through the origin along unit ``axis``."""
    return np.linalg.norm(points - np.outer(points @ axis, axis), axis=-1)


def _geometry_reach(geometry_object: pin.GeometryObject, axis: np.ndarray) -> float:
    """Max distance [m] of a point of the geometry from the joint axis (in the joint frame)."""
    shape = geometry_object.geometry
    placement = geometry_object.placement
    inflation = float(getattr(shape, "getSweptSphereRadius", lambda: 0.0)())
    if type(shape).__name__ == "Capsule":
        half = float(shape.halfLength)
        ends = np.array([placement.act(np.array([0.0, 0.0, s * half])) for s in (-1.0, 1.0)])
        return float(np.max(_perp(ends, axis))) + float(shape.radius) + inflation
    shape.computeLocalAABB()
    lo, hi = np.asarray(shape.aabb_local.min_), np.asarray(shape.aabb_local.max_)
    corners = np.array(
        [[(lo, hi)[i][0], (lo, hi)[j][1], (lo, hi)[k][2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)]
    )
    world = corners @ placement.rotation.T + placement.translation
    return float(np.max(_perp(world, axis))) + inflation


def _max_abs_cos(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """max of |cos u| for u in [lo, hi] (elementwise, lo <= hi), in closed form."""
    k = np.ceil(lo / np.pi)
    crosses = k * np.pi <= hi
    return np.where(crosses, 1.0, np.maximum(np.abs(np.cos(lo)), np.abs(np.cos(hi))))


def _interval_maxima(trajectory: JointTrajectory, ta: np.ndarray, tb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closed-form maxima over [ta, tb] of |dtheta_i/dt| [rad/s] and |d2theta_i/dt2| [rad/s^2].

    Returns two arrays of shape (m, 2).
    """
    p = np.asarray(trajectory.parameters).reshape(2, 4)
    amplitude, w, phi = p[:, 0], p[:, 1], p[:, 2]
    ua = w * ta[:, None] + phi
    ub = w * tb[:, None] + phi
    lo, hi = np.minimum(ua, ub), np.maximum(ua, ub)
    speed = np.abs(amplitude * w) * _max_abs_cos(lo, hi)
    acceleration = np.abs(amplitude * w * w) * _max_abs_cos(lo - np.pi / 2, hi - np.pi / 2)
    return speed, acceleration


def link_speed_bounds(trajectory: JointTrajectory, reach: LinkReach, ta_s: np.ndarray, tb_s: np.ndarray) -> np.ndarray:
    """Upper bound [m/s] on the speed of every point of each link over each interval [ta, tb].

    Args:
        trajectory: The joint trajectory.
        reach: The links' reach (see :class:`LinkReach`).
        ta_s, tb_s: Interval ends [s], shape (m,), ta <= tb.

    Returns:
        Shape (m, 2): column k bounds the point speeds of link k + 1 (module docstring, step 2).
    """
    ta = np.asarray(ta_s, dtype=float)
    tb = np.asarray(tb_s, dtype=float)
    speed, acceleration = _interval_maxima(trajectory, ta, tb)
    w1, w2 = speed[:, 0], speed[:, 1]
    mid_rates = trajectory.dq((ta + tb) / 2.0).reshape(-1, 2)
    sum_rate = np.minimum(
        w1 + w2, np.abs(mid_rates[:, 0] + mid_rates[:, 1]) + (tb - ta) / 2.0 * (acceleration[:, 0] + acceleration[:, 1])
    )
    rho1, e, rho2 = reach.link1_radius_m, reach.elbow_distance_m, reach.link2_radius_m
    v1 = w1 * rho1
    v2 = np.minimum(w1 * (e + rho2) + w2 * rho2, w1 * e + sum_rate * rho2)
    return np.stack([v1, v2], -1) * _SPEED_SLACK


def global_speed_bound(trajectory: JointTrajectory, reach: LinkReach) -> float:
    """Upper bound [m/s] on the speed of any point of either link over [0, T]."""
    bounds = link_speed_bounds(trajectory, reach, np.array([0.0]), np.array([trajectory.duration_s]))
    return float(np.max(bounds))


def samples_for_resolution(trajectory: JointTrajectory, reach: LinkReach, resolution_m: float) -> int:
    """Number of uniform time samples over [0, T] so that no link point moves more than resolution_m
    between two consecutive samples (at least 2)."""
    check_positive("resolution_m", resolution_m)
    travel = global_speed_bound(trajectory, reach) * trajectory.duration_s
    return max(2, math.ceil(travel / resolution_m) + 1)


@dataclass(frozen=True)
class Certificate:
    """Outcome of :func:`certify`.

    Attributes:
        certified_clearance_m: Rigorous lower bound on the clearance over the whole of [0, T]
            and both links [m] (when > 0); <= every sampled value minus the distance error.
        certified_link_clearance_m: The same bound per link [m].
        sampled_clearance_m: Minimum of the clearance over the initial samples [m] (as returned
            by the clearance function).
        sampled_link_clearance_m: The same per link [m].
        sampled_time_s: Time of the sampled minimum [s].
        min_observed_clearance_m: Minimum over every evaluated time, refinements included [m].
        min_observed_time_s: Its time [s].
        bound_time_s: Time where the certified bound is attained [s].
        bound_link: Link (1 or 2) where the certified bound is attained.
        initial_samples: Number of initial uniform samples.
        evaluations: Clearance evaluations made (configurations; initial samples + refinements).
        refinement_rounds: Number of bisection rounds.
        converged: False if the evaluation budget ran out first (the bound is still rigorous,
            only looser than the tolerance).
        distance_error_m: Error bound on the clearance function used [m].
        tolerance_m: Target gap between the bound and the sampled minimum [m].
    """

    certified_clearance_m: float
    certified_link_clearance_m: tuple[float, float]
    sampled_clearance_m: float
    sampled_link_clearance_m: tuple[float, float]
    sampled_time_s: float
    min_observed_clearance_m: float
    min_observed_time_s: float
    bound_time_s: float
    bound_link: int
    initial_samples: int
    evaluations: int
    refinement_rounds: int
    converged: bool
    distance_error_m: float
    tolerance_m: float

    def __post_init__(self) -> None:
        if self.bound_link not in (1, 2):
            raise InvalidParameterError("bound_link", self.bound_link, "1 or 2")
        if self.certified_clearance_m > self.min_observed_clearance_m:
            raise InvalidParameterError(
                "certified_clearance_m", self.certified_clearance_m, "<= min_observed_clearance_m"
            )
        check_positive_int("initial_samples", self.initial_samples, minimum=2)
        check_positive_int("evaluations", self.evaluations, minimum=self.initial_samples)

    @property
    def certified(self) -> bool:
        """True if the trajectory is certified collision-free (certified clearance > 0)."""
        return self.certified_clearance_m > 0.0


def certify(
    trajectory: JointTrajectory,
    clearance: ClearanceFunction,
    reach: LinkReach,
    *,
    samples: int | None = None,
    resolution_m: float = DEFAULT_RESOLUTION_M,
    distance_error_m: float = COAL_DISTANCE_ERROR_M,
    tolerance_m: float = DEFAULT_TOLERANCE_M,
    decide_above_m: float | None = None,
    max_evaluations: int = DEFAULT_MAX_EVALUATIONS,
) -> Certificate:
    """Certify a lower bound on the clearance of ``trajectory`` over the continuous interval [0, T].

    Args:
        trajectory: The joint trajectory (the paper's sinusoids).
        clearance: Per-link clearance function, (m, 2) [rad] -> (m, 2) [m], e.g.
            ``CoalClearance(arm, obstacle).link_clearance``.
        reach: Reach of the links' collision geometry (:meth:`LinkReach.from_arm`).
        samples: Number of initial uniform samples over [0, T] (>= 2); default from
            ``resolution_m`` (:func:`samples_for_resolution`).
        resolution_m: Motion resolution of the default sampling [m].
        distance_error_m, tolerance_m, decide_above_m, max_evaluations: as in :func:`certify_motion`.

    Returns:
        The :class:`Certificate`.
    """
    n = samples_for_resolution(trajectory, reach, resolution_m) if samples is None else samples
    check_positive_int("samples", n, minimum=2)

    def speed_bound(ta: np.ndarray, tb: np.ndarray) -> np.ndarray:
        return link_speed_bounds(trajectory, reach, ta, tb)

    return certify_motion(
        trajectory.q,
        np.linspace(0.0, trajectory.duration_s, n),
        clearance,
        speed_bound,
        distance_error_m=distance_error_m,
        tolerance_m=tolerance_m,
        decide_above_m=decide_above_m,
        max_evaluations=max_evaluations,
    )


def certify_motion(
    q: Callable[[np.ndarray], np.ndarray],
    times_s: np.ndarray,
    clearance: ClearanceFunction,
    speed_bound: SpeedBound,
    *,
    distance_error_m: float = COAL_DISTANCE_ERROR_M,
    tolerance_m: float = DEFAULT_TOLERANCE_M,
    decide_above_m: float | None = None,
    max_evaluations: int = DEFAULT_MAX_EVALUATIONS,
) -> Certificate:
    """The certificate's core, for any joint motion whose link point speeds can be bounded.

    Args:
        q: Joint motion, times (m,) [s] -> configurations (m, 2) [rad].
        times_s: Initial samples, increasing, first and last the ends of the motion [s]. For a
            piecewise motion they must include every breakpoint (the bisection never crosses one).
        clearance: Per-link clearance function, (m, 2) [rad] -> (m, 2) [m].
        speed_bound: Bound on the speed of every point of each link on [ta, tb] [m/s].
        distance_error_m: Bound on the error of ``clearance`` [m] (Coal: :data:`COAL_DISTANCE_ERROR_M`).
        tolerance_m: Refine until the bound is within this of the sampled minimum [m].
        decide_above_m: If given, only decide whether the clearance exceeds this value [m]: intervals
            already bounded above it are not refined, and refinement stops once a sample is at or
            below it. The returned bound is still rigorous, but may be looser than ``tolerance_m``.
        max_evaluations: Cap on refinement evaluations (configurations) beyond the initial samples.
    """
    times = np.asarray(times_s, dtype=float)
    n = times.size
    check_positive_int("samples", n, minimum=2)
    check_non_negative("distance_error_m", distance_error_m)
    check_positive("tolerance_m", tolerance_m)
    check_positive_int("max_evaluations", max_evaluations, minimum=0)

    def evaluate(t: np.ndarray) -> np.ndarray:
        values = np.asarray(clearance(q(t)), dtype=float).reshape(len(t), 2)
        if not np.all(np.isfinite(values)):
            raise InvalidParameterError(
                "clearance", "non-finite values", "finite distances from the clearance function"
            )
        return values

    values = evaluate(times)
    sampled_row = int(np.argmin(np.min(values, axis=1)))
    sampled_link = np.min(values, axis=0)
    evaluations = n
    observed = sampled_link.copy()  # per-link minimum over every evaluated time [m]
    observed_time = times[np.argmin(values, axis=0)]

    # Open intervals (ends, and clearance minus the distance error at the ends), and final bounds.
    ta, tb, da, db = times[:-1], times[1:], values[:-1] - distance_error_m, values[1:] - distance_error_m
    done_lb: list[np.ndarray] = []
    done_t: list[np.ndarray] = []
    rounds = 0
    converged = True
    while ta.size:
        lower, where = _interval_bounds(speed_bound(ta, tb), ta, tb, da, db)
        floor = float(np.min(observed)) - distance_error_m
        worst = np.min(lower, axis=1)
        refine = worst < floor - tolerance_m
        if decide_above_m is not None:
            refine &= worst <= decide_above_m
            if floor <= decide_above_m:
                refine[:] = False
        if np.count_nonzero(refine) > max_evaluations - (evaluations - n):
            converged = False
            refine[:] = False
        done_lb.append(lower[~refine])
        done_t.append(where[~refine])
        if not np.any(refine):
            break
        rounds += 1
        mid = (ta[refine] + tb[refine]) / 2.0
        mid_values = evaluate(mid)
        evaluations += mid.size
        rows = np.argmin(mid_values, axis=0)
        better = mid_values[rows, [0, 1]] < observed
        observed = np.where(better, mid_values[rows, [0, 1]], observed)
        observed_time = np.where(better, mid[rows], observed_time)
        dm = mid_values - distance_error_m
        ta, tb = np.concatenate([ta[refine], mid]), np.concatenate([mid, tb[refine]])
        da, db = np.concatenate([da[refine], dm]), np.concatenate([dm, db[refine]])

    all_lb = np.concatenate(done_lb)
    all_t = np.concatenate(done_t)
    rows = np.argmin(all_lb, axis=0)
    interval_lb = all_lb[rows, [0, 1]]
    link_bounds = np.minimum(interval_lb, observed - distance_error_m)
    link_times = np.where(interval_lb <= observed - distance_error_m, all_t[rows, [0, 1]], observed_time)
    bound_link = int(np.argmin(link_bounds))
    observed_link = int(np.argmin(observed))
    return Certificate(
        certified_clearance_m=float(link_bounds[bound_link]),
        certified_link_clearance_m=(float(link_bounds[0]), float(link_bounds[1])),
        sampled_clearance_m=float(np.min(sampled_link)),
        sampled_link_clearance_m=(float(sampled_link[0]), float(sampled_link[1])),
        sampled_time_s=float(times[sampled_row]),
        min_observed_clearance_m=float(observed[observed_link]),
        min_observed_time_s=float(observed_time[observed_link]),
        bound_time_s=float(link_times[bound_link]),
        bound_link=bound_link + 1,
        initial_samples=n,
        evaluations=evaluations,
        refinement_rounds=rounds,
        converged=converged,
        distance_error_m=float(distance_error_m),
        tolerance_m=float(tolerance_m),
    )


def _interval_bounds(
    speed: np.ndarray, ta: np.ndarray, tb: np.ndarray, da: np.ndarray, db: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Per-link lower bound (m, 2) [m] on each interval and where it is attained (m, 2) [s],
    given the link point speed bounds ``speed`` (m, 2) [m/s] on the intervals."""
    h = (tb - ta)[:, None]
    lower = (da + db - speed * h) / 2.0
    with np.errstate(divide="ignore", invalid="ignore"):
        offset = np.where(speed > 0, (da - db + speed * h) / (2.0 * speed), 0.0)
    where = ta[:, None] + np.clip(offset, 0.0, h)
    # Where the clearance is negative at an end the bound is only used as "not positive".
    return lower, where


def clearance_route(arm: PlanarArm, obstacle: Obstacle, route: str) -> tuple[ClearanceFunction, float]:
    """The clearance function of a route and the bound on its error [m].

    ``"coal"``: Pinocchio geometry model + Coal (canonical); ``"analytic"``: planar capsule to
    rounded rectangle (only for capsule links in the xy plane).

    Raises:
        InvalidParameterError: unknown route. RobotModelError: "analytic" on an unsuitable arm.
    """
    if route == "coal":
        return CoalClearance(arm, obstacle).link_clearance, COAL_DISTANCE_ERROR_M
    if route == "analytic":
        check_fast_route(arm)

        def function(q: np.ndarray) -> np.ndarray:
            return analytic_link_clearance(q, arm, obstacle)

        return function, ANALYTIC_DISTANCE_ERROR_M
    raise InvalidParameterError("route", route, "'coal' or 'analytic'")


def certify_trajectory(
    trajectory: JointTrajectory,
    arm: PlanarArm,
    obstacle: Obstacle,
    *,
    route: str = "coal",
    samples: int | None = None,
    resolution_m: float = DEFAULT_RESOLUTION_M,
    tolerance_m: float = DEFAULT_TOLERANCE_M,
    decide_above_m: float | None = None,
    max_evaluations: int = DEFAULT_MAX_EVALUATIONS,
) -> Certificate:
    """Certify one joint trajectory against one obstacle: the entry point for sweeps and the generator.

    Args:
        trajectory: The joint trajectory.
        arm: The arm (its collision geometry gives the distances and the speed bound's reach).
        obstacle: The rounded box.
        route: ``"coal"`` (Pinocchio geometry model + Coal, the canonical route) or ``"analytic"``
            (planar capsule-to-rounded-rectangle distance; only for capsule links in the xy plane).
        samples, resolution_m, tolerance_m, decide_above_m, max_evaluations: as in :func:`certify`.

    Returns:
        The :class:`Certificate`; ``.certified_clearance_m`` is the certified clearance [m].

    Raises:
        InvalidParameterError: unknown route or bad settings.
        RobotModelError: ``route="analytic"`` on an arm that does not suit it.
    """
    function, error = clearance_route(arm, obstacle, route)
    reach = LinkReach.from_arm(arm)
    return certify(
        trajectory,
        function,
        reach,
        samples=samples,
        resolution_m=resolution_m,
        distance_error_m=error,
        tolerance_m=tolerance_m,
        decide_above_m=decide_above_m,
        max_evaluations=max_evaluations,
    )
