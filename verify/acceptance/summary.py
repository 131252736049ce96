"""A sweep's aggregate numbers as one frozen record: counts, statistics of each per-case quantity,
joint peaks, the least room to the joint limits of the paper and the rest-to-rest timings,
certificate effort, and the worst and failing cases. Every length in m."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from pipeline.exceptions import InvalidParameterError
from pipeline.validation import check_non_negative, check_positive_int

from .metrics import AcceptanceThresholds
from .results import JOINT_QUANTITIES, CaseResult, Pair

#: How many worst cases (by clearance, by endpoint error) a summary keeps.
DEFAULT_WORST = 5


@dataclass(frozen=True)
class Stats:
    """Statistics of one per-case quantity over the measured cases (None when no case has it)."""

    min: float | None = None
    median: float | None = None
    p99: float | None = None
    max: float | None = None

    @classmethod
    def of(cls, values: Sequence[float]) -> Stats:
        """min, median, 99th percentile and max of ``values`` (all None if empty)."""
        if not values:
            return cls()
        array = np.asarray(values, dtype=float)
        return cls(float(np.min(array)), float(np.median(array)), float(np.percentile(array, 99)), float(np.max(array)))


@dataclass(frozen=True)
class SweepSummary:
    """Aggregate statistics of a sweep; deterministic given the cases.

    Attributes:
        n_cases, n_passed: Cases judged, and passing every check.
        n_errors: Cases whose trajectory could not be generated.
        n_extrapolated: Cases outside the coefficients' fitted range.
        n_certified_collision_free: Cases whose certified clearance is > 0.
        margin_m: The safety margin of the thresholds [m].
        n_keep_margin: Cases whose certified clearance is >= ``margin_m``.
        n_within_joint_limits: Measured cases whose joint speeds, angles (and accelerations) are within limits.
        certified_clearance, sampled_clearance, endpoint_error, tracking_max, tracking_rms: Statistics [m].
        peak_velocity_max_rad_s, peak_acceleration_max_rad_s2: Largest joint peaks over the cases, per joint.
        torque_bound_max_n_m: Largest certified torque bound over the cases, per joint [N m].
        least_room: Per timing ("paper", "rest_to_rest"), per quantity of
            :data:`verify.acceptance.results.JOINT_QUANTITIES`, the least limit minus bound over
            the cases, per joint [rad/s, rad/s^2, N m] (inf: unlimited; None: no case).
        n_rest_to_rest: Cases with a rest-to-rest timing within the limits.
        n_rest_to_rest_passed: Those certified within the limits, the bounds >= their samples,
            at rest at both ends.
        rest_to_rest_ratio_max: Largest T' / T (None: no case).
        time_samples_range: (fewest, most) time samples of a case.
        certificate_evaluations_total: Clearance evaluations of every certificate together.
        n_certificate_not_converged: Certificates that stopped before their tolerance.
        worst_clearance: The cases of lowest certified clearance, lowest first.
        worst_endpoint_error: The cases of largest endpoint error, largest first.
        failing: Every failing case, in case order.
    """

    n_cases: int
    n_passed: int
    n_errors: int
    n_extrapolated: int
    n_certified_collision_free: int
    margin_m: float
    n_keep_margin: int
    n_within_joint_limits: int
    certified_clearance: Stats
    sampled_clearance: Stats
    endpoint_error: Stats
    tracking_max: Stats
    tracking_rms: Stats
    peak_velocity_max_rad_s: Pair | None
    peak_acceleration_max_rad_s2: Pair | None
    torque_bound_max_n_m: Pair | None
    least_room: dict[str, dict[str, Pair | None]]
    n_rest_to_rest: int
    n_rest_to_rest_passed: int
    rest_to_rest_ratio_max: float | None
    time_samples_range: tuple[int, int] | None
    certificate_evaluations_total: int
    n_certificate_not_converged: int
    worst_clearance: tuple[CaseResult, ...]
    worst_endpoint_error: tuple[CaseResult, ...]
    failing: tuple[CaseResult, ...]

    def __post_init__(self) -> None:
        check_positive_int("n_cases", self.n_cases, minimum=0)
        check_non_negative("margin_m", self.margin_m)
        if not 0 <= self.n_passed <= self.n_cases:
            raise InvalidParameterError("n_passed", self.n_passed, f"between 0 and n_cases = {self.n_cases}")

    @property
    def all_passed(self) -> bool:
        """Every case passed."""
        return self.n_passed == self.n_cases

    @property
    def n_failed(self) -> int:
        """Cases that failed a check or could not be generated."""
        return self.n_cases - self.n_passed

    @property
    def pass_rate(self) -> float | None:
        """Fraction of the cases that passed (None without cases)."""
        return self.n_passed / self.n_cases if self.n_cases else None

    @property
    def keep_margin_fraction(self) -> float | None:
        """Fraction of the cases that keep the margin (None without cases)."""
        return self.n_keep_margin / self.n_cases if self.n_cases else None

    def to_json(self) -> dict[str, Any]:
        """The flat "summary" document of the sweep's --json."""
        samples = self.time_samples_range
        return {
            "all_passed": self.all_passed,
            "n_cases": self.n_cases,
            "n_passed": self.n_passed,
            "n_failed": self.n_failed,
            "pass_rate": self.pass_rate,
            "n_errors": self.n_errors,
            "n_extrapolated": self.n_extrapolated,
            "n_certified_collision_free": self.n_certified_collision_free,
            "margin_m": self.margin_m,
            "n_keep_margin": self.n_keep_margin,
            "keep_margin_fraction": self.keep_margin_fraction,
            "certified_clearance_min_m": self.certified_clearance.min,
            "certified_clearance_median_m": self.certified_clearance.median,
            "clearance_min_m": self.sampled_clearance.min,
            "clearance_median_m": self.sampled_clearance.median,
            "endpoint_error_median_m": self.endpoint_error.median,
            "endpoint_error_p99_m": self.endpoint_error.p99,
            "endpoint_error_max_m": self.endpoint_error.max,
            "tracking_max_m": self.tracking_max.max,
            "tracking_max_median_m": self.tracking_max.median,
            "tracking_rms_median_m": self.tracking_rms.median,
            "tracking_rms_max_m": self.tracking_rms.max,
            "peak_velocity_max_rad_s": _list(self.peak_velocity_max_rad_s),
            "peak_acceleration_max_rad_s2": _list(self.peak_acceleration_max_rad_s2),
            "torque_bound_max_n_m": _list(self.torque_bound_max_n_m),
            "n_within_joint_limits": self.n_within_joint_limits,
            "least_room": {
                timing: {f"{name}_{unit}": _list(room[name]) for name, unit in _ROOM_KEYS}
                for timing, room in self.least_room.items()
            },
            "n_rest_to_rest": self.n_rest_to_rest,
            "n_rest_to_rest_passed": self.n_rest_to_rest_passed,
            "rest_to_rest_ratio_max": self.rest_to_rest_ratio_max,
            "time_samples_min": None if samples is None else samples[0],
            "time_samples_max": None if samples is None else samples[1],
            "certificate_evaluations_total": self.certificate_evaluations_total,
            "n_certificate_not_converged": self.n_certificate_not_converged,
            "worst_clearance": [brief(c) for c in self.worst_clearance],
            "worst_endpoint_error": [brief(c) for c in self.worst_endpoint_error],
            "failing": [brief(c) for c in self.failing],
        }


#: The least-room keys of the JSON: quantity and unit.
_ROOM_KEYS = (("speed", "rad_s"), ("acceleration", "rad_s2"), ("torque", "n_m"))


def _list(pair: Pair | None) -> list[float | None] | None:
    """The pair as a JSON list (non-finite values become None)."""
    return None if pair is None else [float(v) if np.isfinite(v) else None for v in pair]


def brief(case: CaseResult) -> dict[str, Any]:
    """The few numbers of a case that a summary lists."""
    return {
        "index": case.index,
        "L": case.L_m,
        "W": case.W_m,
        **case.extra_values,
        "certified_clearance_m": case.certified_clearance_m,
        "clearance_m": case.clearance_m,
        "endpoint_error_m": case.endpoint_error_m,
        "tracking_max_m": case.tracking_max_m,
        "failures": list(case.failures),
        "error": case.error,
    }


def _values(cases: Sequence[CaseResult], value: Callable[[CaseResult], float | None]) -> list[float]:
    return [v for v in (value(c) for c in cases) if v is not None]


def _least(rooms: list[dict[str, Pair]]) -> dict[str, Pair | None]:
    """Per quantity, the least room over ``rooms`` per joint (None without any)."""
    out: dict[str, Pair | None] = {}
    for name, _ in JOINT_QUANTITIES:
        if rooms:
            least = np.min(np.asarray([room[name] for room in rooms], dtype=float), axis=0)
            out[name] = (float(least[0]), float(least[1]))
        else:
            out[name] = None
    return out


def _peak(pairs: list[Pair]) -> Pair | None:
    if not pairs:
        return None
    top = np.max(np.asarray(pairs, dtype=float), axis=0)
    return float(top[0]), float(top[1])


def summarize(
    cases: Sequence[CaseResult], thresholds: AcceptanceThresholds, worst: int = DEFAULT_WORST
) -> SweepSummary:
    """Aggregate statistics of a sweep (every length in m). Deterministic given the cases."""
    measured = [c.measurement for c in cases if c.measurement is not None]
    with_bound = [c for c in cases if c.certified_clearance_m is not None]
    certificates = [m.clearance.certified for m in measured if m.clearance.certified is not None]
    samples = [m.clearance.time_samples for m in measured]
    rests = [m.joints.rest_to_rest for m in measured if m.joints.rest_to_rest is not None]
    return SweepSummary(
        n_cases=len(cases),
        n_passed=sum(c.passed for c in cases),
        n_errors=len(cases) - len(measured),
        n_extrapolated=sum(c.extrapolated for c in cases),
        n_certified_collision_free=sum(c.collision_free for c in certificates),
        margin_m=thresholds.margin_m,
        n_keep_margin=sum(c.keeps_margin for c in certificates),
        n_within_joint_limits=sum(m.joints.within_limits for m in measured),
        certified_clearance=Stats.of(_values(cases, lambda c: c.certified_clearance_m)),
        sampled_clearance=Stats.of(_values(cases, lambda c: c.clearance_m)),
        endpoint_error=Stats.of([m.endpoints.max_m for m in measured]),
        tracking_max=Stats.of([m.tracking.max_m for m in measured]),
        tracking_rms=Stats.of([m.tracking.rms_m for m in measured]),
        peak_velocity_max_rad_s=_peak([m.joints.peak_velocity_rad_s for m in measured]),
        peak_acceleration_max_rad_s2=_peak([m.joints.peak_acceleration_rad_s2 for m in measured]),
        torque_bound_max_n_m=_peak([m.joints.torque_bound_n_m for m in measured]),
        least_room={
            "paper": _least([m.joints.room for m in measured]),
            "rest_to_rest": _least([r.room for r in rests]),
        },
        n_rest_to_rest=len(rests),
        n_rest_to_rest_passed=sum(not r.problems() for r in rests),
        rest_to_rest_ratio_max=max((r.duration_ratio for r in rests), default=None),
        time_samples_range=(min(samples), max(samples)) if samples else None,
        certificate_evaluations_total=sum(c.evaluations for c in certificates),
        n_certificate_not_converged=sum(not c.converged for c in certificates),
        worst_clearance=tuple(sorted(with_bound, key=lambda c: (c.certified_clearance_m, c.index))[:worst]),
        worst_endpoint_error=tuple(
            sorted((c for c in cases if c.measurement is not None), key=lambda c: (-c.endpoint_error_m, c.index))[
                :worst
            ]
        ),
        failing=tuple(c for c in cases if not c.passed),
    )
