"""Certificate that a timed joint trajectory respects the arm's limits over all of [0, T'].

For ``q(tau) = theta(sigma(tau))`` (:mod:`pipeline.motion.timing`) it proves rigorous upper bounds,
over the whole executed interval (continuous time, not samples), on: the joint angles' range,
|dq_i|, |ddq_i|, the joint jerks |d3q_i/dt3| and the joint torques |tau_i| of the arm's inverse
dynamics (:class:`pipeline.model.dynamics.PlanarDynamics`, identified from Pinocchio's RNEA).

**Enclosures over a time interval [a, b].**

* sigma, sigma', sigma'' and sigma''' are piecewise polynomials whose extremes over [a, b] lie at
  a, b, at the timing's knots or at the critical points of each piece
  (:meth:`pipeline.motion.timing.Timing.ranges_with_jerk`): their ranges are exact.
* theta_i = A sin(w s + phi) + gamma over s in [sigma(a), sigma(b)]: the range of sin over the
  phase interval is exact (its ends, and -1 / +1 where the interval holds -pi/2 / pi/2 modulo
  2 pi); likewise theta_i' = A w cos(.) and theta_i'' = -A w^2 sin(.).
* dq = theta' sigma', ddq = theta'' sigma'^2 + theta' sigma'', the jerk
  theta''' sigma'^3 + 3 theta'' sigma' sigma'' + theta' sigma''' (theta''' = -A w^3 cos(.)), and the torques
  ``tau1 = M11 ddq1 + M12 ddq2 + h (2 dq1 dq2 + dq2^2)``, ``tau2 = M12 ddq1 + M22 ddq2 - h dq1^2``
  with M_ij = m0 + mc cos q2 + ms sin q2 and h = (-mc11 sin q2 + ms11 cos q2) / 2 over the
  range of q2 (exact ranges of cos and sin), all in interval arithmetic: each result encloses
  every value the quantity takes on [a, b] (products of intervals take the extremes of the
  four corner products; a square of an interval holding 0 starts at 0).

Interval arithmetic overestimates (each quantity appears more than once), less so on shorter
intervals, so intervals are bisected where the question is open, and only there:

* **tight** (no limits given): where a bound exceeds the largest value sampled so far (at the
  intervals' ends and midpoints, the exact values of q, dq, ddq and tau) by more than the
  tolerance; the bounds end within the tolerance of the true maxima;
* **decide** (limits given): where a bound exceeds its limit while no sample does (a sample
  beyond it proves the violation) and the tolerance allows, starting from the timing's pieces
  (one for the paper's and the rest-to-rest timings). A coarser question is asked first, in
  closed form, for those two timings: the exact maxima V_i of
  |theta_i'| and A_i of |theta_i''| and the exact angle ranges of the sinusoids over [0, T]
  (:meth:`pipeline.motion.trajectory.JointTrajectory.peak_velocity_rad_s` and the like) give, for
  the paper timing, |dq_i| <= V_i and |ddq_i| <= A_i, and for a rest-to-rest timing (sigma' <= c,
  |sigma''| <= 1.5 c / r) |dq_i| <= c V_i and |ddq_i| <= c^2 A_i + 1.5 c V_i / r; the torque
  bound is ``sum_j Mmax_ij max|ddq_j| + Hmax c^2 Q_i`` with the suprema over q2 of |M_ij| and
  |h| over the path's exact range of q2 (Q_1 = 2 V_1 V_2 + V_2^2, Q_2 = V_1^2). If these keep
  every limit, nothing else runs. The jerk's closed-form bound is given at :func:`_closed_form`.

The bound is the largest enclosure over the final partition (rigorous), the sampled maximum a
value the quantity takes (so the true maximum lies between them).

**Rounding.** Every enclosure is widened by :data:`FLOAT_SLACK_RELATIVE` of its magnitude plus
:data:`FLOAT_SLACK_ABSOLUTE`: the chain is a few dozen floating-point operations on values of
order 1 (each correctly rounded to 1.1e-16 relative, sin and cos within an ulp), so its error
is below 1e-13 relative; the slack is a thousand times that. A critical point of sin lying
within rounding of a phase interval's end changes the range by the square of that rounding
(sin is flat there), far below the slack.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from pipeline.model.dynamics import PlanarDynamics
from pipeline.model.limits import ArmLimits
from pipeline.motion.interval_arithmetic import (
    FLOAT_SLACK_ABSOLUTE,
    FLOAT_SLACK_RELATIVE,
    affine_trig,
    magnitude,
    mul,
    scale,
    sin_extremes,
    sin_range,
    sinusoid_ranges,
    square,
    widen,
)
from pipeline.motion.path_box import TimedPathBox
from pipeline.motion.smooth_timing import SmoothTiming
from pipeline.motion.timed_trajectory import TimedTrajectory
from pipeline.motion.timing import PaperTiming, RestToRestTiming

__all__ = [
    "FLOAT_SLACK_ABSOLUTE",
    "FLOAT_SLACK_RELATIVE",
    "ExecutionCertificate",
    "LimitViolation",
    "certify_execution",
]

#: Default tolerance of the bounds: an interval is bisected while its enclosure exceeds the
#: sampled maximum by more than this fraction of it (or of 1e-3 in the quantity's unit).
DEFAULT_RELATIVE_TOLERANCE = 1e-4
_INITIAL_INTERVALS = 32
_MAX_INTERVALS = 200_000
_MAX_ROUNDS = 40
#: The certified quantities, in column order: the maxima of q1, q2, -q1, -q2, |dq|, |ddq|, |tau|, |jerk|.
_QUANTITIES = (
    "q1 max", "q2 max", "-q1 min", "-q2 min", "dq1", "dq2", "ddq1", "ddq2", "tau1", "tau2", "jerk1", "jerk2"
)  # fmt: skip


def _joint_enclosures(timed, lo: np.ndarray, hi: np.ndarray):
    """Per joint, the intervals of q, dq, ddq and the jerk over each [lo_k, hi_k] (module docstring),
    for every path between ``timed.parameter_bounds`` (one path, or a box of them)."""
    s_lo, s_hi, d1_lo, d1_hi, d2_lo, d2_hi, d3_lo, d3_hi = timed.timing.ranges_with_jerk(lo, hi)
    d1_sq = square(d1_lo, d1_hi)
    d1_cube = mul(*d1_sq, d1_lo, d1_hi)
    d1_d2 = mul(d1_lo, d1_hi, d2_lo, d2_hi)
    theta, speed, accel, jerk = [], [], [], []
    for angle, v, a, j in sinusoid_ranges(*timed.parameter_bounds, s_lo, s_hi, timed.mean_value):
        theta.append(widen(*angle))
        speed.append(widen(*mul(*v, d1_lo, d1_hi)))
        first, second = mul(*a, *d1_sq), mul(*v, d2_lo, d2_hi)
        accel.append(widen(first[0] + second[0], first[1] + second[1]))
        parts = (mul(*j, *d1_cube), scale(3.0, *mul(*a, *d1_d2)), mul(*v, d3_lo, d3_hi))
        jerk.append(widen(sum(q[0] for q in parts), sum(q[1] for q in parts)))
    return theta, speed, accel, jerk


def _torques(dynamics: PlanarDynamics, theta, speed, accel):
    """The intervals of tau_1, tau_2 from those of q2, dq and ddq (module docstring)."""
    q2_lo, q2_hi = theta[1]
    sin2 = sin_range(q2_lo, q2_hi)
    cos2 = sin_range(q2_lo + np.pi / 2, q2_hi + np.pi / 2)
    m0, mc, ms = (np.asarray(m) for m in (dynamics.m0, dynamics.mc, dynamics.ms))
    m11 = affine_trig(m0[0, 0], mc[0, 0], ms[0, 0], *cos2, *sin2)
    m12 = affine_trig(m0[0, 1], mc[0, 1], ms[0, 1], *cos2, *sin2)
    m22 = affine_trig(m0[1, 1], mc[1, 1], ms[1, 1], *cos2, *sin2)
    h = affine_trig(0.0, 0.5 * ms[0, 0], -0.5 * mc[0, 0], *cos2, *sin2)
    (dq1, dq2), (ddq1, ddq2) = speed, accel
    cross = mul(*dq1, *dq2)
    dq2_sq, dq1_sq = square(*dq2), square(*dq1)
    quadratic1 = (2.0 * cross[0] + dq2_sq[0], 2.0 * cross[1] + dq2_sq[1])
    parts1 = [mul(*m11, *ddq1), mul(*m12, *ddq2), mul(*h, *quadratic1)]
    minus_h = (-h[1], -h[0])
    parts2 = [mul(*m12, *ddq1), mul(*m22, *ddq2), mul(*minus_h, *dq1_sq)]
    return [widen(sum(p[0] for p in parts), sum(p[1] for p in parts)) for parts in (parts1, parts2)]


def _upper_bounds(timed: TimedTrajectory, dynamics: PlanarDynamics, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Rigorous upper bounds of the :data:`_QUANTITIES` over each interval [lo_k, hi_k]: (n, 12)."""
    theta, speed, accel, jerk = _joint_enclosures(timed, lo, hi)
    tau = _torques(dynamics, theta, speed, accel)
    columns = [theta[0][1], theta[1][1], -theta[0][0], -theta[1][0]]
    columns += [magnitude(v) for v in (*speed, *accel, *tau, *jerk)]
    return np.stack(columns, -1)


def _values(timed: TimedTrajectory, dynamics: PlanarDynamics, t: np.ndarray) -> np.ndarray:
    """The :data:`_QUANTITIES` at times ``t`` (exact evaluation): (m, 12)."""
    q, dq, ddq = timed.states(t, outside="clamp")
    tau = dynamics.torque(q, dq, ddq)
    jerk = timed.jerk(t, outside="clamp")
    return np.column_stack(
        [q[:, 0], q[:, 1], -q[:, 0], -q[:, 1], *np.abs(dq).T, *np.abs(ddq).T, *np.abs(tau).T, *np.abs(jerk).T]
    )


@dataclass(frozen=True)
class LimitViolation:
    """A certified bound beyond a limit.

    Attributes:
        quantity: "angle", "speed", "acceleration", "torque" or "jerk".
        joint: 1 or 2.
        bound: The certified bound (for an angle: the extreme of the certified range) [rad, rad/s,
            rad/s^2, N m, rad/s^3]. It is a bound: the motion's true extreme lies at or below it.
        limit: The limit it exceeds, same unit.
        unit: The unit's symbol.
    """

    quantity: str
    joint: int
    bound: float
    limit: float
    unit: str

    def __str__(self) -> str:
        if self.quantity == "angle":
            side = "upper" if self.bound > self.limit else "lower"
            relation = ">" if side == "upper" else "<"
            return (
                f"joint {self.joint} angle bound {self.bound:.4f} {self.unit} {relation} {side} limit "
                f"{self.limit:.4f} {self.unit} (by {abs(self.bound - self.limit):.3g} {self.unit})"
            )
        return (
            f"joint {self.joint} {self.quantity} bound {self.bound:.4f} {self.unit} > limit {self.limit:.4f} "
            f"{self.unit} (by {self.bound - self.limit:.3g} {self.unit})"
        )


def _unbounded_jerk() -> np.ndarray:
    return np.full(2, np.inf)


@dataclass(frozen=True, eq=False)
class ExecutionCertificate:
    """Rigorous bounds of a timed trajectory over all of [0, T'] (module docstring).

    Attributes:
        timing_name: The timing's name ("paper", "rest-to-rest", "near-optimal").
        duration_s: T' [s].
        angle_range_rad: ((lo1, hi1), (lo2, hi2)) enclosing every joint angle taken [rad].
        speed_bound_rad_s, acceleration_bound_rad_s2, torque_bound_n_m: (2,) upper bounds of
            |dq_i| [rad/s], |ddq_i| [rad/s^2], |tau_i| [N m].
        sampled: The largest values sampled (values the quantities take), per quantity as the bounds:
            {"speed_rad_s": (2,), "acceleration_rad_s2": (2,), "torque_n_m": (2,), "jerk_rad_s3": (2,),
            "angle_range_rad": ...}.
        intervals: Time intervals of the final partition (0: decided in closed form).
        decided_against: The limits the bounds were decided against (None: tight bounds).
        source: "query" (this certificate, over this trajectory) or "range" (the bounds of the
            region map's leaf holding the obstacle, proven for every obstacle of the leaf:
            :mod:`pipeline.certify.execution_bounds`; no samples).
        jerk_bound_rad_s3: (2,) upper bounds of the joint jerks [rad/s^3] (inf: not bounded, as
            for the map's bounds, which hold no jerk).
    """

    timing_name: str
    duration_s: float
    angle_range_rad: tuple[tuple[float, float], tuple[float, float]]
    speed_bound_rad_s: np.ndarray
    acceleration_bound_rad_s2: np.ndarray
    torque_bound_n_m: np.ndarray
    sampled: dict
    intervals: int
    decided_against: ArmLimits | None = None
    source: str = "query"
    jerk_bound_rad_s3: np.ndarray = field(default_factory=_unbounded_jerk)

    def violations(self, limits: ArmLimits) -> list[LimitViolation]:
        """Every limit a bound exceeds (empty: the trajectory is certified within ``limits``)."""
        found = []
        for i in (0, 1):
            lo, hi = self.angle_range_rad[i]
            limit_lo, limit_hi = limits.position_rad[i]
            if hi > limit_hi:
                found.append(LimitViolation("angle", i + 1, hi, limit_hi, "rad"))
            if lo < limit_lo:
                found.append(LimitViolation("angle", i + 1, lo, limit_lo, "rad"))
        for quantity, bounds, limit, unit in (
            ("speed", self.speed_bound_rad_s, limits.velocity_rad_s, "rad/s"),
            ("acceleration", self.acceleration_bound_rad_s2, limits.acceleration_rad_s2, "rad/s^2"),
            ("torque", self.torque_bound_n_m, limits.effort_n_m, "N m"),
            ("jerk", self.jerk_bound_rad_s3, limits.jerk_rad_s3, "rad/s^3"),
        ):
            for i in (0, 1):
                if bounds[i] > limit[i]:
                    found.append(LimitViolation(quantity, i + 1, float(bounds[i]), float(limit[i]), unit))
        return found


def _closed_form(timed: TimedTrajectory, dynamics: PlanarDynamics, limits: ArmLimits) -> ExecutionCertificate | None:
    """The bounds in closed form (module docstring), if they keep every limit; else None. For a
    rest-to-rest timing (speed scale c, ramp r: sigma' <= c, |sigma''| <= 1.5 c / r,
    |sigma'''| <= 6 c / r^2) the speeds scale by c, the accelerations are bounded by
    c^2 max|theta''| + 1.5 c max|theta'| / r, the jerks by c^3 |A| w^3 + 4.5 c^2 max|theta''| / r +
    6 c max|theta'| / r^2, and the torques follow from the speeds and accelerations as for the
    paper timing (c = 1, no ramp).

    In plain floats: the path's exact peaks and angle ranges are computed once per trajectory
    (:attr:`pipeline.motion.trajectory.JointTrajectory.peaks`), so both timings of one path share them,
    and the inertia suprema over that range of q2 (:func:`_inertia_sup`); each bound is a few
    products and sums, widened by the same slack as every enclosure."""
    peaks = timed.trajectory.peaks
    (V1, V2), (acc1, acc2), (third1, third2) = peaks.velocity_rad_s, peaks.acceleration_rad_s2, peaks.third_rad_s3
    (lo1, hi1), (lo2, hi2) = peaks.angle_ranges_rad
    c, ramp_term, jerk1, jerk2 = 1.0, 0.0, 0.0, 0.0
    if isinstance(timed.timing, RestToRestTiming):
        c, r = timed.timing.speed_scale, timed.timing.ramp_s
        ramp_term = 1.5 * c / r
        jerk1 = 4.5 * c * c * acc1 / r + 6.0 * c * V1 / r**2
        jerk2 = 4.5 * c * c * acc2 / r + 6.0 * c * V2 / r**2
    accel1, accel2 = c * c * acc1 + ramp_term * V1, c * c * acc2 + ramp_term * V2
    (m11, m12), (m21, m22), coriolis = _inertia_sup(dynamics, lo2, hi2)
    quadratic1, quadratic2 = c * c * (2.0 * V1 * V2 + V2**2), c * c * V1**2
    raw = (
        hi1, hi2, -lo1, -lo2,
        c * V1, c * V2,
        accel1, accel2,
        m11 * accel1 + m12 * accel2 + coriolis * quadratic1, m21 * accel1 + m22 * accel2 + coriolis * quadratic2,
        c**3 * third1 + jerk1, c**3 * third2 + jerk2,
    )  # fmt: skip
    relative, absolute = FLOAT_SLACK_RELATIVE, FLOAT_SLACK_ABSOLUTE
    bounds = [b + relative * abs(b) + absolute for b in raw]
    if any(b > limit for b, limit in zip(bounds, _limit_tuple(limits), strict=True)):
        return None
    return _certificate(timed, np.array(bounds), None, 0, limits)


def _inertia_sup(
    dynamics: PlanarDynamics, q2_lo: float, q2_hi: float
) -> tuple[tuple[float, float], tuple[float, float], float]:
    """sup of |M_ij(q2)| (rows (M11, M12), (M21, M22)) and of |h(q2)| over q2 in [q2_lo, q2_hi]
    (the path's exact range of q2): max |k0 + kc cos + ks sin| over the exact ranges of cos and sin,
    as interval arithmetic gives it; never above the suprema over all q2. Plain floats."""
    s_lo, s_hi = sin_extremes(q2_lo, q2_hi)
    c_lo, c_hi = sin_extremes(q2_lo + 0.5 * math.pi, q2_hi + 0.5 * math.pi)

    def sup(k0: float, kc: float, ks: float) -> float:
        low = k0 + min(kc * c_lo, kc * c_hi) + min(ks * s_lo, ks * s_hi)
        high = k0 + max(kc * c_lo, kc * c_hi) + max(ks * s_lo, ks * s_hi)
        return max(abs(low), abs(high))

    m0, mc, ms = dynamics.m0, dynamics.mc, dynamics.ms
    everywhere, coriolis_everywhere = dynamics.suprema
    row1, row2 = (tuple(min(sup(m0[i][j], mc[i][j], ms[i][j]), everywhere[i][j]) for j in (0, 1)) for i in (0, 1))
    coriolis = min(sup(0.0, 0.5 * ms[0][0], -0.5 * mc[0][0]), coriolis_everywhere)
    return row1, row2, coriolis  # type: ignore[return-value]


def _limit_vector(limits: ArmLimits) -> np.ndarray:
    """The limits in the order of :data:`_QUANTITIES`."""
    return np.array(_limit_tuple(limits))


def _limit_tuple(limits: ArmLimits) -> tuple[float, ...]:
    """:func:`_limit_vector` as plain floats."""
    (lo1, hi1), (lo2, hi2) = limits.position_rad
    rates = (limits.velocity_rad_s, limits.acceleration_rad_s2, limits.effort_n_m, limits.jerk_rad_s3)
    return tuple(float(v) for v in (hi1, hi2, -lo1, -lo2, *(value for pair in rates for value in pair)))


def _certificate(timed: TimedTrajectory, bound, sampled, intervals: int, limits) -> ExecutionCertificate:
    """The certificate of the bounds (and sampled maxima, None: none) in :data:`_QUANTITIES` order."""

    def angles(v):
        return ((-float(v[2]), float(v[0])), (-float(v[3]), float(v[1])))

    found = {}
    if sampled is not None:
        found = {
            "angle_range_rad": angles(sampled),
            "speed_rad_s": sampled[4:6].copy(),
            "acceleration_rad_s2": sampled[6:8].copy(),
            "torque_n_m": sampled[8:10].copy(),
            "jerk_rad_s3": sampled[10:12].copy(),
        }
    return ExecutionCertificate(
        timing_name=timed.timing.name,
        duration_s=timed.duration_s,
        angle_range_rad=angles(bound),
        speed_bound_rad_s=bound[4:6].copy(),
        acceleration_bound_rad_s2=bound[6:8].copy(),
        torque_bound_n_m=bound[8:10].copy(),
        sampled=found,
        intervals=intervals,
        decided_against=limits,
        jerk_bound_rad_s3=bound[10:12].copy(),
    )


def _initial_partition(timed: TimedTrajectory, tight: bool) -> tuple[np.ndarray, np.ndarray]:
    """The first intervals: the timing's own pieces (one polynomial each); for tight bounds of a
    timing of one piece, :data:`_INITIAL_INTERVALS` equal ones."""
    knots = np.asarray(timed.timing.knots_s, dtype=float)
    if tight and knots.size == 2:
        knots = np.linspace(0.0, timed.duration_s, _INITIAL_INTERVALS + 1)
    return knots[:-1], knots[1:]


def certify_execution(
    timed: TimedTrajectory | TimedPathBox,
    dynamics: PlanarDynamics,
    limits: ArmLimits | None = None,
    relative_tolerance: float = DEFAULT_RELATIVE_TOLERANCE,
    *,
    compiled: bool = True,
) -> ExecutionCertificate:
    """Bound the angles, speeds, accelerations, torques and jerks of ``timed`` over all of [0, T'].

    Args:
        timed: The trajectory with its timing, or every path of a box under one timing
            (:class:`pipeline.motion.path_box.TimedPathBox`: the NumPy route, its bounds hold for all of them).
        dynamics: The arm's inverse dynamics.
        limits: None: tight bounds (within the tolerance of the maxima); given: only decide
            whether each quantity stays within its limit (module docstring), the fastest question.
        relative_tolerance: Bisect while a bound exceeds the sampled maximum by more than this
            fraction of it (of 1e-3 for maxima below that).
        compiled: For a smooth timing, run the same algorithm compiled
            (:mod:`pipeline.motion.certificate_kernel`, equal to rounding); False: the NumPy route.
    """
    limit = None if limits is None else _limit_vector(limits)
    if limit is not None and isinstance(timed.timing, PaperTiming | RestToRestTiming):
        coarse = _closed_form(timed, dynamics, limits)
        if coarse is not None:
            return coarse
    if isinstance(timed, TimedTrajectory) and isinstance(timed.timing, SmoothTiming) and compiled:
        from pipeline.motion.certificate_kernel import certify_smooth_execution

        mass_terms = np.array([dynamics.m0, dynamics.mc, dynamics.ms], dtype=float)
        bound, sampled, total = certify_smooth_execution(
            timed.parameters, timed.timing, mass_terms, limit, relative_tolerance, _MAX_INTERVALS, _MAX_ROUNDS
        )
        return _certificate(timed, bound, sampled, total, limits)
    lo, hi = _initial_partition(timed, limit is None)
    sampled = _values(timed, dynamics, np.concatenate([lo, hi[-1:]])).max(0)
    bound = np.full(len(_QUANTITIES), -np.inf)
    total = 0
    for _ in range(_MAX_ROUNDS):
        upper = _upper_bounds(timed, dynamics, lo, hi)
        tolerance = relative_tolerance * np.maximum(np.abs(sampled), 1e-3)
        loose = upper > sampled + tolerance
        if limit is not None:  # decide: open only where the limit is in question
            loose &= (upper > limit) & (sampled <= limit)
        open_ = np.any(loose, axis=1)
        done = ~open_
        if np.any(done):
            bound = np.maximum(bound, upper[done].max(0))
        total += int(done.sum())
        if not np.any(open_) or 2 * int(open_.sum()) + total > _MAX_INTERVALS:
            if np.any(open_):
                bound = np.maximum(bound, upper[open_].max(0))
                total += int(open_.sum())
            break
        mid = 0.5 * (lo[open_] + hi[open_])
        sampled = np.maximum(sampled, _values(timed, dynamics, mid).max(0))
        lo, hi = np.concatenate([lo[open_], mid]), np.concatenate([mid, hi[open_]])
    else:
        bound = np.maximum(bound, _upper_bounds(timed, dynamics, lo, hi).max(0))
        total += lo.size
    return _certificate(timed, bound, sampled, total, limits)
