"""The certificate core shared by every motion: a rigorous lower bound on the clearance over a
continuous time interval, from samples of the clearance and bounds on the link point speeds.

Derivation
==========

1. **Distance is 1-Lipschitz in the motion of the geometry.** If every material point of a
   link moves by at most ``delta`` between times ``s`` and ``t``, the two placed geometries are
   within Hausdorff distance ``delta`` of each other, so the (non-negative) distance from the
   link to a fixed obstacle changes by at most ``delta``: ``|d(t) - d(s)| <= delta <= V |t - s|``
   with ``V`` a bound on the speed of every point of the link over ``[s, t]``
   (:mod:`pipeline.geometry.link_reach`; the motion's own module bounds the joint rates).

2. **Interval lower bound.** On ``[ta, tb]`` (length ``h``) with speed bound ``V``,
   ``d(t) >= max(d(ta) - V (t - ta), d(tb) - V (tb - t))``, whose minimum over the interval is
   ``(d(ta) + d(tb) - V h) / 2``, reached at ``ta + (d(ta) - d(tb) + V h) / (2 V)``.

3. **Distance error.** Every sampled value enters the bound as ``d - distance_error_m`` (the
   route's bound, :mod:`pipeline.geometry.clearance`: 1e-5 m for Coal, 1e-12 m analytic).

4. **Adaptive bisection.** Every interval whose bound is more than ``tolerance_m`` below the
   smallest sampled value (so the bound is too loose to say anything better) is bisected: one
   more clearance evaluation at its midpoint, two intervals with smaller ``h`` and tighter speed
   bounds. With ``decide_above_m``, only intervals whose bound is at or below that value are
   bisected, and refinement stops as soon as a sample is at or below it: the question is then
   only "is the clearance above this value?".

The certified clearance is the minimum of all interval bounds and all sampled values (minus
the distance error). It is a rigorous lower bound whenever it is positive; where a sample is in
contact (``d <= 0``) the certified value is at most that sample and the case is in collision.
A motion is *certified collision-free* only if the certified clearance is ``> 0``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.clearance import COAL_DISTANCE_ERROR_M, ClearanceFunction
from pipeline.validation import check_non_negative, check_positive, check_positive_int

#: Default motion resolution [m]: no point of either link moves more than this between samples.
DEFAULT_RESOLUTION_M = 1e-3
#: Default certificate tolerance [m]: stop refining once the bound is this close to the samples.
DEFAULT_TOLERANCE_M = 1e-5
#: Default cap on clearance evaluations (configurations) spent on refinement per trajectory.
DEFAULT_MAX_EVALUATIONS = 200_000

#: A speed bound: interval ends ta, tb (m,) [s] -> bound on every link point's speed (m, 2) [m/s].
SpeedBound = Callable[[np.ndarray, np.ndarray], np.ndarray]


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
        initial_samples: Number of initial uniform samples (the adaptive sinusoid route samples each
            link on its own grid: the number of distinct times of both grids).
        evaluations: Clearance evaluations made (configurations; initial samples + refinements; the
            adaptive route's refinements evaluate one link each).
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
    values = _evaluated(clearance, q, times)
    sampled_link = np.min(values, axis=0)
    # Open intervals (ends, and clearance minus the distance error at the ends).
    intervals = (times[:-1], times[1:], values[:-1] - distance_error_m, values[1:] - distance_error_m)
    refinement = _bisection_rounds(
        q,
        clearance,
        speed_bound,
        intervals,
        (sampled_link.copy(), times[np.argmin(values, axis=0)]),
        (distance_error_m, tolerance_m, decide_above_m),
        max_evaluations,
    )
    sampled_rows = np.argmin(values, axis=0)
    return conclude(
        interval_bound_m=refinement.interval_bound_m,
        interval_time_s=refinement.interval_time_s,
        observed_m=refinement.observed_m,
        observed_time_s=refinement.observed_time_s,
        sampled_m=sampled_link,
        sampled_time_s=times[sampled_rows],
        distance_error_m=distance_error_m,
        tolerance_m=tolerance_m,
        initial_samples=n,
        evaluations=n + refinement.evaluations,
        refinement_rounds=refinement.rounds,
        converged=refinement.converged,
    )


def _evaluated(clearance: ClearanceFunction, q: Callable[[np.ndarray], np.ndarray], t: np.ndarray) -> np.ndarray:
    """The clearances (m, 2) [m] of both links at times ``t`` (m,) [s] of the motion ``q``.

    Raises:
        InvalidParameterError: the clearance function returned a value that is not finite.
    """
    values = np.asarray(clearance(q(t)), dtype=float).reshape(len(t), 2)
    if not np.all(np.isfinite(values)):
        raise InvalidParameterError("clearance", "non-finite values", "finite distances from the clearance function")
    return values


@dataclass(frozen=True)
class _Refinement:
    """What the bisection rounds of :func:`certify_motion` found, per link (link 1, link 2).

    Attributes:
        interval_bound_m, interval_time_s: Lowest settled interval bound [m] and where [s].
        observed_m, observed_time_s: Lowest evaluated clearance [m] and when [s], initial samples included.
        evaluations: Refinement evaluations (configurations) beyond the initial samples.
        rounds: Bisection rounds.
        converged: False if the evaluation budget ran out first.
    """

    interval_bound_m: np.ndarray
    interval_time_s: np.ndarray
    observed_m: np.ndarray
    observed_time_s: np.ndarray
    evaluations: int
    rounds: int
    converged: bool


def _bisection_rounds(
    q: Callable[[np.ndarray], np.ndarray],
    clearance: ClearanceFunction,
    speed_bound: SpeedBound,
    intervals: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    seen: tuple[np.ndarray, np.ndarray],
    settings: tuple[float, float, float | None],
    budget: int,
) -> _Refinement:
    """Bisect the intervals whose bound is loose (or, deciding, undecided) until none is or ``budget``
    would be exceeded; every other interval's bound is settled.

    Args:
        q, clearance, speed_bound: As in :func:`certify_motion`.
        intervals: (ta, tb [s], da, db (m, 2) [m]: the clearance less the distance error at the ends).
        seen: Lowest sampled clearance per link [m] and when [s].
        settings: (distance error, tolerance, decide-above value or None) [m], as in :func:`certify_motion`.
        budget: Most refinement evaluations (configurations).
    """
    ta, tb, da, db = intervals
    observed, observed_time = seen
    error, tolerance, decide = settings
    done_lb: list[np.ndarray] = []
    done_t: list[np.ndarray] = []
    evaluations, rounds, converged = 0, 0, True
    while ta.size:
        lower, where = _interval_bounds(speed_bound(ta, tb), ta, tb, da, db)
        refine = _to_refine(np.min(lower, axis=1), float(np.min(observed)) - error, tolerance, decide)
        if np.count_nonzero(refine) > budget - evaluations:
            converged = False
            refine[:] = False
        done_lb.append(lower[~refine])
        done_t.append(where[~refine])
        if not np.any(refine):
            break
        rounds += 1
        mid = (ta[refine] + tb[refine]) / 2.0
        mid_values = _evaluated(clearance, q, mid)
        evaluations += mid.size
        rows = np.argmin(mid_values, axis=0)
        better = mid_values[rows, [0, 1]] < observed
        observed = np.where(better, mid_values[rows, [0, 1]], observed)
        observed_time = np.where(better, mid[rows], observed_time)
        dm = mid_values - error
        ta, tb = np.concatenate([ta[refine], mid]), np.concatenate([mid, tb[refine]])
        da, db = np.concatenate([da[refine], dm]), np.concatenate([dm, db[refine]])
    all_lb = np.concatenate(done_lb)
    all_t = np.concatenate(done_t)
    rows = np.argmin(all_lb, axis=0)
    return _Refinement(
        all_lb[rows, [0, 1]], all_t[rows, [0, 1]], observed, observed_time, evaluations, rounds, converged
    )


def _to_refine(worst: np.ndarray, floor: float, tolerance: float, decide: float | None) -> np.ndarray:
    """Which intervals to bisect, from their lower bound ``worst`` over both links [m]: those more than
    ``tolerance`` below ``floor`` (the smallest sample less the distance error) [m]; deciding, only those
    at or below ``decide`` [m], and none once ``floor`` is."""
    refine = worst < floor - tolerance
    if decide is not None:
        refine &= worst <= decide
        if floor <= decide:
            refine[:] = False
    return refine


def conclude(
    *,
    interval_bound_m: Sequence[float],
    interval_time_s: Sequence[float],
    observed_m: Sequence[float],
    observed_time_s: Sequence[float],
    sampled_m: Sequence[float],
    sampled_time_s: Sequence[float],
    distance_error_m: float,
    tolerance_m: float,
    initial_samples: int,
    evaluations: int,
    refinement_rounds: int,
    converged: bool,
) -> Certificate:
    """The :class:`Certificate` from a refinement's per-link results (every argument a pair: link 1, link 2).

    Each link's bound is the lower of its lowest settled interval bound and its lowest evaluated
    clearance minus the distance error, attained where that one is; the certified clearance is
    the lower link's. Shared by :func:`certify_motion` and the adaptive sinusoid route.

    Args:
        interval_bound_m, interval_time_s: Lowest settled interval bound per link [m] and where [s].
        observed_m, observed_time_s: Lowest evaluated clearance per link [m] and when [s].
        sampled_m, sampled_time_s: The same over the initial samples only [m], [s].
        distance_error_m, tolerance_m, initial_samples, evaluations, refinement_rounds, converged:
            As in :class:`Certificate`.
    """
    floor = [float(observed_m[k]) - distance_error_m for k in (0, 1)]
    bounds = [min(float(interval_bound_m[k]), floor[k]) for k in (0, 1)]
    where = [
        float(interval_time_s[k]) if interval_bound_m[k] <= floor[k] else float(observed_time_s[k]) for k in (0, 1)
    ]
    k = 0 if bounds[0] <= bounds[1] else 1
    seen = 0 if observed_m[0] <= observed_m[1] else 1
    sampled = 0 if sampled_m[0] <= sampled_m[1] else 1
    return Certificate(
        certified_clearance_m=bounds[k],
        certified_link_clearance_m=(bounds[0], bounds[1]),
        sampled_clearance_m=float(sampled_m[sampled]),
        sampled_link_clearance_m=(float(sampled_m[0]), float(sampled_m[1])),
        sampled_time_s=float(sampled_time_s[sampled]),
        min_observed_clearance_m=float(observed_m[seen]),
        min_observed_time_s=float(observed_time_s[seen]),
        bound_time_s=where[k],
        bound_link=k + 1,
        initial_samples=int(initial_samples),
        evaluations=int(evaluations),
        refinement_rounds=int(refinement_rounds),
        converged=bool(converged),
        distance_error_m=float(distance_error_m),
        tolerance_m=float(tolerance_m),
    )


def interval_lower_bound(da: np.ndarray, db: np.ndarray, speed: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Step 2: the lower bound (d(ta) + d(tb) - V h) / 2 [m] on an interval of length ``h`` [s]
    with end clearances ``da``, ``db`` [m] (distance error already subtracted) and speed bound ``V`` [m/s]."""
    return (da + db - speed * h) / 2.0


def interval_argmin_offset(da, db, speed, h):
    """Step 2: where in the interval (offset from ``ta``, clipped to [0, h]) [s] that bound is attained.

    Elementwise on arrays; on floats (one interval) in plain float arithmetic, the same formula.
    """
    if isinstance(speed, float):
        offset = (da - db + speed * h) / (2.0 * speed) if speed > 0 else 0.0
        return min(max(offset, 0.0), h)
    with np.errstate(divide="ignore", invalid="ignore"):
        offset = np.where(speed > 0, (da - db + speed * h) / (2.0 * speed), 0.0)
    return np.clip(offset, 0.0, h)


def _interval_bounds(
    speed: np.ndarray, ta: np.ndarray, tb: np.ndarray, da: np.ndarray, db: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Per-link lower bound (m, 2) [m] on each interval and where it is attained (m, 2) [s],
    given the link point speed bounds ``speed`` (m, 2) [m/s] on the intervals."""
    h = (tb - ta)[:, None]
    # Where the clearance is negative at an end the bound is only used as "not positive".
    return interval_lower_bound(da, db, speed, h), ta[:, None] + interval_argmin_offset(da, db, speed, h)
