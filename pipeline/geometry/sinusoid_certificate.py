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
   speed bound is inflated by a relative ``1e-9`` against rounding. The adaptive route (step 3)
   bounds ``W_i`` and ``Acc_i`` from the phase ``u_m`` at the midpoint instead: every phase of the
   interval is ``u_m + x`` with ``|x| <= delta = |w_i| h / 2``, so
   ``|cos u| <= |cos u_m| |cos x| + |sin u_m| |sin x| <= |cos u_m| + |sin u_m| sin(min(delta, pi/2))``
   (capped at 1; likewise for ``|sin u|``), within ``O(delta^2)`` of the closed form, from one
   sine and one cosine per joint and interval.

3. **Adaptive sampling** (``initial="adaptive"``, the default). The initial grid is coarse: uniform
   in time, per link, so that no point of that link moves more than :data:`COARSE_RESOLUTION_M`
   (15 cm) between its samples (speed bound from the peak joint rates ``|A_i w_i|``), at least
   :data:`MIN_INITIAL_SAMPLES` samples: a few dozen for link 2 of the paper's motions and about
   ten for the slower link 1, against about 3,300 configurations for the dense route's 1 mm. Then, **per
   link**, only the intervals that need it are split, with one clearance evaluation of that link
   per new point. In tolerance mode the intervals whose bound is more than ``tolerance_m`` below
   the smallest sampled value (both links) are bisected. In decide mode (``decide_above_m``) the
   intervals whose bound is at or below that value (and more than ``tolerance_m`` below the
   smallest sample) are split, until none is or a sample (minus the distance error) is at or below
   it; an interval is split into ``k`` equal parts, ``k = ceil(1.5 V h / (2 g))`` clipped to 2..8,
   where ``g`` is how far its lower end value lies above the value its bound must reach: the number
   of parts that would settle it if the clearance stayed at its end values (a bisection when it is
   nearly settled), so that most trajectories need one round. The interval bound (step 2 of
   :mod:`pipeline.geometry.motion_certificate`) and the distance error are the same as on a dense
   grid, so the result is as rigorous; a coarse grid only means more splitting where the bound is
   close, and none elsewhere. ``initial="dense"`` keeps the former route (a uniform grid at
   ``resolution_m``, 1 mm by default, and the shared core
   :func:`pipeline.geometry.motion_certificate.certify_motion`) for comparison.

The certified clearance is the minimum of all interval bounds and all sampled values
(minus the distance error). It is a rigorous lower bound whenever it is positive; where a
sample is in contact (``d <= 0``; Coal then reports a penetration depth) the certified
value is at most that sample and the case is in collision. A trajectory is *certified
collision-free* only if the certified clearance is ``> 0``. In decide mode the bound is only
guaranteed to say which side of ``decide_above_m`` the clearance is on: above it, it may be
well below the true minimum.
"""

from __future__ import annotations

import math

import numpy as np

from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.adaptive_kernel import merge_round, plan_round
from pipeline.geometry.clearance import (
    COAL,
    COAL_DISTANCE_ERROR_M,
    ClearanceFunction,
    ClearanceRoute,
    LinkClearanceFunction,
    per_link,
)
from pipeline.geometry.link_reach import SPEED_SLACK, LinkReach, link_point_speed_bounds
from pipeline.geometry.motion_certificate import (
    DEFAULT_MAX_EVALUATIONS,
    DEFAULT_RESOLUTION_M,
    DEFAULT_TOLERANCE_M,
    Certificate,
    certify_motion,
    conclude,
    interval_argmin_offset,
    interval_lower_bound,
)
from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle
from pipeline.motion.trajectory import JointTrajectory
from pipeline.validation import check_non_negative, check_positive, check_positive_int

#: Motion resolution of the adaptive initial grid [m]: no link point moves more than this between samples.
COARSE_RESOLUTION_M = 0.15
#: Fewest initial samples of the adaptive grid, per link.
MIN_INITIAL_SAMPLES = 8
#: Safety factor of the split count: an interval of bound-deficit is split into
#: ceil(SPLIT_SAFETY * V h / (2 * (min(d_a, d_b) - target))) parts, 2 .. MAX_SPLIT.
SPLIT_SAFETY = 1.5
#: Most parts one interval is split into per round.
MAX_SPLIT = 8
#: The initial grids: "adaptive" (coarse, then per-link bisection) or "dense" (the former 1 mm grid).
INITIAL_GRIDS = ("adaptive", "dense")


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
    initial: str = "adaptive",
    resolution_m: float | None = None,
    distance_error_m: float = COAL_DISTANCE_ERROR_M,
    tolerance_m: float = DEFAULT_TOLERANCE_M,
    decide_above_m: float | None = None,
    max_evaluations: int = DEFAULT_MAX_EVALUATIONS,
    link_clearance: LinkClearanceFunction | None = None,
    compiled: bool = True,
) -> Certificate:
    """Certify a lower bound on the clearance of ``trajectory`` over the continuous interval [0, T].

    Args:
        trajectory: The joint trajectory (the paper's sinusoids).
        clearance: Per-link clearance function, (m, 2) [rad] -> (m, 2) [m], e.g.
            ``CoalClearance(arm, obstacle).link_clearance``.
        reach: Reach of the links' collision geometry (:meth:`LinkReach.from_arm`).
        samples: Number of initial uniform samples over [0, T] (>= 2); default from ``resolution_m``
            (:func:`samples_for_resolution`, at least :data:`MIN_INITIAL_SAMPLES` for "adaptive").
        initial: "adaptive" (default: coarse grid, then per-link bisection, module docstring step 3)
            or "dense" (the former route: fine grid and :func:`certify_motion`).
        resolution_m: Motion resolution of the initial grid [m]; default :data:`COARSE_RESOLUTION_M`
            for "adaptive", :data:`DEFAULT_RESOLUTION_M` (1 mm) for "dense".
        distance_error_m, tolerance_m, decide_above_m, max_evaluations: as in :func:`certify_motion`.
        link_clearance: One link's clearance, (m, 2) [rad] and link 0 / 1 -> (m,) [m] (e.g.
            ``CoalClearance.link_distances``), for the adaptive route's per-link bisection; default
            from ``clearance`` (which then computes both links).
        compiled: For the adaptive route, run each refinement round's bookkeeping compiled
            (:mod:`pipeline.geometry.adaptive_kernel`, the same operations, tested equal); False:
            the readable NumPy route.

    Returns:
        The :class:`Certificate`.

    Raises:
        InvalidParameterError: bad settings, or a clearance function returning non-finite values.
    """
    if initial not in INITIAL_GRIDS:
        raise InvalidParameterError("initial", initial, f"one of {INITIAL_GRIDS}")
    if resolution_m is None:
        resolution_m = COARSE_RESOLUTION_M if initial == "adaptive" else DEFAULT_RESOLUTION_M
    check_positive("resolution_m", resolution_m)
    if initial == "dense":
        n = samples_for_resolution(trajectory, reach, resolution_m) if samples is None else samples
        check_positive_int("samples", n, minimum=2)
        return _certify_dense(
            trajectory, clearance, reach, n, (distance_error_m, tolerance_m, decide_above_m), max_evaluations
        )
    check_non_negative("distance_error_m", distance_error_m)
    check_positive("tolerance_m", tolerance_m)
    check_positive_int("max_evaluations", max_evaluations, minimum=0)
    core = _AdaptiveCertificate(trajectory, reach)
    if samples is None:
        n = _adaptive_initial_samples(core, reach, resolution_m)
    else:
        check_positive_int("samples", samples, minimum=2)
        n = (samples, samples)
    return core.run(
        n,
        clearance,
        link_clearance if link_clearance is not None else per_link(clearance),
        distance_error_m,
        tolerance_m,
        decide_above_m,
        max_evaluations,
        compiled,
    )


def _certify_dense(
    trajectory: JointTrajectory,
    clearance: ClearanceFunction,
    reach: LinkReach,
    samples: int,
    settings: tuple[float, float, float | None],
    max_evaluations: int,
) -> Certificate:
    """The dense route: ``samples`` uniform times over [0, T] and :func:`certify_motion` with the
    closed-form interval speed bounds of :func:`link_speed_bounds`.

    Args:
        settings: (distance error [m], tolerance [m], decide-above value [m] or None), as in :func:`certify`.
    """
    distance_error_m, tolerance_m, decide_above_m = settings

    def speed_bound(ta: np.ndarray, tb: np.ndarray) -> np.ndarray:
        return link_speed_bounds(trajectory, reach, ta, tb)

    return certify_motion(
        trajectory.q,
        np.linspace(0.0, trajectory.duration_s, samples),
        clearance,
        speed_bound,
        distance_error_m=distance_error_m,
        tolerance_m=tolerance_m,
        decide_above_m=decide_above_m,
        max_evaluations=max_evaluations,
    )


def _adaptive_initial_samples(core: _AdaptiveCertificate, reach: LinkReach, resolution_m: float) -> tuple[int, int]:
    """Initial samples of each link's grid over [0, T]: as :func:`samples_for_resolution`, per link, from
    the peak joint rates ``|A_i w_i|`` [rad/s] (scalar bounds), so that no point of the link moves more
    than ``resolution_m`` [m] between samples; at least :data:`MIN_INITIAL_SAMPLES`."""
    rate1, rate2 = (float(v) for v in core.rate_peak)
    speeds = (
        rate1 * reach.link1_radius_m,
        rate1 * (reach.elbow_distance_m + reach.link2_radius_m) + rate2 * reach.link2_radius_m,
    )
    return tuple(max(MIN_INITIAL_SAMPLES, math.ceil(v * core.duration / resolution_m) + 1) for v in speeds)


def _clearance_values(link_clearance, q, points, point_link, error, observed, observed_time) -> np.ndarray:
    """The clearances [m] at the new points (configurations ``q``, link per point), less the
    distance routine's ``error``; the observed minima per link (lists) updated in place.

    Raises:
        InvalidParameterError: the clearance function returned a value that is not finite.
    """
    values = np.empty(points.size)
    for k, mask in ((0, ~point_link), (1, point_link)):
        if mask.any():
            got = np.asarray(link_clearance(q[mask], k), dtype=float)
            if not math.isfinite(float(got.sum())):
                raise InvalidParameterError(
                    "clearance", "non-finite values", "finite distances from the clearance function"
                )
            i = int(got.argmin())
            if got[i] < observed[k]:
                observed[k], observed_time[k] = float(got[i]), float(points[mask][i])
            values[mask] = got - error
    return values


def _split_parts(
    refine: np.ndarray, intervals: tuple[np.ndarray, ...], floor: float, tolerance: float, decide: float | None
) -> tuple[np.ndarray | None, int]:
    """New points per interval to refine (step 3): one (a bisection) in tolerance mode; in decide mode
    as many as should settle it, ``ceil(SPLIT_SAFETY V h / (2 g)) - 1`` with the parts clipped to
    2 .. :data:`MAX_SPLIT`.

    Args:
        refine: Which intervals to refine.
        intervals: (da, db [m], speed [m/s], h [s]) of every interval.
        floor: The smallest sample of both links less the distance error [m].
        tolerance, decide: As in :meth:`_AdaptiveCertificate.run` [m].

    Returns:
        (new points per interval to refine, their total); (None, 0) if there is none to refine.
    """
    if not refine.any():
        return None, 0
    if decide is None:  # tolerance mode: bisect
        inner = np.ones(int(np.count_nonzero(refine)), dtype=int)
        return inner, inner.size
    da, db, speed, h = intervals
    gap = np.minimum(da, db)[refine] - min(floor - tolerance, decide)
    parts = np.clip(np.ceil(SPLIT_SAFETY * speed[refine] * h[refine] / (2.0 * gap)), 2, MAX_SPLIT)
    inner = parts.astype(int) - 1
    return inner, int(inner.sum())


def _keep_lowest_settled(
    best: list[tuple[float, float]],
    settled: np.ndarray,
    link: np.ndarray,
    lower: np.ndarray,
    intervals: tuple[np.ndarray, ...],
) -> None:
    """Lower ``best[k]``, link k's (lowest settled bound [m], where [s]), to the lowest bound ``lower``
    of its settled intervals, if lower, with the time where that interval's bound is attained.

    Args:
        intervals: (ta [s], da, db [m], speed [m/s], h [s]) of every interval.
    """
    ta, da, db, speed, h = intervals
    for k, mask in ((0, settled & ~link), (1, settled & link)):
        if mask.any():
            candidates = np.where(mask, lower, np.inf)
            i = int(candidates.argmin())
            if candidates[i] < best[k][0]:
                offset = interval_argmin_offset(float(da[i]), float(db[i]), float(speed[i]), float(h[i]))
                best[k] = (float(candidates[i]), float(ta[i] + offset))


def _grid_minima(grids: list[tuple[np.ndarray, np.ndarray]]) -> tuple[list[float], list[float]]:
    """Each link's smallest clearance [m] over its grid of (times [s], clearances [m]) and its time [s].

    Raises:
        InvalidParameterError: a clearance is not finite.
    """
    observed, observed_time = [], []
    for times, values in grids:
        if not math.isfinite(float(values.sum())):  # NaN and +-inf propagate into the sum
            raise InvalidParameterError(
                "clearance", "non-finite values", "finite distances from the clearance function"
            )
        i = int(values.argmin())
        observed.append(float(values[i]))
        observed_time.append(float(times[i]))
    return observed, observed_time


class _AdaptiveCertificate:
    """The adaptive route (module docstring, step 3): lean arithmetic on one trajectory's sinusoids."""

    def __init__(self, trajectory: JointTrajectory, reach: LinkReach) -> None:
        a1, w1, phi1, gamma1, a2, w2, phi2, gamma2 = (float(v) for v in trajectory.parameters)
        self.duration = trajectory.duration_s
        self.amplitude, self.w = np.array([a1, a2]), np.array([w1, w2])
        self.phi, self.gamma = np.array([phi1, phi2]), np.array([gamma1, gamma2])
        self.rate_amplitude = np.array([a1 * w1, a2 * w2])
        self.rate_peak = np.abs(self.rate_amplitude)  # max |dtheta_i/dt| [rad/s]
        self.acceleration_peak = np.array([abs(a1 * w1 * w1), abs(a2 * w2 * w2)])  # max |d2theta_i/dt2| [rad/s^2]
        self.half_w, self.half_abs_w = np.array([w1 / 2.0, w2 / 2.0]), np.array([abs(w1) / 2.0, abs(w2) / 2.0])
        rho1, e, rho2 = reach.link1_radius_m, reach.elbow_distance_m, reach.link2_radius_m
        # The link_point_speed_bounds factors, inflated by SPEED_SLACK against rounding.
        self.link1_factor = rho1 * SPEED_SLACK
        self.link2_factors = ((e + rho2) * SPEED_SLACK, rho2 * SPEED_SLACK, e * SPEED_SLACK)
        # The same constants for the compiled rounds (adaptive_kernel.MOTION_FIELDS order).
        self.motion = np.array(
            [*self.half_w, *self.phi, *self.half_abs_w, *self.rate_peak, *self.acceleration_peak]
            + [*self.rate_amplitude, self.link1_factor, *self.link2_factors, *self.w, *self.amplitude, *self.gamma]
        )

    def q(self, t: np.ndarray) -> np.ndarray:
        """Joint angles (m, 2) [rad] at times t (m,) [s] (Eq. 1)."""
        return np.sin(np.multiply.outer(t, self.w) + self.phi) * self.amplitude + self.gamma

    def speeds(self, ta: np.ndarray, tb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Bounds [m/s] on every point's speed of link 1 and of link 2 over each [ta, tb] (step 2).

        With ``u_m`` the phase at the midpoint and ``delta = |w| h / 2`` (at most pi/2), every phase
        of the interval is ``u_m + x``, ``|x| <= delta``, so ``|cos u| <= |cos u_m| + |sin u_m| sin delta``
        and ``|sin u| <= |sin u_m| + |cos u_m| sin delta`` (both capped at 1): the interval maxima of
        the joint rates and accelerations, within O(delta^2) of the closed forms of
        :func:`link_speed_bounds`, from one sine and one cosine per joint.
        """
        h = tb - ta
        um = np.multiply.outer(ta + tb, self.half_w)
        um += self.phi
        spread = np.multiply.outer(h, self.half_abs_w)
        np.minimum(spread, np.pi / 2, out=spread)
        np.sin(spread, out=spread)
        sine, cosine = np.sin(um), np.cos(um)
        abs_sine, abs_cosine = np.abs(sine), np.abs(cosine)
        rate = abs_sine * spread
        rate += abs_cosine
        np.minimum(rate, 1.0, out=rate)
        rate *= self.rate_peak
        acceleration = abs_cosine * spread
        acceleration += abs_sine
        np.minimum(acceleration, 1.0, out=acceleration)
        acceleration *= self.acceleration_peak
        mid_rates = cosine * self.rate_amplitude
        w1, w2 = rate[:, 0], rate[:, 1]
        sum_rate = np.abs(mid_rates[:, 0] + mid_rates[:, 1])
        sum_rate += h * (acceleration[:, 0] + acceleration[:, 1]) / 2.0
        np.minimum(sum_rate, w1 + w2, out=sum_rate)
        v1 = w1 * self.link1_factor
        v2 = np.minimum(
            w1 * self.link2_factors[0] + w2 * self.link2_factors[1],
            w1 * self.link2_factors[2] + sum_rate * self.link2_factors[1],
        )
        return v1, v2

    @staticmethod
    def _refine(lower: np.ndarray, floor: float, tolerance: float, decide: float | None) -> np.ndarray:
        """Which intervals to refine (step 3): loose ones, or in decide mode the undecided loose ones."""
        refine = lower < floor - tolerance
        if decide is not None:
            if floor <= decide:
                refine[:] = False
            else:
                refine &= lower <= decide
        return refine

    def run(
        self,
        n: tuple[int, int],
        clearance: ClearanceFunction,
        link_clearance: LinkClearanceFunction,
        error: float,
        tolerance: float,
        decide: float | None,
        max_evaluations: int,
        compiled: bool = False,
    ) -> Certificate:
        """The adaptive certificate (module docstring, step 3) from ``n`` initial samples per link.

        Args:
            n: Initial uniform samples over [0, T] of link 1 and of link 2 (>= 2 each).
            clearance: Both links' clearance, (m, 2) [rad] -> (m, 2) [m] (the initial grid when shared).
            link_clearance: One link's clearance, (m, 2) [rad] and link 0 / 1 -> (m,) [m].
            error: The clearance function's distance error [m].
            tolerance: Target gap between the bound and the smallest sample [m].
            decide: Decide mode's value [m], or None for tolerance mode.
            max_evaluations: Budget of refinement evaluations (configurations, one link each).
            compiled: Run the rounds' bookkeeping compiled (:meth:`_compiled_rounds`), else in NumPy.
        """
        grids, initial = self._initial_grids(n, clearance, link_clearance)
        observed, observed_time = _grid_minima(grids)  # per link, over every sample [m, s]
        sampled_link, sampled_time = tuple(observed), tuple(observed_time)
        best = [(math.inf, 0.0), (math.inf, 0.0)]  # per link: (lowest settled bound, where) [m, s]
        rounds_of = self._compiled_rounds if compiled else self._numpy_rounds
        evaluations, rounds, converged = rounds_of(
            self._initial_intervals(grids, error),
            link_clearance,
            (error, tolerance, decide),
            max_evaluations,
            best,
            (observed, observed_time),
        )
        return conclude(
            interval_bound_m=(best[0][0], best[1][0]),
            interval_time_s=(best[0][1], best[1][1]),
            observed_m=observed,
            observed_time_s=observed_time,
            sampled_m=sampled_link,
            sampled_time_s=sampled_time,
            distance_error_m=error,
            tolerance_m=tolerance,
            initial_samples=initial,
            evaluations=initial + evaluations,
            refinement_rounds=rounds,
            converged=converged,
        )

    def _initial_grids(
        self, n: tuple[int, int], clearance: ClearanceFunction, link_clearance: LinkClearanceFunction
    ) -> tuple[list[tuple[np.ndarray, np.ndarray]], int]:
        """Each link's initial grid: (times [s], clearances [m]) of ``n[k]`` uniform samples over [0, T],
        one grid for both links at once when they are the same size.

        Returns:
            The two grids and the number of their distinct times.
        """
        if n[0] == n[1]:
            times = np.linspace(0.0, self.duration, n[0])
            both = np.asarray(clearance(self.q(times)), dtype=float).reshape(n[0], 2)
            return [(times, both[:, 0]), (times, both[:, 1])], n[0]
        grids = []
        for k in (0, 1):
            times = np.arange(n[k], dtype=float)
            times *= self.duration / (n[k] - 1)  # as np.linspace, the last exactly T
            times[-1] = self.duration
            grids.append((times, np.asarray(link_clearance(self.q(times), k), dtype=float).reshape(n[k])))
        # Distinct times of the two grids: both ends, and gcd(n1 - 1, n2 - 1) - 1 common inner points.
        return grids, n[0] + n[1] - math.gcd(n[0] - 1, n[1] - 1) - 1

    def _initial_intervals(self, grids: list[tuple[np.ndarray, np.ndarray]], error: float) -> tuple[np.ndarray, ...]:
        """The open intervals of both links' grids, as the rounds take them: (ta, tb [s], da, db [m]: the
        clearance minus ``error`` at the ends, link: False for link 1, True for link 2, speed [m/s], own).

        Speed bounds are first the global ones (peak joint rates); where an interval is refined, its own
        (step 2) replaces it and ``own`` is set; a sub-interval inherits its parent's, valid on it, until
        it is refined.
        """
        ta = np.concatenate([grids[0][0][:-1], grids[1][0][:-1]])
        tb = np.concatenate([grids[0][0][1:], grids[1][0][1:]])
        da = np.concatenate([grids[0][1][:-1], grids[1][1][:-1]]) - error
        db = np.concatenate([grids[0][1][1:], grids[1][1][1:]]) - error
        link = np.repeat(np.array([False, True]), [grids[0][0].size - 1, grids[1][0].size - 1])
        rate1, rate2 = (float(v) for v in self.rate_peak)
        global_speed = (rate1 * self.link1_factor, rate1 * self.link2_factors[0] + rate2 * self.link2_factors[1])
        speed = np.where(link, global_speed[1], global_speed[0])
        own = np.zeros(ta.size, dtype=bool)  # True where ``speed`` is the interval's own bound
        return ta, tb, da, db, link, speed, own

    def _numpy_rounds(
        self,
        state: tuple[np.ndarray, ...],
        link_clearance: LinkClearanceFunction,
        settings: tuple[float, float, float | None],
        budget: int,
        best: list[tuple[float, float]],
        seen: tuple[list[float], list[float]],
    ) -> tuple[int, int, bool]:
        """The refinement rounds of :meth:`run` in NumPy, arguments and result as :meth:`_compiled_rounds`:
        each round bounds the intervals, keeps the settled ones' lowest bound in ``best`` and splits the
        others at new points, evaluated with ``link_clearance``.

        Returns:
            (refinement evaluations, rounds, converged).
        """
        ta, tb, da, db, link, speed, own = state
        error, tolerance, decide = settings
        evaluations, rounds, converged = 0, 0, True
        while ta.size:
            h = tb - ta
            floor = min(seen[0]) - error
            lower, refine = self._bound_intervals((ta, tb, da, db, link, speed, own), h, floor, tolerance, decide)
            inner, count = _split_parts(refine, (da, db, speed, h), floor, tolerance, decide)
            if count > budget - evaluations:
                converged, refine[:], count = False, False, 0
            _keep_lowest_settled(best, ~refine, link, lower, (ta, da, db, speed, h))
            if not count:
                break
            rounds += 1
            kept = tuple(a[refine] for a in (ta, tb, da, db, link, speed, h))
            ta, tb, da, db, link, speed, own = self._split(kept, inner, count, link_clearance, error, seen)
            evaluations += count
        return evaluations, rounds, converged

    def _bound_intervals(
        self, state: tuple[np.ndarray, ...], h: np.ndarray, floor: float, tolerance: float, decide: float | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Each interval's lower bound [m] and which to refine (:meth:`_refine`); where an interval to refine
        has only an inherited speed bound, its own (step 2) is computed first and written into the
        state's ``speed`` and ``own`` in place.

        Args:
            state: (ta, tb, da, db, link, speed, own) as in :meth:`_initial_intervals`.
            h: Interval lengths [s].
            floor: The smallest sample of both links less the distance error [m].
        """
        ta, tb, da, db, link, speed, own = state
        lower = interval_lower_bound(da, db, speed, h)
        refine = self._refine(lower, floor, tolerance, decide)
        stale = refine & ~own
        if stale.any():
            v1, v2 = self.speeds(ta[stale], tb[stale])
            speed[stale] = np.where(link[stale], v2, v1)
            own[stale] = True
            lower = interval_lower_bound(da, db, speed, h)
            refine = self._refine(lower, floor, tolerance, decide)
        return lower, refine

    def _split(
        self,
        intervals: tuple[np.ndarray, ...],
        inner: np.ndarray,
        count: int,
        link_clearance: LinkClearanceFunction,
        error: float,
        seen: tuple[list[float], list[float]],
    ) -> tuple[np.ndarray, ...]:
        """Split the intervals to refine at ``inner`` new points each, ``j / (inner + 1)`` of the way
        through, j = 1 .. inner, evaluated with ``link_clearance`` (the observed minima ``seen`` updated).

        Args:
            intervals: (ta, tb [s], da, db [m], link, speed [m/s], h [s]) of the intervals to refine.
            inner: New points per interval; ``count`` their sum.

        Returns:
            The sub-intervals as (ta, tb, da, db, link, speed, own): [previous point, point] for every new
            point, then [last point, tb]; speeds inherited, none their own.
        """
        ta, tb, da, db, link, speed, h = intervals
        owner = np.arange(ta.size).repeat(inner)
        last = np.cumsum(inner) - 1
        j = np.arange(count) - (last + 1 - inner).repeat(inner) + 1
        points = ta[owner] + h[owner] * (j / (inner + 1)[owner])
        point_link = link[owner]
        q = self.q(points)
        values = _clearance_values(link_clearance, q, points, point_link, error, seen[0], seen[1])
        first = j == 1
        previous_t, previous_d = np.empty(count), np.empty(count)
        previous_t[1:], previous_d[1:] = points[:-1], values[:-1]
        previous_t[first], previous_d[first] = ta[owner[first]], da[owner[first]]
        ta, tb = np.concatenate([previous_t, points[last]]), np.concatenate([points, tb])
        da, db = np.concatenate([previous_d, values[last]]), np.concatenate([values, db])
        link = np.concatenate([point_link, link])
        speed = np.concatenate([speed[owner], speed])
        return ta, tb, da, db, link, speed, np.zeros(ta.size, dtype=bool)

    def _compiled_rounds(
        self,
        state: tuple[np.ndarray, ...],
        link_clearance: LinkClearanceFunction,
        settings: tuple[float, float, float | None],
        budget: int,
        best: list[tuple[float, float]],
        seen: tuple[list[float], list[float]],
    ) -> tuple[int, int, bool]:
        """The refinement rounds of :meth:`run` with their bookkeeping compiled
        (:func:`pipeline.geometry.adaptive_kernel.plan_round`, :func:`~pipeline.geometry.adaptive_kernel.merge_round`),
        the clearance evaluated between them; ``best`` and the observed minima ``seen`` updated in place.

        Returns:
            (refinement evaluations, rounds, converged).
        """
        ta, tb, da, db, link, speed, own = state
        error, tolerance, decide = settings
        observed, observed_time = seen
        best_value = np.array([best[0][0], best[1][0]])
        best_time = np.array([best[0][1], best[1][1]])
        has_decide = decide is not None
        decide_value = float(decide) if has_decide else 0.0
        evaluations, rounds, converged = 0, 0, True
        while ta.size:
            floor = min(observed) - error
            count, over_budget, refine, _, points, point_link, q, owner, j, last = plan_round(
                ta, tb, da, db, link, speed, own, floor, tolerance, decide_value, has_decide,
                budget - evaluations, SPLIT_SAFETY, float(MAX_SPLIT), best_value, best_time, self.motion,
            )  # fmt: skip
            if over_budget:
                converged = False
            if not count:
                break
            rounds += 1
            values = _clearance_values(link_clearance, q, points, point_link, error, observed, observed_time)
            evaluations += count
            ta, tb, da, db, link, speed, own = merge_round(
                ta, tb, da, db, link, speed, refine, points, values, point_link, owner, j, last
            )
        best[0], best[1] = (float(best_value[0]), float(best_time[0])), (float(best_value[1]), float(best_time[1]))
        return evaluations, rounds, converged


def arm_reach(arm: PlanarArm) -> LinkReach:
    """:meth:`LinkReach.from_arm`, computed once per arm object and kept by it (:meth:`PlanarArm.derived`)."""
    return arm.derived(LinkReach.from_arm)


def certify_trajectory(
    trajectory: JointTrajectory,
    arm: PlanarArm,
    obstacle: Obstacle,
    *,
    route: ClearanceRoute = COAL,
    samples: int | None = None,
    initial: str = "adaptive",
    resolution_m: float | None = None,
    tolerance_m: float = DEFAULT_TOLERANCE_M,
    decide_above_m: float | None = None,
    max_evaluations: int = DEFAULT_MAX_EVALUATIONS,
) -> Certificate:
    """Certify one joint trajectory against one obstacle: the entry point for sweeps and the generator.

    Args:
        trajectory: The joint trajectory.
        arm: The arm (its collision geometry gives the distances and the speed bound's reach).
        obstacle: The rounded box.
        route: ``COAL`` (the arm's Pinocchio collision geometry + Coal, the canonical route) or
            ``ANALYTIC`` (planar capsule-to-rounded-rectangle distance; only for capsule links in the xy plane).
        samples, initial, resolution_m, tolerance_m, decide_above_m, max_evaluations: as in :func:`certify`.

    Returns:
        The :class:`Certificate`; ``.certified_clearance_m`` is the certified clearance [m].

    Raises:
        InvalidParameterError: unknown route or bad settings.
        RobotModelError: ``route="analytic"`` on an arm that does not suit it.
    """
    function, one_link = route.functions(arm, obstacle)
    return certify(
        trajectory,
        function,
        arm_reach(arm),
        samples=samples,
        initial=initial,
        resolution_m=resolution_m,
        distance_error_m=route.distance_error_m,
        tolerance_m=tolerance_m,
        decide_above_m=decide_above_m,
        max_evaluations=max_evaluations,
        link_clearance=one_link,
    )
