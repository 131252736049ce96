"""What the verifier measured on one case, as typed parts.

A :class:`CaseResult` is the case (index, obstacle size, extrapolated or not), its
:class:`Verdict` (failed checks in words, or the error that kept it from being generated), and,
when the trajectory could be generated, its :class:`Measurement`: duration and parameters, the
:class:`Clearance` (sampled, and the :class:`CertifiedClearance` when the certificate ran), the
:class:`EndpointErrors`, the :class:`Tracking` errors and the :class:`JointCheck` against the
URDF (with the :class:`RestToRestCheck` of the rest-to-rest timing). Lengths in m, times in s,
angles in rad.

``CaseResult.to_json`` writes the flat document the sweep's ``--json`` has always written
(``"L"``, ``"W"``, ``"T_s"``, ``"clearance_m"``, ...); the viewer reads that form.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from pipeline.exceptions import InvalidParameterError
from pipeline.validation import check_finite, check_non_negative, check_positive, check_positive_int

Pair = tuple[float, float]

#: The limited joint quantities whose room is reported: name, unit.
JOINT_QUANTITIES: tuple[tuple[str, str], ...] = (("speed", "rad/s"), ("acceleration", "rad/s^2"), ("torque", "N m"))
#: |dq|, |ddq| at both ends of a rest-to-rest timing must be at most this [rad/s, rad/s^2].
AT_REST_TOLERANCE = 1e-12


def _room(limits: Pair, bounds: Pair) -> Pair:
    """limit - bound per joint (inf where the limit is)."""
    a, b = (math.inf if math.isinf(lim) else lim - bound for lim, bound in zip(limits, bounds, strict=True))
    return a, b


@dataclass(frozen=True)
class CertifiedClearance:
    """The continuous-time certificate of one trajectory.

    Attributes:
        certified_clearance_m: Rigorous lower bound of the clearance over [0, T] [m].
        link_clearance_m: The bound per link [m].
        time_s: Where the bound is attained [s].
        link: The link attaining it (1 or 2).
        evaluations: Clearance evaluations the certificate used.
        converged: Whether the refinement reached its tolerance.
        collision_free: The bound is > 0.
        keeps_margin: The bound is >= the safety margin of the thresholds.
        tight: The bound is within the certificate's tolerance of the sampled minimum (tolerance
            mode); False where the certificate only decided that the clearance keeps the margin
            (the bound is then >= the margin but may lie well below the true minimum).
    """

    certified_clearance_m: float
    link_clearance_m: Pair
    time_s: float
    link: int
    evaluations: int
    converged: bool
    collision_free: bool
    keeps_margin: bool
    tight: bool = True

    def __post_init__(self) -> None:
        check_finite("certified_clearance_m", self.certified_clearance_m)
        check_positive_int("evaluations", self.evaluations, minimum=0)


@dataclass(frozen=True)
class Clearance:
    """Link-obstacle clearance of one trajectory.

    Attributes:
        sampled_m: Minimum over the time samples (Coal's exact distance) [m]: the certificate's
            samples when it was computed, else uniform samples.
        sampled_link_m: The minimum per link [m] (with the certificate: over its initial grid).
        sampled_time_s: Where the sampled minimum is [s].
        time_samples: Number of time samples over [0, T] (the certificate's clearance evaluations
            when it was computed, else uniform samples).
        certified: The certificate, or None if it was not computed.
    """

    sampled_m: float
    sampled_link_m: Pair
    sampled_time_s: float
    time_samples: int
    certified: CertifiedClearance | None

    def __post_init__(self) -> None:
        check_finite("sampled_m", self.sampled_m)
        check_positive_int("time_samples", self.time_samples, minimum=2)
        if self.certified is not None and self.certified.certified_clearance_m > self.sampled_m:
            raise InvalidParameterError(
                "certified_clearance_m", self.certified.certified_clearance_m, "<= the sampled clearance"
            )


@dataclass(frozen=True)
class EndpointErrors:
    """Distance of the end effector from P1 at t = 0 and from P5 at t = T [m]."""

    start_m: float
    end_m: float

    def __post_init__(self) -> None:
        check_non_negative("start_m", self.start_m)
        check_non_negative("end_m", self.end_m)

    @property
    def max_m(self) -> float:
        """The larger of the two [m]."""
        return max(self.start_m, self.end_m)


@dataclass(frozen=True)
class Tracking:
    """Distance between the end effector and the desired path at matched times (t = S / v) [m]."""

    max_m: float
    rms_m: float

    def __post_init__(self) -> None:
        check_non_negative("max_m", self.max_m)
        check_non_negative("rms_m", self.rms_m)


@dataclass(frozen=True)
class JointCheck:
    """Closed-form joint peaks and ranges against the limits.

    Attributes:
        peak_velocity_rad_s, peak_acceleration_rad_s2: max |dtheta/dt| [rad/s], |d2theta/dt2| [rad/s^2] per joint.
        range_rad: (min, max) of each joint angle over [0, T] [rad].
        velocity_limits_rad_s: The URDF's speed limits [rad/s].
        position_limits_rad: The URDF's angle limits [rad].
        acceleration_limits_rad_s2: The thresholds' acceleration limits [rad/s^2] (None: not checked).
        within_velocity_limits, within_position_limits: Whether the peaks / ranges respect them.
        within_acceleration_limits: Likewise; None if there are no acceleration limits.
        torque_bound_n_m: Certified upper bound of |tau_i| over all of [0, T] (paper timing;
            Pinocchio's dynamics in closed form, decided against the effort limits) [N m].
        peak_torque_sampled_n_m: Largest |tau_i| the sampled check found [N m] (a coarse grid,
            refined at its peaks where they come near the bound or the region map's:
            :mod:`verify.acceptance.sampling`); the bound must not lie below it.
        effort_limits_n_m: The URDF's effort limits [N m].
        within_effort_limits: Whether the torque bound respects them.
        rest_to_rest: The shortest rest-to-rest timing within the limits, certified (None if
            there is none: ``rest_to_rest_error`` says why).
        rest_to_rest_error: Why there is no rest-to-rest timing.
    """

    peak_velocity_rad_s: Pair
    peak_acceleration_rad_s2: Pair
    range_rad: tuple[Pair, Pair]
    velocity_limits_rad_s: Pair
    position_limits_rad: tuple[Pair, Pair]
    acceleration_limits_rad_s2: Pair | None
    within_velocity_limits: bool
    within_position_limits: bool
    within_acceleration_limits: bool | None
    torque_bound_n_m: Pair = (math.nan, math.nan)
    peak_torque_sampled_n_m: Pair = (math.nan, math.nan)
    effort_limits_n_m: Pair = (math.inf, math.inf)
    within_effort_limits: bool = True

    rest_to_rest: RestToRestCheck | None = None
    rest_to_rest_error: str | None = None

    @property
    def within_limits(self) -> bool:
        """Speeds, angles, torques and (if limited) accelerations all within their limits."""
        return (
            self.within_velocity_limits
            and self.within_position_limits
            and self.within_acceleration_limits is not False
            and self.within_effort_limits
        )

    @property
    def room(self) -> dict[str, Pair]:
        """Paper timing: limit minus bound per quantity of :data:`JOINT_QUANTITIES` and joint (the
        closed-form peaks for speed and acceleration, the certified bound for torque; inf where
        unlimited) [rad/s, rad/s^2, N m]."""
        acceleration = self.acceleration_limits_rad_s2 or (math.inf, math.inf)
        return {
            "speed": _room(self.velocity_limits_rad_s, self.peak_velocity_rad_s),
            "acceleration": _room(acceleration, self.peak_acceleration_rad_s2),
            "torque": _room(self.effort_limits_n_m, self.torque_bound_n_m),
        }


@dataclass(frozen=True)
class RestToRestCheck:
    """The shortest rest-to-rest timing within the arm's limits, certified over all of [0, T'].

    Attributes:
        path_duration_s: T, the paper timing's duration [s].
        duration_s: T' = T / c + r [s].
        speed_scale: c; ramp_s: r [s].
        speed_bound_rad_s, acceleration_bound_rad_s2, torque_bound_n_m: Certified upper bounds of
            |dq_i|, |ddq_i|, |tau_i| over [0, T'] (decided against the limits).
        sampled_speed_rad_s, sampled_acceleration_rad_s2, sampled_torque_n_m: Their largest values
            at ``samples`` instants: a coarse grid over each ramp and the middle, refined at its
            peaks where they come near the bound (:mod:`verify.acceptance.sampling`) (torques by
            the closed-form dynamics and, at each joint's peak sample, Pinocchio's RNEA; the larger).
        samples: Number of those instants.
        end_speed_rad_s, end_acceleration_rad_s2: Largest |dq_i|, |ddq_i| at tau = 0 and T'.
        velocity_limits_rad_s, acceleration_limits_rad_s2, effort_limits_n_m: The limits (inf: none).
        intervals: Time intervals of the certificate's final partition.
    """

    path_duration_s: float
    duration_s: float
    speed_scale: float
    ramp_s: float
    speed_bound_rad_s: Pair
    acceleration_bound_rad_s2: Pair
    torque_bound_n_m: Pair
    sampled_speed_rad_s: Pair
    sampled_acceleration_rad_s2: Pair
    sampled_torque_n_m: Pair
    samples: int
    end_speed_rad_s: float
    end_acceleration_rad_s2: float
    velocity_limits_rad_s: Pair
    acceleration_limits_rad_s2: Pair
    effort_limits_n_m: Pair
    intervals: int

    def __post_init__(self) -> None:
        check_positive("path_duration_s", self.path_duration_s)
        check_positive("duration_s", self.duration_s)
        check_positive_int("samples", self.samples, minimum=2)

    @property
    def duration_ratio(self) -> float:
        """T' / T."""
        return self.duration_s / self.path_duration_s

    def quantities(self) -> dict[str, tuple[Pair, Pair, Pair]]:
        """(certified bound, sampled maximum, limit) per quantity of :data:`JOINT_QUANTITIES`."""
        return {
            "speed": (self.speed_bound_rad_s, self.sampled_speed_rad_s, self.velocity_limits_rad_s),
            "acceleration": (
                self.acceleration_bound_rad_s2,
                self.sampled_acceleration_rad_s2,
                self.acceleration_limits_rad_s2,
            ),
            "torque": (self.torque_bound_n_m, self.sampled_torque_n_m, self.effort_limits_n_m),
        }

    @property
    def room(self) -> dict[str, Pair]:
        """Limit minus certified bound per quantity and joint (inf where unlimited)."""
        return {name: _room(limit, bound) for name, (bound, _, limit) in self.quantities().items()}

    @property
    def at_rest(self) -> bool:
        """dq and ddq are 0 (to :data:`AT_REST_TOLERANCE`) at both ends."""
        return self.end_speed_rad_s <= AT_REST_TOLERANCE and self.end_acceleration_rad_s2 <= AT_REST_TOLERANCE

    def problems(self) -> list[str]:
        """What is wrong, in words (empty: certified within the limits, consistent with the
        samples, at rest at both ends)."""
        found = []
        for (name, unit), (bound, sampled, limit) in zip(JOINT_QUANTITIES, self.quantities().values(), strict=True):
            if any(b < s for b, s in zip(bound, sampled, strict=True)):
                found.append(
                    f"rest-to-rest certified {name} bound {_text(bound)} {unit} below a sampled {name} {_text(sampled)}"
                )
            if any(b > lim for b, lim in zip(bound, limit, strict=True)):
                found.append(f"rest-to-rest {name} bound {_text(bound)} {unit} exceeds the limits {_text(limit)}")
        if not self.at_rest:
            found.append(
                f"rest-to-rest timing not at rest at its ends: |dq| up to {self.end_speed_rad_s:.3g} rad/s, "
                f"|ddq| up to {self.end_acceleration_rad_s2:.3g} rad/s^2"
            )
        return found

    def to_json(self) -> dict[str, Any]:
        """Plain JSON (infinite limits and room become null)."""
        out: dict[str, Any] = {
            "T_s": self.duration_s,
            "T_ratio": self.duration_ratio,
            "speed_scale": self.speed_scale,
            "ramp_s": self.ramp_s,
        }
        for name in (
            "speed_bound_rad_s",
            "acceleration_bound_rad_s2",
            "torque_bound_n_m",
            "sampled_speed_rad_s",
            "sampled_acceleration_rad_s2",
            "sampled_torque_n_m",
            "samples",
            "end_speed_rad_s",
            "end_acceleration_rad_s2",
            "intervals",
        ):
            out[name] = getattr(self, name)
        out["room"] = dict(zip(("speed_rad_s", "acceleration_rad_s2", "torque_n_m"), self.room.values(), strict=True))
        out["problems"] = self.problems()
        return {key: _jsonable(value) for key, value in out.items()}


def _text(pair: Pair) -> str:
    return "(" + ", ".join(f"{v:.4g}" for v in pair) + ")"


@dataclass(frozen=True)
class Measurement:
    """Everything measured on a generated trajectory.

    Attributes:
        T_s: Duration [s].
        parameters: The eight sinusoid parameters (A1, w1, phi1, gamma1, A2, w2, phi2, gamma2).
    """

    T_s: float
    parameters: tuple[float, ...]
    clearance: Clearance
    endpoints: EndpointErrors
    tracking: Tracking
    joints: JointCheck

    def __post_init__(self) -> None:
        check_positive("T_s", self.T_s)
        if len(self.parameters) != 8:
            raise InvalidParameterError("parameters", self.parameters, "eight sinusoid parameters")


@dataclass(frozen=True)
class Verdict:
    """Acceptance of one case: the failed checks in words, or why it could not be generated.

    ``passed`` is True only if there is no failure and no error.
    """

    failures: tuple[str, ...] = ()
    error: str | None = None

    @property
    def passed(self) -> bool:
        """No failed check and no error."""
        return not self.failures and self.error is None


@dataclass(frozen=True)
class CaseResult:
    """One case of a sweep: the obstacle, what was measured (None if it could not be generated:
    ``verdict.error`` says why), and the verdict.

    Attributes:
        index: Case number (>= 0).
        L_m, W_m: Obstacle size [m].
        extrapolated: (L, W), or an extra variable's value, lies outside the coefficients' fitted range.
        measurement: The measured trajectory, or None.
        verdict: Failed checks or error.
        extra: ((name, value), ...) of the coefficients' scene variables beyond L and W, in their
            canonical order (e.g. (("x", 0.01),): the obstacle's centre x [m]); empty for (L, W).
    """

    index: int
    L_m: float
    W_m: float
    extrapolated: bool
    measurement: Measurement | None
    verdict: Verdict
    extra: tuple[tuple[str, float], ...] = ()

    def __post_init__(self) -> None:
        check_positive_int("index", self.index, minimum=0)
        check_positive("L_m", self.L_m)
        check_positive("W_m", self.W_m)
        if (self.measurement is None) == (self.verdict.error is None):
            raise InvalidParameterError(
                "measurement", self.measurement, "a measurement exactly when the case has no error"
            )
        object.__setattr__(self, "extra", tuple((str(name), float(value)) for name, value in self.extra))

    @property
    def extra_values(self) -> dict[str, float]:
        """The extra variables' values by name [m] (keyword arguments of
        :func:`pipeline.online.generator.generate`); empty for (L, W)."""
        return dict(self.extra)

    @property
    def point(self) -> tuple[float, ...]:
        """(L, W, then the extra variables' values) [m]: the case's point of the fitted box."""
        return (self.L_m, self.W_m, *(value for _, value in self.extra))

    # The few numbers every report reads; the rest is in the parts.

    @property
    def passed(self) -> bool:
        """The case passed every check."""
        return self.verdict.passed

    @property
    def failures(self) -> tuple[str, ...]:
        """Failed checks, in words."""
        return self.verdict.failures

    @property
    def error(self) -> str | None:
        """Why the trajectory could not be generated (None if it was)."""
        return self.verdict.error

    @property
    def certificate(self) -> CertifiedClearance | None:
        """The certificate, if the case was measured with one."""
        return None if self.measurement is None else self.measurement.clearance.certified

    @property
    def clearance_m(self) -> float | None:
        """Sampled minimum clearance [m]."""
        return None if self.measurement is None else self.measurement.clearance.sampled_m

    @property
    def certified_clearance_m(self) -> float | None:
        """Certified clearance [m]."""
        return None if self.certificate is None else self.certificate.certified_clearance_m

    @property
    def endpoint_error_m(self) -> float | None:
        """The larger endpoint error [m]."""
        return None if self.measurement is None else self.measurement.endpoints.max_m

    @property
    def tracking_max_m(self) -> float | None:
        """Max tracking error [m]."""
        return None if self.measurement is None else self.measurement.tracking.max_m

    def to_json(self) -> dict[str, Any]:
        """The flat JSON form ("L", "W", the extra variables by name (e.g. "x"), "T_s",
        "clearance_m", ...); non-finite numbers become null."""
        m, c = self.measurement, self.certificate
        clearance = None if m is None else m.clearance
        joints = None if m is None else m.joints
        out: dict[str, Any] = {
            "index": self.index,
            "L": self.L_m,
            "W": self.W_m,
            **self.extra_values,
            "extrapolated": self.extrapolated,
            "passed": self.passed,
            "failures": list(self.failures),
            "error": self.error,
            "T_s": None if m is None else m.T_s,
            "parameters": None if m is None else m.parameters,
            "time_samples": None if clearance is None else clearance.time_samples,
            "clearance_m": self.clearance_m,
            "clearance_link_m": None if clearance is None else clearance.sampled_link_m,
            "clearance_time_s": None if clearance is None else clearance.sampled_time_s,
            "certified_clearance_m": self.certified_clearance_m,
            "certified_link_clearance_m": None if c is None else c.link_clearance_m,
            "certified_time_s": None if c is None else c.time_s,
            "certified_link": None if c is None else c.link,
            "certificate_evaluations": None if c is None else c.evaluations,
            "certificate_converged": None if c is None else c.converged,
            "collision_free": None if c is None else c.collision_free,
            "keeps_margin": None if c is None else c.keeps_margin,
            "endpoint_error_start_m": None if m is None else m.endpoints.start_m,
            "endpoint_error_end_m": None if m is None else m.endpoints.end_m,
            "tracking_max_m": None if m is None else m.tracking.max_m,
            "tracking_rms_m": None if m is None else m.tracking.rms_m,
        }
        for name in (
            "peak_velocity_rad_s",
            "peak_acceleration_rad_s2",
            "velocity_limits_rad_s",
            "acceleration_limits_rad_s2",
            "torque_bound_n_m",
            "peak_torque_sampled_n_m",
            "effort_limits_n_m",
        ):
            out[name] = None if joints is None else getattr(joints, name)
        out["joint_range_rad"] = None if joints is None else joints.range_rad
        out["position_limits_rad"] = None if joints is None else joints.position_limits_rad
        for name in (
            "within_velocity_limits",
            "within_acceleration_limits",
            "within_position_limits",
            "within_effort_limits",
        ):
            out[name] = None if joints is None else getattr(joints, name)
        out["endpoint_error_m"] = self.endpoint_error_m
        rest = None if joints is None else joints.rest_to_rest
        out["rest_to_rest"] = None if rest is None else rest.to_json()
        out["rest_to_rest_error"] = None if joints is None else joints.rest_to_rest_error
        return {key: _jsonable(value) for key, value in out.items()}


def failed_case(
    index: int,
    L_m: float,
    W_m: float,
    extrapolated: bool,
    error: str,
    extra: tuple[tuple[str, float], ...] = (),
) -> CaseResult:
    """A case whose trajectory could not be generated (``error`` says why): it fails. ``extra``:
    the extra variables' values, as in :class:`CaseResult`."""
    return CaseResult(index, L_m, W_m, extrapolated, None, Verdict(error=error), extra)


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {key: _jsonable(v) for key, v in value.items()}
    if isinstance(value, tuple | list):
        return [_jsonable(v) for v in value]
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value
