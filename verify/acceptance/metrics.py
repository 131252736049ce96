"""Per-case measurement: one obstacle (L, W), one trajectory, every number the verifier reports.

For one case the verifier measures

* **clearance** [m]: the minimum over ``n`` uniform time samples of the exact distance between
  each link's collision geometry (the URDF through Pinocchio's geometry model) and the rounded
  box (Coal); ``n`` defaults to the number of samples at which no point of either link moves
  more than ``resolution_m`` (1 mm) between two samples;
* **certified clearance** [m]: a rigorous lower bound on the clearance over the whole continuous
  time interval (:mod:`pipeline.geometry.sinusoid_certificate`); the case is collision-free only if it is > 0;
* **endpoint errors** [m]: end effector (Pinocchio frame) against P1 at t = 0 and P5 at t = T;
* **tracking errors** [m]: max and RMS distance between the end effector and the desired path
  at matched times (t = S / v) over the same time samples;
* **joint peaks**: closed-form max |dtheta/dt| [rad/s] and |d2theta/dt2| [rad/s^2], and the
  closed-form range of each joint angle [rad], against the URDF's limits.

The acceptance thresholds are :class:`AcceptanceThresholds`; :class:`CaseResult` says which
failed and why.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from pipeline.exceptions import InvalidParameterError, PipelineError
from pipeline.geometry.clearance import COAL_DISTANCE_ERROR_M, CoalClearance
from pipeline.geometry.link_reach import LinkReach
from pipeline.geometry.motion_certificate import DEFAULT_MAX_EVALUATIONS, DEFAULT_RESOLUTION_M, DEFAULT_TOLERANCE_M
from pipeline.geometry.sinusoid_certificate import certify, samples_for_resolution
from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle
from pipeline.motion.path import QuarticPath
from pipeline.motion.trajectory import JointTrajectory
from pipeline.validation import check_finite, check_non_negative, check_positive, check_positive_int

if TYPE_CHECKING:  # pragma: no cover
    from pipeline.offline.coefficients import Coefficients


@dataclass(frozen=True)
class AcceptanceThresholds:
    """What a case must satisfy to pass.

    Attributes:
        min_certified_clearance_m: The certified clearance must be strictly greater than this [m]
            (default 0: certified collision-free).
        max_endpoint_error_m: Both endpoint errors must be at most this [m] (default 5 mm).
        margin_m: Safety margin whose keeping is reported per case [m] (default 1 cm).
        require_margin: If True, a case must also keep the margin (certified clearance >= margin).
        max_tracking_error_m: If given, the max tracking error must be at most this [m].
        check_joint_limits: If True, joint speeds and angles must stay within the URDF's limits
            (and accelerations within ``acceleration_limits_rad_s2`` if given).
        acceleration_limits_rad_s2: Optional acceleration limits per joint [rad/s^2] (the URDF has none).
    """

    min_certified_clearance_m: float = 0.0
    max_endpoint_error_m: float = 0.005
    margin_m: float = 0.01
    require_margin: bool = False
    max_tracking_error_m: float | None = None
    check_joint_limits: bool = True
    acceleration_limits_rad_s2: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        check_finite("min_certified_clearance_m", self.min_certified_clearance_m)
        check_non_negative("max_endpoint_error_m", self.max_endpoint_error_m)
        check_non_negative("margin_m", self.margin_m)
        if self.max_tracking_error_m is not None:
            check_non_negative("max_tracking_error_m", self.max_tracking_error_m)
        if self.acceleration_limits_rad_s2 is not None:
            limits = tuple(float(v) for v in self.acceleration_limits_rad_s2)
            if len(limits) != 2:
                raise InvalidParameterError("acceleration_limits_rad_s2", limits, "two values (joint 1, joint 2)")
            for value in limits:
                check_positive("acceleration_limits_rad_s2", value)
            object.__setattr__(self, "acceleration_limits_rad_s2", limits)


@dataclass(frozen=True)
class MeasureSettings:
    """How a case is measured.

    Attributes:
        resolution_m: Default time sampling: no link point moves more than this between samples [m].
        time_samples: Number of uniform time samples over [0, T]; None means from ``resolution_m``.
        certify: Compute the continuous-time certificate (without it no case can pass).
        tolerance_m: Certificate refinement tolerance [m].
        max_evaluations: Certificate refinement budget (configurations) per case.
        thresholds: The acceptance thresholds.
    """

    resolution_m: float = DEFAULT_RESOLUTION_M
    time_samples: int | None = None
    certify: bool = True
    tolerance_m: float = DEFAULT_TOLERANCE_M
    max_evaluations: int = DEFAULT_MAX_EVALUATIONS
    thresholds: AcceptanceThresholds = field(default_factory=AcceptanceThresholds)

    def __post_init__(self) -> None:
        check_positive("resolution_m", self.resolution_m)
        if self.time_samples is not None:
            check_positive_int("time_samples", self.time_samples, minimum=2)
        check_positive("tolerance_m", self.tolerance_m)
        check_positive_int("max_evaluations", self.max_evaluations, minimum=0)

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form (for provenance)."""
        return {
            "resolution_m": self.resolution_m,
            "time_samples": self.time_samples,
            "certify": self.certify,
            "tolerance_m": self.tolerance_m,
            "max_evaluations": self.max_evaluations,
            "coal_distance_error_m": COAL_DISTANCE_ERROR_M,
            "thresholds": {
                "min_certified_clearance_m": self.thresholds.min_certified_clearance_m,
                "max_endpoint_error_m": self.thresholds.max_endpoint_error_m,
                "margin_m": self.thresholds.margin_m,
                "require_margin": self.thresholds.require_margin,
                "max_tracking_error_m": self.thresholds.max_tracking_error_m,
                "check_joint_limits": self.thresholds.check_joint_limits,
                "acceleration_limits_rad_s2": self.thresholds.acceleration_limits_rad_s2,
            },
        }


Pair = tuple[float, float]


@dataclass(frozen=True)
class CaseResult:
    """Everything measured on one case. Lengths in m, times in s, angles in rad.

    Fields that could not be measured (the trajectory could not be generated: ``error`` says
    why) are None. ``failures`` lists every failed acceptance check in words; ``passed`` is
    True only if there is none and no error.
    """

    index: int
    L_m: float
    W_m: float
    extrapolated: bool
    passed: bool
    failures: tuple[str, ...] = ()
    error: str | None = None
    T_s: float | None = None
    parameters: tuple[float, ...] | None = None
    time_samples: int | None = None
    clearance_m: float | None = None
    clearance_link_m: Pair | None = None
    clearance_time_s: float | None = None
    certified_clearance_m: float | None = None
    certified_link_clearance_m: Pair | None = None
    certified_time_s: float | None = None
    certified_link: int | None = None
    certificate_evaluations: int | None = None
    certificate_converged: bool | None = None
    collision_free: bool | None = None
    keeps_margin: bool | None = None
    endpoint_error_start_m: float | None = None
    endpoint_error_end_m: float | None = None
    tracking_max_m: float | None = None
    tracking_rms_m: float | None = None
    peak_velocity_rad_s: Pair | None = None
    peak_acceleration_rad_s2: Pair | None = None
    velocity_limits_rad_s: Pair | None = None
    acceleration_limits_rad_s2: Pair | None = None
    joint_range_rad: tuple[Pair, Pair] | None = None
    position_limits_rad: tuple[Pair, Pair] | None = None
    within_velocity_limits: bool | None = None
    within_acceleration_limits: bool | None = None
    within_position_limits: bool | None = None

    def __post_init__(self) -> None:
        check_positive_int("index", self.index, minimum=0)
        check_positive("L_m", self.L_m)
        check_positive("W_m", self.W_m)
        if self.passed and (self.failures or self.error is not None):
            raise InvalidParameterError("passed", self.passed, "False when there are failures or an error")
        if not self.passed and not (self.failures or self.error is not None):
            raise InvalidParameterError("passed", self.passed, "True when there is no failure and no error")
        if self.error is None and self.T_s is None:
            raise InvalidParameterError("T_s", None, "a duration when the case was measured")
        for name in ("clearance_m", "certified_clearance_m", "endpoint_error_start_m", "endpoint_error_end_m"):
            value = getattr(self, name)
            if value is not None:
                check_finite(name, value)
        if self.certified_clearance_m is not None and self.clearance_m is not None:
            if self.certified_clearance_m > self.clearance_m:
                raise InvalidParameterError(
                    "certified_clearance_m", self.certified_clearance_m, "<= the sampled clearance_m"
                )

    @property
    def endpoint_error_m(self) -> float | None:
        """The larger of the two endpoint errors [m]."""
        if self.endpoint_error_start_m is None or self.endpoint_error_end_m is None:
            return None
        return max(self.endpoint_error_start_m, self.endpoint_error_end_m)

    def to_json(self) -> dict[str, Any]:
        """JSON form with the issue's keys ("L", "W", "T_s", ...); non-finite numbers become null."""
        out: dict[str, Any] = {"index": self.index, "L": self.L_m, "W": self.W_m}
        for name in self.__dataclass_fields__:
            if name in ("index", "L_m", "W_m"):
                continue
            out[name] = _jsonable(getattr(self, name))
        out["endpoint_error_m"] = _jsonable(self.endpoint_error_m)
        return out


def _jsonable(value: Any) -> Any:
    if isinstance(value, tuple | list):
        return [_jsonable(v) for v in value]
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


def _sin_range(lo: float, hi: float) -> tuple[float, float]:
    """(min, max) of sin(u) over u in [lo, hi], closed form."""
    top = 1.0 if math.ceil((lo - math.pi / 2) / (2 * math.pi)) * 2 * math.pi + math.pi / 2 <= hi else None
    bottom = -1.0 if math.ceil((lo + math.pi / 2) / (2 * math.pi)) * 2 * math.pi - math.pi / 2 <= hi else None
    ends = (math.sin(lo), math.sin(hi))
    return (bottom if bottom is not None else min(ends), top if top is not None else max(ends))


def joint_ranges(trajectory: JointTrajectory) -> tuple[Pair, Pair]:
    """Closed-form (min, max) of each joint angle over [0, T] [rad]."""
    p = trajectory.parameters
    out = []
    for i in (0, 1):
        amplitude, w, phi, gamma = p[4 * i : 4 * i + 4]
        lo, hi = sorted((phi, w * trajectory.duration_s + phi))
        s_min, s_max = _sin_range(lo, hi)
        values = (gamma + amplitude * s_min, gamma + amplitude * s_max)
        out.append((min(values), max(values)))
    return out[0], out[1]


def _pair(values: Any) -> Pair:
    a, b = (float(v) for v in values)
    return a, b


def measure_trajectory(
    trajectory: JointTrajectory,
    path: QuarticPath,
    obstacle: Obstacle,
    arm: PlanarArm,
    settings: MeasureSettings | None = None,
    *,
    index: int = 0,
    extrapolated: bool = False,
    reach: LinkReach | None = None,
) -> CaseResult:
    """Measure one trajectory against its obstacle and desired path.

    Args:
        trajectory: The joint trajectory to judge.
        path: The desired path (its P1, P5 and timing t = S / v).
        obstacle: The rounded box.
        arm: The arm (collision geometry, end-effector frame, joint limits).
        settings: Sampling, certificate and thresholds; default :class:`MeasureSettings`.
        index: Case number (kept in the result).
        extrapolated: Whether (L, W) lies outside the coefficients' fitted range.
        reach: The links' reach for the certificate (computed from ``arm`` if None).

    Returns:
        The :class:`CaseResult`.
    """
    settings = settings or MeasureSettings()
    thresholds = settings.thresholds
    reach = reach or LinkReach.from_arm(arm)
    duration = trajectory.duration_s
    n = settings.time_samples or samples_for_resolution(trajectory, reach, settings.resolution_m)
    coal_route = CoalClearance(arm, obstacle)

    # Clearance: sampled (Coal) and, if asked, certified over the continuous interval.
    times = np.linspace(0.0, duration, n)
    certificate = None
    if settings.certify:
        certificate = certify(
            trajectory,
            coal_route.link_clearance,
            reach,
            samples=n,
            distance_error_m=COAL_DISTANCE_ERROR_M,
            tolerance_m=settings.tolerance_m,
            max_evaluations=settings.max_evaluations,
        )
        sampled_link = certificate.sampled_link_clearance_m
        sampled_time = certificate.sampled_time_s
    else:
        values = coal_route.link_clearance(trajectory.q(times))
        sampled_link = _pair(values.min(axis=0))
        sampled_time = float(times[int(np.argmin(values.min(axis=1)))])
    clearance = min(sampled_link)

    # Endpoints through the URDF's end-effector frame (Pinocchio).
    start = arm.to_plane(arm.end_effector_position(trajectory.q(0.0)))
    end = arm.to_plane(arm.end_effector_position(trajectory.q(duration)))
    error_start = float(np.linalg.norm(start - path.points_m[0]))
    error_end = float(np.linalg.norm(end - path.points_m[-1]))

    # Tracking at matched times.
    actual = arm.end_effector_planar(trajectory.q(times))
    desired = path.position_at_time(times)
    deviation = np.linalg.norm(actual - desired, axis=-1)
    tracking_max = float(np.max(deviation))
    tracking_rms = float(np.sqrt(np.mean(deviation**2)))

    # Joints (closed form).
    peak_velocity = _pair(trajectory.peak_velocity_rad_s())
    peak_acceleration = _pair(trajectory.peak_acceleration_rad_s2())
    ranges = joint_ranges(trajectory)
    velocity_limits = _pair(arm.velocity_limits_rad_s)
    position_limits = (_pair(arm.position_limits_rad[0]), _pair(arm.position_limits_rad[1]))
    within_velocity = all(p <= v for p, v in zip(peak_velocity, velocity_limits, strict=True))
    within_position = all(lim[0] <= r[0] and r[1] <= lim[1] for r, lim in zip(ranges, position_limits, strict=True))
    acceleration_limits = thresholds.acceleration_limits_rad_s2
    within_acceleration = (
        None
        if acceleration_limits is None
        else all(p <= a for p, a in zip(peak_acceleration, acceleration_limits, strict=True))
    )

    # Acceptance.
    failures: list[str] = []
    certified_value = certificate.certified_clearance_m if certificate else None
    if certificate is None:
        failures.append("clearance not certified (certificate disabled)")
        collision_free = None
        keeps_margin = None
    else:
        collision_free = certificate.certified
        keeps_margin = certified_value >= thresholds.margin_m
        if certified_value <= thresholds.min_certified_clearance_m:
            failures.append(
                f"certified clearance {certified_value * 1e3:.3f} mm <= "
                f"{thresholds.min_certified_clearance_m * 1e3:.3f} mm"
                + ("" if collision_free else " (collision not excluded)")
            )
        if thresholds.require_margin and not keeps_margin:
            failures.append(
                f"certified clearance {certified_value * 1e3:.3f} mm < margin {thresholds.margin_m * 1e3:.3f} mm"
            )
    for name, value in (("start", error_start), ("end", error_end)):
        if value > thresholds.max_endpoint_error_m:
            failures.append(
                f"endpoint error at {name} {value * 1e3:.3f} mm > {thresholds.max_endpoint_error_m * 1e3:.3f} mm"
            )
    if thresholds.max_tracking_error_m is not None and tracking_max > thresholds.max_tracking_error_m:
        failures.append(f"tracking error {tracking_max * 1e3:.3f} mm > {thresholds.max_tracking_error_m * 1e3:.3f} mm")
    if thresholds.check_joint_limits:
        if not within_velocity:
            failures.append(f"joint speed peak {peak_velocity} rad/s exceeds the URDF limits {velocity_limits}")
        if not within_position:
            failures.append(f"joint range {ranges} rad leaves the URDF limits {position_limits}")
        if within_acceleration is False:
            failures.append(f"joint acceleration peak {peak_acceleration} rad/s^2 exceeds {acceleration_limits}")

    return CaseResult(
        index=index,
        L_m=float(obstacle.length_m),
        W_m=float(obstacle.width_m),
        extrapolated=bool(extrapolated),
        passed=not failures,
        failures=tuple(failures),
        T_s=float(duration),
        parameters=tuple(trajectory.parameters),
        time_samples=n,
        clearance_m=float(clearance),
        clearance_link_m=sampled_link,
        clearance_time_s=sampled_time,
        certified_clearance_m=certified_value,
        certified_link_clearance_m=certificate.certified_link_clearance_m if certificate else None,
        certified_time_s=certificate.bound_time_s if certificate else None,
        certified_link=certificate.bound_link if certificate else None,
        certificate_evaluations=certificate.evaluations if certificate else None,
        certificate_converged=certificate.converged if certificate else None,
        collision_free=collision_free,
        keeps_margin=keeps_margin,
        endpoint_error_start_m=error_start,
        endpoint_error_end_m=error_end,
        tracking_max_m=tracking_max,
        tracking_rms_m=tracking_rms,
        peak_velocity_rad_s=peak_velocity,
        peak_acceleration_rad_s2=peak_acceleration,
        velocity_limits_rad_s=velocity_limits,
        acceleration_limits_rad_s2=acceleration_limits,
        joint_range_rad=ranges,
        position_limits_rad=position_limits,
        within_velocity_limits=within_velocity,
        within_acceleration_limits=within_acceleration,
        within_position_limits=within_position,
    )


def failed_case(index: int, L_m: float, W_m: float, extrapolated: bool, error: str) -> CaseResult:
    """A case whose trajectory could not be generated (``error`` says why): it fails."""
    return CaseResult(index=index, L_m=L_m, W_m=W_m, extrapolated=extrapolated, passed=False, error=error)


def is_extrapolated(coefficients: Coefficients, L_m: float, W_m: float) -> bool:
    """True if (L, W) lies outside the coefficients' fitted range."""
    fitted = coefficients.fitted_range_m
    return not (fitted["L"][0] <= L_m <= fitted["L"][1] and fitted["W"][0] <= W_m <= fitted["W"][1])


def check_arm_matches(coefficients: Coefficients, arm: PlanarArm, tolerance_m: float = 1e-9) -> None:
    """Raise InvalidParameterError if the coefficients were fitted for other link lengths than ``arm``'s."""
    expected = getattr(coefficients, "link_lengths_m", None)
    if expected is None:
        return
    if any(abs(float(a) - float(b)) > tolerance_m for a, b in zip(expected, arm.link_lengths_m, strict=True)):
        raise InvalidParameterError(
            "coefficients link_lengths_m",
            tuple(float(v) for v in expected),
            f"the URDF's link lengths {tuple(round(v, 9) for v in arm.link_lengths_m)} m ({arm.urdf_path})",
        )


def measure_case(
    coefficients: Coefficients,
    L_m: float,
    W_m: float,
    arm: PlanarArm,
    settings: MeasureSettings | None = None,
    *,
    index: int = 0,
    reach: LinkReach | None = None,
) -> CaseResult:
    """Generate the trajectory for (L, W) as an online user would, then measure it.

    Extrapolation is allowed (and reported in ``extrapolated``). A case whose trajectory cannot
    be generated (e.g. the arm cannot reach the constraint points) is returned as failed with
    ``error`` set; it does not raise. The generator uses the link lengths stored in the
    coefficients; :func:`check_arm_matches` tells whether they are ``arm``'s.
    """
    from pipeline.online.generator import generate

    try:
        generated = generate(coefficients, L_m, W_m, out_of_range="ignore")
    except PipelineError as exc:
        return failed_case(index, L_m, W_m, is_extrapolated(coefficients, L_m, W_m), f"{type(exc).__name__}: {exc}")
    return measure_trajectory(
        generated.trajectory,
        generated.path,
        generated.obstacle,
        arm,
        settings,
        index=index,
        extrapolated=bool(generated.extrapolated),
        reach=reach,
    )
