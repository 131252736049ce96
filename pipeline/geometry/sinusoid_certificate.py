"""A continuous-time clearance certificate for the paper's sinusoidal joint trajectories.

Coal's Python API has no continuous collision check, so this module derives one. Given a
clearance function ``d(q)`` (per link, [m]) and a trajectory
``theta_i(t) = A_i sin(w_i t + phi_i) + gamma_i`` on ``[0, T]``, it returns a number that is
a *rigorous lower bound* on ``min_t d_k(q(t))`` over the whole continuous interval and
both links, not only at the samples.

Derivation
==========

1. **Distance is 1-Lipschitz in the motion of the geometry**, and the certificate's interval
   bound, distance error and bisection are those of :mod:`pipeline.geometry.motion_certificate`.

2. **Point speeds of a planar 2R arm** are bounded from the joint rates ``|w_1|``, ``|w_2|`` and
   ``|w_1 + w_2|`` as in :mod:`pipeline.geometry.link_reach`.

   For the sinusoids ``|w_i(t)| = |A_i w_i cos(w_i t + phi_i)|``; its maximum over an
   interval ``[ta, tb]`` is known in closed form (``|A_i w_i|`` if the phase crosses a
   multiple of pi, else the larger end value). ``|w_1 + w_2|`` on the interval is bounded
   by ``min(W_1 + W_2, |w_1(tm) + w_2(tm)| + (tb - ta)/2 * (Acc_1 + Acc_2))`` with ``W_i``
   and ``Acc_i`` the closed-form interval maxima of ``|w_i|`` and ``|dw_i/dt|`` and ``tm``
   the midpoint (the sum of rates is Lipschitz with constant ``Acc_1 + Acc_2``). Every
   speed bound is inflated by a relative ``1e-9`` against rounding.

The certified clearance is the minimum of all interval bounds and all sampled values
(minus the distance error). It is a rigorous lower bound whenever it is positive; where a
sample is in contact (``d <= 0``; Coal then reports a penetration depth) the certified
value is at most that sample and the case is in collision. A trajectory is *certified
collision-free* only if the certified clearance is ``> 0``.
"""

from __future__ import annotations

import math

import numpy as np

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
from pipeline.motion.trajectory import JointTrajectory
from pipeline.validation import check_positive, check_positive_int


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
    return link_point_speed_bounds(w1, w2, sum_rate, reach)


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


def certify_trajectory(
    trajectory: JointTrajectory,
    arm: PlanarArm,
    obstacle: Obstacle,
    *,
    route: ClearanceRoute = COAL,
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
    function, error = route.function(arm, obstacle), route.distance_error_m
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
