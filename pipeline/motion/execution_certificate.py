"""Certificate that a timed joint trajectory respects the arm's limits over all of [0, T'].

For ``q(tau) = theta(sigma(tau))`` (:mod:`pipeline.motion.timing`) it proves rigorous upper bounds,
over the whole executed interval (continuous time, not samples), on: the joint angles' range,
|dq_i|, |ddq_i| and the joint torques |tau_i| of the arm's inverse dynamics
(:class:`pipeline.model.dynamics.PlanarDynamics`, identified from Pinocchio's RNEA).

**Enclosures over a time interval [a, b].**

* sigma is non-decreasing, so sigma([a, b]) = [sigma(a), sigma(b)]; sigma' and sigma'' are
  piecewise polynomials whose extremes over [a, b] lie at a, b or at the timing's knots
  (:meth:`pipeline.motion.timing.Timing.ranges`): their ranges are exact.
* theta_i = A sin(w s + phi) + gamma over s in [sigma(a), sigma(b)]: the range of sin over the
  phase interval is exact (its ends, and -1 / +1 where the interval holds -pi/2 / pi/2 modulo
  2 pi); likewise theta_i' = A w cos(.) and theta_i'' = -A w^2 sin(.).
* dq = theta' sigma', ddq = theta'' sigma'^2 + theta' sigma'', and the torques
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
  beyond it proves the violation) and the tolerance allows, starting from the whole of [0, T']
  as one interval. A coarser question is asked first, in closed form: the exact maxima V_i of
  |theta_i'| and A_i of |theta_i''| and the exact angle ranges of the sinusoids over [0, T]
  (:meth:`pipeline.motion.trajectory.JointTrajectory.peak_velocity_rad_s` and the like) give, for
  the paper timing, |dq_i| <= V_i and |ddq_i| <= A_i, and for a rest-to-rest timing (sigma' <= c,
  |sigma''| <= 1.5 c / r) |dq_i| <= c V_i and |ddq_i| <= c^2 A_i + 1.5 c V_i / r; the torque
  bound is ``sum_j Mmax_ij max|ddq_j| + Hmax c^2 Q_i`` with the suprema over q2 of |M_ij| and
  |h| (Q_1 = 2 V_1 V_2 + V_2^2, Q_2 = V_1^2). If these keep every limit, nothing else runs.

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
from dataclasses import dataclass

import numpy as np

from pipeline.model.dynamics import PlanarDynamics
from pipeline.model.limits import ArmLimits
from pipeline.motion.timed_trajectory import TimedTrajectory
from pipeline.motion.timing import PaperTiming, RestToRestTiming

__all__ = [
    "FLOAT_SLACK_ABSOLUTE",
    "FLOAT_SLACK_RELATIVE",
    "ExecutionCertificate",
    "LimitViolation",
    "certify_execution",
]

#: Widening of every enclosure for floating-point rounding (module docstring).
FLOAT_SLACK_RELATIVE = 1e-10
FLOAT_SLACK_ABSOLUTE = 1e-12
#: Default tolerance of the bounds: an interval is bisected while its enclosure exceeds the
#: sampled maximum by more than this fraction of it (or of 1e-3 in the quantity's unit).
DEFAULT_RELATIVE_TOLERANCE = 1e-4
_INITIAL_INTERVALS = 32
_MAX_INTERVALS = 200_000
_MAX_ROUNDS = 40
_TWO_PI = 2.0 * math.pi
#: The certified quantities, in column order: the maxima of q1, q2, -q1, -q2, |dq|, |ddq|, |tau|.
_QUANTITIES = ("q1 max", "q2 max", "-q1 min", "-q2 min", "dq1", "dq2", "ddq1", "ddq2", "tau1", "tau2")


def _sin_range(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact (min, max) of sin over [lo, hi] (elementwise, lo <= hi)."""
    top = np.ceil((lo - math.pi / 2) / _TWO_PI) * _TWO_PI + math.pi / 2 <= hi
    bottom = np.ceil((lo + math.pi / 2) / _TWO_PI) * _TWO_PI - math.pi / 2 <= hi
    s_lo, s_hi = np.sin(lo), np.sin(hi)
    return np.where(bottom, -1.0, np.minimum(s_lo, s_hi)), np.where(top, 1.0, np.maximum(s_lo, s_hi))


def _scale(k, lo, hi):
    """k [lo, hi] for a scalar or array k."""
    a, b = k * lo, k * hi
    return np.minimum(a, b), np.maximum(a, b)


def _mul(a_lo, a_hi, b_lo, b_hi):
    corners = np.stack([a_lo * b_lo, a_lo * b_hi, a_hi * b_lo, a_hi * b_hi])
    return corners.min(0), corners.max(0)


def _square(lo, hi):
    low = np.where((lo <= 0.0) & (hi >= 0.0), 0.0, np.minimum(lo * lo, hi * hi))
    return low, np.maximum(lo * lo, hi * hi)


def _affine_trig(k0, kc, ks, c_lo, c_hi, s_lo, s_hi):
    """k0 + kc [cos] + ks [sin] as an interval."""
    a_lo, a_hi = _scale(kc, c_lo, c_hi)
    b_lo, b_hi = _scale(ks, s_lo, s_hi)
    return k0 + a_lo + b_lo, k0 + a_hi + b_hi


def _widen(lo, hi):
    slack = FLOAT_SLACK_RELATIVE * np.maximum(np.abs(lo), np.abs(hi)) + FLOAT_SLACK_ABSOLUTE
    return lo - slack, hi + slack


def _upper_bounds(timed: TimedTrajectory, dynamics: PlanarDynamics, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Rigorous upper bounds of the :data:`_QUANTITIES` over each interval [lo_k, hi_k]: (n, 10)."""
    s_lo, s_hi, d1_lo, d1_hi, d2_lo, d2_hi = timed.timing.ranges(lo, hi)
    p = timed.parameters
    theta, speed, accel = [], [], []
    for i in (0, 1):
        amplitude, w, phi, gamma = p[4 * i : 4 * i + 4]
        ph_a, ph_b = w * s_lo + phi, w * s_hi + phi
        ph_lo, ph_hi = np.minimum(ph_a, ph_b), np.maximum(ph_a, ph_b)
        sin_lo, sin_hi = _sin_range(ph_lo, ph_hi)
        cos_lo, cos_hi = _sin_range(ph_lo + math.pi / 2, ph_hi + math.pi / 2)
        t_lo, t_hi = _scale(amplitude, sin_lo, sin_hi)
        theta.append(_widen(t_lo + gamma, t_hi + gamma))
        v = _scale(amplitude * w, cos_lo, cos_hi)
        a = _scale(-amplitude * w * w, sin_lo, sin_hi)
        dq = _mul(*v, d1_lo, d1_hi)
        sq = _square(d1_lo, d1_hi)
        ddq_lo1, ddq_hi1 = _mul(*a, *sq)
        ddq_lo2, ddq_hi2 = _mul(*v, d2_lo, d2_hi)
        speed.append(_widen(*dq))
        accel.append(_widen(ddq_lo1 + ddq_lo2, ddq_hi1 + ddq_hi2))
    q2_lo, q2_hi = theta[1]
    sin2 = _sin_range(q2_lo, q2_hi)
    cos2 = _sin_range(q2_lo + math.pi / 2, q2_hi + math.pi / 2)
    m0, mc, ms = (np.asarray(m) for m in (dynamics.m0, dynamics.mc, dynamics.ms))
    m11 = _affine_trig(m0[0, 0], mc[0, 0], ms[0, 0], *cos2, *sin2)
    m12 = _affine_trig(m0[0, 1], mc[0, 1], ms[0, 1], *cos2, *sin2)
    m22 = _affine_trig(m0[1, 1], mc[1, 1], ms[1, 1], *cos2, *sin2)
    h = _affine_trig(0.0, 0.5 * ms[0, 0], -0.5 * mc[0, 0], *cos2, *sin2)
    (dq1, dq2), (ddq1, ddq2) = speed, accel
    cross = _mul(*dq1, *dq2)
    dq2_sq, dq1_sq = _square(*dq2), _square(*dq1)
    quadratic1 = (2.0 * cross[0] + dq2_sq[0], 2.0 * cross[1] + dq2_sq[1])
    parts1 = [_mul(*m11, *ddq1), _mul(*m12, *ddq2), _mul(*h, *quadratic1)]
    minus_h = (-h[1], -h[0])
    parts2 = [_mul(*m12, *ddq1), _mul(*m22, *ddq2), _mul(*minus_h, *dq1_sq)]
    tau = [_widen(sum(p[0] for p in parts), sum(p[1] for p in parts)) for parts in (parts1, parts2)]

    def magnitude(interval):
        return np.maximum(np.abs(interval[0]), np.abs(interval[1]))

    return np.stack(
        [
            theta[0][1],
            theta[1][1],
            -theta[0][0],
            -theta[1][0],
            magnitude(speed[0]),
            magnitude(speed[1]),
            magnitude(accel[0]),
            magnitude(accel[1]),
            magnitude(tau[0]),
            magnitude(tau[1]),
        ],
        -1,
    )


def _values(timed: TimedTrajectory, dynamics: PlanarDynamics, t: np.ndarray) -> np.ndarray:
    """The :data:`_QUANTITIES` at times ``t`` (exact evaluation): (m, 10)."""
    q, dq, ddq = timed.states(t, outside="clamp")
    tau = dynamics.torque(q, dq, ddq)
    return np.column_stack([q[:, 0], q[:, 1], -q[:, 0], -q[:, 1], *np.abs(dq).T, *np.abs(ddq).T, *np.abs(tau).T])


@dataclass(frozen=True)
class LimitViolation:
    """A certified bound beyond a limit.

    Attributes:
        quantity: "angle", "speed", "acceleration" or "torque".
        joint: 1 or 2.
        bound: The certified bound (for an angle: the extreme angle reached) [rad, rad/s, rad/s^2, N m].
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
            return (
                f"joint {self.joint} angle reaches {self.bound:.4f} {self.unit}, beyond its {side} limit "
                f"{self.limit:.4f} {self.unit} (by {abs(self.bound - self.limit):.4f} {self.unit})"
            )
        return (
            f"joint {self.joint} {self.quantity} up to {self.bound:.4f} {self.unit} > limit {self.limit:.4f} "
            f"{self.unit} (by {self.bound - self.limit:.4f} {self.unit})"
        )


@dataclass(frozen=True, eq=False)
class ExecutionCertificate:
    """Rigorous bounds of a timed trajectory over all of [0, T'] (module docstring).

    Attributes:
        timing_name: "paper" or "rest-to-rest".
        duration_s: T' [s].
        angle_range_rad: ((lo1, hi1), (lo2, hi2)) enclosing every joint angle taken [rad].
        speed_bound_rad_s, acceleration_bound_rad_s2, torque_bound_n_m: (2,) upper bounds of
            |dq_i| [rad/s], |ddq_i| [rad/s^2], |tau_i| [N m].
        sampled: The largest values sampled (values the quantities take), per quantity as the bounds:
            {"speed_rad_s": (2,), "acceleration_rad_s2": (2,), "torque_n_m": (2,), "angle_range_rad": ...}.
        intervals: Time intervals of the final partition (0: decided in closed form).
        decided_against: The limits the bounds were decided against (None: tight bounds).
        source: "query" (this certificate, over this trajectory) or "range" (the bounds of the
            region map's leaf holding the obstacle, proven for every obstacle of the leaf:
            :mod:`pipeline.certify.execution_bounds`; no samples).
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
        ):
            for i in (0, 1):
                if bounds[i] > limit[i]:
                    found.append(LimitViolation(quantity, i + 1, float(bounds[i]), float(limit[i]), unit))
        return found


def _closed_form(timed: TimedTrajectory, dynamics: PlanarDynamics, limits: ArmLimits) -> ExecutionCertificate | None:
    """The bounds in closed form (module docstring), if they keep every limit; else None. For a
    rest-to-rest timing (speed scale c, ramp r: sigma' <= c, |sigma''| <= 1.5 c / r) the speeds
    scale by c, the accelerations are bounded by c^2 max|theta''| + 1.5 c max|theta'| / r, and
    the torques follow from those as for the paper timing (c = 1, no ramp)."""
    trajectory = timed.trajectory
    V, acc = np.asarray(trajectory.peak_velocity_rad_s()), np.asarray(trajectory.peak_acceleration_rad_s2())
    c, ramp_term = 1.0, 0.0
    if isinstance(timed.timing, RestToRestTiming):
        c = timed.timing.speed_scale
        ramp_term = 1.5 * c / timed.timing.ramp_s
    speed, accel = c * V, c * c * acc + ramp_term * V
    (lo1, hi1), (lo2, hi2) = trajectory.angle_ranges_rad()
    quadratic = c * c * np.array([2.0 * V[0] * V[1] + V[1] ** 2, V[0] ** 2])
    torque = dynamics.mass_matrix_sup() @ accel + dynamics.coriolis_sup() * quadratic
    bounds = np.array([hi1, hi2, -lo1, -lo2, *speed, *accel, *torque])
    bounds = bounds + FLOAT_SLACK_RELATIVE * np.abs(bounds) + FLOAT_SLACK_ABSOLUTE
    if np.any(bounds > _limit_vector(limits)):
        return None
    return ExecutionCertificate(
        timing_name=timed.timing.name,
        duration_s=timed.duration_s,
        angle_range_rad=((-float(bounds[2]), float(bounds[0])), (-float(bounds[3]), float(bounds[1]))),
        speed_bound_rad_s=bounds[4:6].copy(),
        acceleration_bound_rad_s2=bounds[6:8].copy(),
        torque_bound_n_m=bounds[8:10].copy(),
        sampled={},
        intervals=0,
        decided_against=limits,
    )


def _limit_vector(limits: ArmLimits) -> np.ndarray:
    """The limits in the order of :data:`_QUANTITIES`."""
    (lo1, hi1), (lo2, hi2) = limits.position_rad
    return np.array([hi1, hi2, -lo1, -lo2, *limits.velocity_rad_s, *limits.acceleration_rad_s2, *limits.effort_n_m])


def certify_execution(
    timed: TimedTrajectory,
    dynamics: PlanarDynamics,
    limits: ArmLimits | None = None,
    relative_tolerance: float = DEFAULT_RELATIVE_TOLERANCE,
) -> ExecutionCertificate:
    """Bound the angles, speeds, accelerations and torques of ``timed`` over all of [0, T'].

    Args:
        timed: The trajectory with its timing.
        dynamics: The arm's inverse dynamics.
        limits: None: tight bounds (within the tolerance of the maxima); given: only decide
            whether each quantity stays within its limit (module docstring), the fastest question.
        relative_tolerance: Bisect while a bound exceeds the sampled maximum by more than this
            fraction of it (of 1e-3 for maxima below that).
    """
    limit = None if limits is None else _limit_vector(limits)
    if limit is not None and isinstance(timed.timing, PaperTiming | RestToRestTiming):
        coarse = _closed_form(timed, dynamics, limits)
        if coarse is not None:
            return coarse
    end = timed.duration_s
    edges = np.linspace(0.0, end, (_INITIAL_INTERVALS if limit is None else 1) + 1)
    lo, hi = edges[:-1], edges[1:]
    sampled = _values(timed, dynamics, edges).max(0)
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
    return ExecutionCertificate(
        timing_name=timed.timing.name,
        duration_s=end,
        angle_range_rad=((-float(bound[2]), float(bound[0])), (-float(bound[3]), float(bound[1]))),
        speed_bound_rad_s=bound[4:6].copy(),
        acceleration_bound_rad_s2=bound[6:8].copy(),
        torque_bound_n_m=bound[8:10].copy(),
        sampled={
            "angle_range_rad": ((-float(sampled[2]), float(sampled[0])), (-float(sampled[3]), float(sampled[1]))),
            "speed_rad_s": sampled[4:6].copy(),
            "acceleration_rad_s2": sampled[6:8].copy(),
            "torque_n_m": sampled[8:10].copy(),
        },
        intervals=total,
        decided_against=limits,
    )
