"""Per-case measurement: one obstacle (L, W), one trajectory, every number the verifier reports.

For one case the verifier measures

* **certified clearance** [m]: a rigorous lower bound on the clearance over the whole continuous
  time interval (:mod:`pipeline.geometry.sinusoid_certificate`, adaptive, Coal); the case is
  collision-free only if it is > 0. By default the certificate only decides whether the margin is
  kept and tightens the bound where it is not (``certificate_mode``);
* **clearance** [m]: the minimum of the exact distance between each link's collision geometry
  (the URDF through Pinocchio's geometry model) and the rounded box (Coal) over the
  certificate's samples (without the certificate: over uniform time samples at which no point of
  either link moves more than ``resolution_m`` between two samples);
* **endpoint errors** [m]: end effector (Pinocchio frame) against P1 at t = 0 and P5 at t = T;
* **tracking errors** [m]: max and RMS distance between the end effector and the desired path
  at matched times (t = S(x) / v) over path points uniform in x, one per ``resolution_m`` of path
  length;
* **joint peaks**: closed-form max |dtheta/dt| [rad/s] and |d2theta/dt2| [rad/s^2], and the
  closed-form range of each joint angle [rad], against the URDF's limits, and a certified bound of
  the torques (paper timing) against the largest sampled torque;
* **rest-to-rest timing**: the shortest rest-to-rest timing within the arm's limits (the URDF's
  and the thresholds' acceleration limits), its T', certified bounds of |dq|, |ddq|, |tau| over
  all of [0, T'] against the largest sampled values, and dq = ddq = 0 at both ends.

The sampled maxima that check the execution certificates are found coarse first and refined
around the coarse grid's highest local maxima (:mod:`verify.acceptance.sampling`), vectorised over
the cases measured together (:func:`measure_trajectories`, :func:`measure_cases`); every case
keeps its own clearance and execution certificates.

The acceptance thresholds are :class:`AcceptanceThresholds`; the result is a
:class:`verify.acceptance.results.CaseResult` made of typed parts, whose verdict says which check
failed and why.
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from pipeline.exceptions import ArmMismatchError, InvalidParameterError, PipelineError
from pipeline.geometry.clearance import COAL_DISTANCE_ERROR_M, CoalClearance
from pipeline.geometry.link_reach import LinkReach
from pipeline.geometry.motion_certificate import (
    DEFAULT_MAX_EVALUATIONS,
    DEFAULT_TOLERANCE_M,
    Certificate,
)
from pipeline.geometry.sinusoid_certificate import certify, samples_for_resolution
from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle
from pipeline.motion.path import QuarticPath
from pipeline.motion.trajectory import JointTrajectory
from pipeline.online.arm_check import check_arm_matches as check_arm_matches_online
from pipeline.online.generator import generate
from pipeline.validation import check_finite, check_non_negative, check_positive, check_positive_int

from .results import (
    CaseResult,
    CertifiedClearance,
    Clearance,
    EndpointErrors,
    JointCheck,
    Measurement,
    Pair,
    RestToRestCheck,
    Tracking,
    Verdict,
    failed_case,
)
from .sampling import (
    PAPER_GRID,
    PAPER_ROOM,
    REST_TO_REST_GRID,
    REST_TO_REST_ROOM,
    path_samples,
    piecewise_grid,
    refined_maxima,
    sinusoid_angles,
    sinusoid_states,
    timed_states,
    uniform_grid,
)

if TYPE_CHECKING:  # pragma: no cover
    from pipeline.model.dynamics import PlanarDynamics
    from pipeline.model.limits import ArmLimits
    from pipeline.motion.timing import RestToRestTiming
    from pipeline.offline.coefficients import Coefficients


#: Default spacing of the tracking error's path samples [m] (on 200 cases of the default build the
#: max tracking error at 2 mm spacing is within 7.6 um of that at 0.1 mm; 1.8 um at 1 mm).
TRACKING_RESOLUTION_M = 2e-3
#: How the sweep certifies: decide the margin and tighten below it, or tighten every case.
CERTIFICATE_MODES: tuple[str, ...] = ("decide", "tight")


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
        resolution_m: Spacing of the tracking error's path samples along the path [m]; without the
            certificate also the motion resolution of the uniform clearance samples (no link point
            moves more than this between two samples).
        time_samples: Number of those samples, instead of from ``resolution_m``.
        certify: Compute the continuous-time certificate (without it no case can pass).
        certificate_mode: ``"decide"`` (default): decide whether each case keeps the margin and
            tighten the bound only where it does not; ``"tight"``: every bound within
            ``tolerance_m`` of the sampled minimum (several times slower).
        tolerance_m: Certificate refinement tolerance [m].
        max_evaluations: Certificate refinement budget (configurations) per case.
        thresholds: The acceptance thresholds.
    """

    resolution_m: float = TRACKING_RESOLUTION_M
    time_samples: int | None = None
    certify: bool = True
    certificate_mode: str = "decide"
    tolerance_m: float = DEFAULT_TOLERANCE_M
    max_evaluations: int = DEFAULT_MAX_EVALUATIONS
    thresholds: AcceptanceThresholds = field(default_factory=AcceptanceThresholds)

    def __post_init__(self) -> None:
        check_positive("resolution_m", self.resolution_m)
        if self.time_samples is not None:
            check_positive_int("time_samples", self.time_samples, minimum=2)
        if self.certificate_mode not in CERTIFICATE_MODES:
            raise InvalidParameterError("certificate_mode", self.certificate_mode, f"one of {CERTIFICATE_MODES}")
        check_positive("tolerance_m", self.tolerance_m)
        check_positive_int("max_evaluations", self.max_evaluations, minimum=0)

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form (for provenance)."""
        return {
            "resolution_m": self.resolution_m,
            "time_samples": self.time_samples,
            "certify": self.certify,
            "certificate_mode": self.certificate_mode,
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


def joint_ranges(trajectory: JointTrajectory) -> tuple[Pair, Pair]:
    """Closed-form (min, max) of each joint angle over [0, T] [rad]
    (:meth:`~pipeline.motion.trajectory.JointTrajectory.angle_ranges_rad`)."""
    return trajectory.angle_ranges_rad()


def _pair(values: Any) -> Pair:
    a, b = (float(v) for v in values)
    return a, b


@dataclass(frozen=True)
class Subject:
    """One trajectory to measure, with what placed it.

    Attributes:
        trajectory: The joint trajectory to judge.
        path: The desired path (its P1, P5 and timing t = S / v).
        obstacle: The rounded box.
        index: Case number (kept in the result).
        extrapolated: Whether (L, W) lies outside the coefficients' fitted range.
        extra: The values of the scene variables beyond L and W that placed ``obstacle`` and
            ``path`` ((name, value), ... [m]).
        torque_ceiling_n_m: Another proven upper bound of the paper timing's |tau_i| for this
            case (the region map's, of the leaf holding it) [N m], against which the sampled torque
            is also checked later: the torque samples are refined where they come near it, too
            (None: none).
    """

    trajectory: JointTrajectory
    path: QuarticPath
    obstacle: Obstacle
    index: int = 0
    extrapolated: bool = False
    extra: tuple[tuple[str, float], ...] = ()
    torque_ceiling_n_m: Pair | None = None


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
    extra: tuple[tuple[str, float], ...] = (),
) -> CaseResult:
    """Measure one trajectory against its obstacle and desired path (:func:`measure_trajectories`
    of one :class:`Subject`).

    Args:
        trajectory: The joint trajectory to judge.
        path: The desired path (its P1, P5 and timing t = S / v).
        obstacle: The rounded box.
        arm: The arm (collision geometry, end-effector frame, joint limits).
        settings: Sampling, certificate and thresholds; default :class:`MeasureSettings`.
        index: Case number (kept in the result).
        extrapolated: Whether (L, W) lies outside the coefficients' fitted range.
        reach: The links' reach for the certificate (computed from ``arm`` if None).
        extra: The values of the scene variables beyond L and W that placed ``obstacle`` and
            ``path`` ((name, value), ... [m]), kept in the result.

    Returns:
        The :class:`CaseResult`.
    """
    subject = Subject(trajectory, path, obstacle, index, bool(extrapolated), extra)
    return measure_trajectories([subject], arm, settings, reach=reach)[0]


def measure_trajectories(
    subjects: Sequence[Subject],
    arm: PlanarArm,
    settings: MeasureSettings | None = None,
    *,
    reach: LinkReach | None = None,
) -> list[CaseResult]:
    """Measure many trajectories, each against its own obstacle and desired path; results in
    the order of ``subjects``.

    Each case gets its own clearance certificate and its own execution certificates (both
    timings); the endpoint errors, the tracking errors and the sampled maxima that check the
    execution certificates are computed for all the cases at once (vectorised over them: the
    same numbers as case by case, to rounding).

    Args:
        subjects: The trajectories and what placed them.
        arm: The arm (collision geometry, end-effector frame, joint limits).
        settings: Sampling, certificate and thresholds; default :class:`MeasureSettings`.
        reach: The links' reach for the certificate (computed from ``arm`` if None).
    """
    settings = settings or MeasureSettings()
    if not subjects:
        return []
    reach = reach or LinkReach.from_arm(arm)
    trajectories = [s.trajectory for s in subjects]
    paths = [s.path for s in subjects]
    clearances = [
        measure_clearance(
            s.trajectory,
            s.obstacle,
            arm,
            reach,
            settings.time_samples
            or (0 if settings.certify else samples_for_resolution(s.trajectory, reach, settings.resolution_m)),
            settings,
        )
        for s in subjects
    ]
    path_samples = [settings.time_samples or max(7, math.ceil(p.length_m / settings.resolution_m) + 1) for p in paths]
    endpoints = endpoint_errors_of(trajectories, paths, arm)
    tracking = tracking_errors_of(trajectories, paths, arm, path_samples)
    ceilings = [s.torque_ceiling_n_m for s in subjects]
    joints = joint_checks(trajectories, arm, settings.thresholds.acceleration_limits_rad_s2, ceilings)
    results = []
    for s, clearance, endpoint, track, joint in zip(subjects, clearances, endpoints, tracking, joints, strict=True):
        measurement = Measurement(
            T_s=float(s.trajectory.duration_s),
            parameters=tuple(float(v) for v in s.trajectory.parameters),
            clearance=clearance,
            endpoints=endpoint,
            tracking=track,
            joints=joint,
        )
        results.append(
            CaseResult(
                index=s.index,
                L_m=float(s.obstacle.length_m),
                W_m=float(s.obstacle.width_m),
                extrapolated=bool(s.extrapolated),
                measurement=measurement,
                verdict=Verdict(failures=tuple(acceptance_failures(measurement, settings.thresholds))),
                extra=s.extra,
            )
        )
    return results


def measure_clearance(
    trajectory: JointTrajectory,
    obstacle: Obstacle,
    arm: PlanarArm,
    reach: LinkReach,
    samples: int,
    settings: MeasureSettings,
) -> Clearance:
    """Clearance of one trajectory: the continuous-time certificate if ``settings.certify``
    (its Coal samples give the sampled minimum), else Coal at ``samples`` uniform times.

    In the ``"decide"`` certificate mode the certificate first only decides whether the clearance
    keeps the margin (:func:`pipeline.geometry.sinusoid_certificate.certify` with
    ``decide_above_m``); only a trajectory where it does not is certified again in tolerance
    mode, so the bounds of the cases below the margin are tight and those above it are merely
    >= the margin. ``"tight"`` certifies every case in tolerance mode.
    """
    coal_route = CoalClearance(arm, obstacle)
    if not settings.certify:
        times = np.linspace(0.0, trajectory.duration_s, samples)
        values = coal_route.link_clearance(trajectory.q(times))
        sampled_link = _pair(values.min(axis=0))
        sampled_time = float(times[int(np.argmin(values.min(axis=1)))])
        return Clearance(min(sampled_link), sampled_link, sampled_time, samples, None)
    margin = settings.thresholds.margin_m
    decide = settings.certificate_mode == "decide"
    certificate = _certify(trajectory, coal_route, reach, settings, margin if decide else None)
    evaluations = int(certificate.evaluations)
    tight = not decide or certificate.certified_clearance_m < margin
    if decide and tight:
        certificate = _certify(trajectory, coal_route, reach, settings, None)
        evaluations += int(certificate.evaluations)
    bound = float(certificate.certified_clearance_m)
    certified = CertifiedClearance(
        certified_clearance_m=bound,
        link_clearance_m=_pair(certificate.certified_link_clearance_m),
        time_s=float(certificate.bound_time_s),
        link=int(certificate.bound_link),
        evaluations=evaluations,
        converged=bool(certificate.converged),
        collision_free=bool(certificate.certified),
        keeps_margin=bound >= margin,
        tight=tight,
    )
    return Clearance(
        float(certificate.min_observed_clearance_m),
        _pair(certificate.sampled_link_clearance_m),
        float(certificate.min_observed_time_s),
        max(2, evaluations),
        certified,
    )


def _certify(
    trajectory: JointTrajectory,
    coal_route: CoalClearance,
    reach: LinkReach,
    settings: MeasureSettings,
    decide_above_m: float | None,
) -> Certificate:
    """The adaptive certificate with Coal (decide mode if ``decide_above_m`` is given)."""
    return certify(
        trajectory,
        coal_route.link_clearance,
        reach,
        distance_error_m=COAL_DISTANCE_ERROR_M,
        tolerance_m=settings.tolerance_m,
        decide_above_m=decide_above_m,
        max_evaluations=settings.max_evaluations,
        link_clearance=coal_route.link_distances,
    )


def _parameters(trajectories: Sequence[JointTrajectory]) -> np.ndarray:
    """The trajectories' parameters, (n, 8)."""
    return np.array([t.parameters for t in trajectories], dtype=float).reshape(-1, 8)


def _durations(trajectories: Sequence[JointTrajectory]) -> np.ndarray:
    """The trajectories' durations T, (n,) [s]."""
    return np.array([t.duration_s for t in trajectories], dtype=float)


def endpoint_errors(trajectory: JointTrajectory, path: QuarticPath, arm: PlanarArm) -> EndpointErrors:
    """End effector (the URDF's frame, through Pinocchio) against P1 at t = 0 and P5 at t = T [m]."""
    return endpoint_errors_of([trajectory], [path], arm)[0]


def endpoint_errors_of(
    trajectories: Sequence[JointTrajectory], paths: Sequence[QuarticPath], arm: PlanarArm
) -> list[EndpointErrors]:
    """:func:`endpoint_errors` of many trajectories, their forward kinematics in one Pinocchio pass."""
    durations = _durations(trajectories)
    q = sinusoid_states(_parameters(trajectories), np.column_stack([np.zeros_like(durations), durations]))[0]
    tips = arm.to_plane(arm.end_effector_positions(q.reshape(-1, 2))).reshape(-1, 2, 2)
    targets = np.array([(p.points_m[0], p.points_m[-1]) for p in paths], dtype=float)
    errors = np.linalg.norm(tips - targets, axis=-1)
    return [EndpointErrors(start_m=float(a), end_m=float(b)) for a, b in errors]


def tracking_errors(trajectory: JointTrajectory, path: QuarticPath, arm: PlanarArm, samples: int) -> Tracking:
    """Max and RMS distance between the end effector and the desired path at matched times [m].

    The path points are ``samples`` points uniform in x from P1 to P5, each with its time
    t = S(x) / v (:meth:`QuarticPath.uniform_samples`: one forward arc length, no inversion).
    """
    return tracking_errors_of([trajectory], [path], arm, [samples])[0]


def tracking_errors_of(
    trajectories: Sequence[JointTrajectory], paths: Sequence[QuarticPath], arm: PlanarArm, samples: Sequence[int]
) -> list[Tracking]:
    """:func:`tracking_errors` of many trajectories (``samples[k]`` path points for the k-th), the
    end effector of all their points in one closed-form pass (Eq. 2)."""
    times, desired, valid = path_samples(paths, samples)
    times = np.minimum(times, _durations(trajectories)[:, None])  # S(x_end) / v is T up to rounding
    q = sinusoid_angles(_parameters(trajectories), times)
    deviation = np.linalg.norm(arm.end_effector_planar(q) - desired, axis=-1)
    deviation[~valid] = 0.0
    peak = deviation.max(axis=1)
    rms = np.sqrt((deviation**2).sum(axis=1) / valid.sum(axis=1))
    return [Tracking(max_m=float(a), rms_m=float(b)) for a, b in zip(peak, rms, strict=True)]


def joint_check(
    trajectory: JointTrajectory, arm: PlanarArm, acceleration_limits_rad_s2: Pair | None = None
) -> JointCheck:
    """Closed-form joint peaks and ranges against the URDF's limits (and the given acceleration
    limits), the torques: a certified bound over all of [0, T] (paper timing, decided against
    the URDF's effort limits) checked against the closed-form dynamics sampled at
    :data:`verify.acceptance.sampling.PAPER_GRID` (coarse, refined at the peaks: a bound below a
    sampled torque is a failure of the certificate, reported), and the shortest rest-to-rest
    timing within the same limits (:func:`rest_to_rest_check`)."""
    return joint_checks([trajectory], arm, acceleration_limits_rad_s2)[0]


def joint_checks(
    trajectories: Sequence[JointTrajectory],
    arm: PlanarArm,
    acceleration_limits_rad_s2: Pair | None = None,
    torque_ceilings: Sequence[Pair | None] | None = None,
) -> list[JointCheck]:
    """:func:`joint_check` of many trajectories (the sampled maxima vectorised over them);
    ``torque_ceilings``: per trajectory, another bound its sampled paper-timing torque will be
    checked against (:attr:`Subject.torque_ceiling_n_m`), or None."""
    from pipeline.model.limits import ArmLimits
    from pipeline.online.execution import dynamics_of

    dynamics, limits = dynamics_of(arm), ArmLimits.from_arm(arm, acceleration_limits_rad_s2)
    velocity_limits = _pair(arm.velocity_limits_rad_s)
    position_limits = (_pair(arm.position_limits_rad[0]), _pair(arm.position_limits_rad[1]))
    torques = _torque_checks(trajectories, dynamics, limits, torque_ceilings)
    rests = _rest_to_rest_checks(trajectories, arm, dynamics, limits)
    checks = []
    for trajectory, torque, (rest_to_rest, error) in zip(trajectories, torques, rests, strict=True):
        peak_velocity = _pair(trajectory.peak_velocity_rad_s())
        peak_acceleration = _pair(trajectory.peak_acceleration_rad_s2())
        ranges = joint_ranges(trajectory)
        checks.append(
            JointCheck(
                peak_velocity_rad_s=peak_velocity,
                peak_acceleration_rad_s2=peak_acceleration,
                range_rad=ranges,
                velocity_limits_rad_s=velocity_limits,
                position_limits_rad=position_limits,
                acceleration_limits_rad_s2=acceleration_limits_rad_s2,
                within_velocity_limits=all(p <= v for p, v in zip(peak_velocity, velocity_limits, strict=True)),
                within_position_limits=all(
                    lim[0] <= r[0] and r[1] <= lim[1] for r, lim in zip(ranges, position_limits, strict=True)
                ),
                within_acceleration_limits=(
                    None
                    if acceleration_limits_rad_s2 is None
                    else all(p <= a for p, a in zip(peak_acceleration, acceleration_limits_rad_s2, strict=True))
                ),
                **torque,
                rest_to_rest=rest_to_rest,
                rest_to_rest_error=None if error is None else f"no rest-to-rest timing keeps the limits ({error})",
            )
        )
    return checks


def paper_torque_maxima(
    trajectories: Sequence[JointTrajectory], dynamics: PlanarDynamics, bounds: np.ndarray | None = None
) -> np.ndarray:
    """Largest |tau_i| (n, 2) [N m] of the paper timing by the closed-form dynamics, sampled
    coarse and refined at the peaks (:data:`verify.acceptance.sampling.PAPER_GRID`): at every
    peak, or, given the bounds (n, 2) [N m] the samples are checked against, only where the coarse
    samples come within :data:`verify.acceptance.sampling.PAPER_ROOM` of them."""
    parameters = _parameters(trajectories)

    def evaluate(rows: np.ndarray, t: np.ndarray) -> np.ndarray:
        return np.abs(dynamics.torque(*sinusoid_states(parameters[rows], t)))

    coarse, fine = PAPER_GRID
    return refined_maxima(evaluate, uniform_grid(_durations(trajectories), coarse), fine, bounds, PAPER_ROOM)[0]


def _torque_checks(
    trajectories: Sequence[JointTrajectory],
    dynamics: PlanarDynamics,
    limits: ArmLimits,
    ceilings: Sequence[Pair | None] | None = None,
) -> list[dict[str, Any]]:
    """The paper timing's certified torque bounds, decided against the effort limits, and the
    sampled torques that check them (refined where the samples come near the bound or the
    ``ceilings``, the other bounds they will be checked against)."""
    from pipeline.model.limits import ArmLimits
    from pipeline.motion.execution_certificate import certify_execution
    from pipeline.motion.timed_trajectory import TimedTrajectory
    from pipeline.motion.timing import PAPER_TIMING

    effort = _pair(limits.effort_n_m)
    effort_only = ArmLimits(effort_n_m=effort)
    bounds = [
        _pair(certify_execution(TimedTrajectory(t, PAPER_TIMING), dynamics, effort_only).torque_bound_n_m)
        for t in trajectories
    ]
    checked = np.array(bounds, dtype=float).reshape(-1, 2)
    for k, ceiling in enumerate(ceilings or ()):
        if ceiling is not None:
            checked[k] = np.minimum(checked[k], ceiling)
    sampled = paper_torque_maxima(trajectories, dynamics, checked)
    return [
        {
            "torque_bound_n_m": bound,
            "peak_torque_sampled_n_m": _pair(peaks),
            "effort_limits_n_m": effort,
            "within_effort_limits": all(b <= e for b, e in zip(bound, effort, strict=True)),
        }
        for bound, peaks in zip(bounds, sampled, strict=True)
    ]


_PINOCCHIO_DATA: weakref.WeakKeyDictionary[PlanarArm, Any] = weakref.WeakKeyDictionary()


def _pinocchio_data(arm: PlanarArm) -> Any:
    """Pinocchio's data of ``arm``'s model, made once per arm."""
    data = _PINOCCHIO_DATA.get(arm)
    if data is None:
        data = _PINOCCHIO_DATA[arm] = arm.model.createData()
    return data


def rest_to_rest_instants(timing: RestToRestTiming, samples: tuple[int, int] = REST_TO_REST_GRID[:2]) -> np.ndarray:
    """The coarse grid of the rest-to-rest check, sorted distinct instants [s] over [0, T']:
    ``samples[0]`` uniform over each ramp (the ends included) and ``samples[1]`` uniform over the
    middle [r, T' - r] (:func:`verify.acceptance.sampling.piecewise_grid`)."""
    ramp, middle = (check_positive_int("samples", n, minimum=2) for n in samples)
    return piecewise_grid(np.array([timing.duration_s]), np.array([timing.ramp_s]), ramp, middle)[0]


def rest_to_rest_check(
    trajectory: JointTrajectory,
    arm: PlanarArm,
    dynamics: PlanarDynamics,
    limits: ArmLimits,
    grid: tuple[int, int, int] = REST_TO_REST_GRID,
) -> RestToRestCheck:
    """The shortest rest-to-rest timing of ``trajectory``'s path within ``limits``
    (:func:`pipeline.motion.rest_to_rest.shortest_rest_to_rest`), certified over all of [0, T']
    (:func:`pipeline.motion.execution_certificate.certify_execution`, decide mode against
    ``limits``), with the largest |dq|, |ddq| and |tau| found on the coarse grid
    :func:`rest_to_rest_instants` (``grid[:2]``) refined by ``grid[2]`` instants around its
    highest local maxima (:func:`verify.acceptance.sampling.refined_maxima`; torques by the
    closed-form dynamics, at each joint's peak also by Pinocchio's RNEA, the larger kept) and
    |dq|, |ddq| at both ends.

    Raises:
        InvalidParameterError: no rest-to-rest timing keeps ``limits`` (one binds at rest).
    """
    check, error = _rest_to_rest_checks([trajectory], arm, dynamics, limits, grid)[0]
    if error is not None:
        raise error
    return check


def _rest_to_rest_checks(
    trajectories: Sequence[JointTrajectory],
    arm: PlanarArm,
    dynamics: PlanarDynamics,
    limits: ArmLimits,
    grid: tuple[int, int, int] = REST_TO_REST_GRID,
) -> list[tuple[RestToRestCheck | None, InvalidParameterError | None]]:
    """:func:`rest_to_rest_check` of many trajectories, each (check, None) or (None, why there is
    no rest-to-rest timing); the sampled maxima vectorised over them."""
    import pinocchio as pin

    from pipeline.motion.execution_certificate import certify_execution
    from pipeline.motion.rest_to_rest import shortest_rest_to_rest
    from pipeline.motion.timed_trajectory import TimedTrajectory

    out: list[tuple[RestToRestCheck | None, InvalidParameterError | None]] = []
    timed: list[TimedTrajectory] = []
    for trajectory in trajectories:
        try:
            timed.append(TimedTrajectory(trajectory, shortest_rest_to_rest(trajectory, dynamics, limits)))
            out.append((None, None))
        except InvalidParameterError as exc:  # a limit binds at rest
            out.append((None, exc))
    if not timed:
        return out
    certificates = [certify_execution(t, dynamics, limits) for t in timed]
    parameters, timings = _parameters([t.trajectory for t in timed]), [t.timing for t in timed]
    durations = np.array([t.duration_s for t in timed], dtype=float)
    ramps = np.array([t.timing.ramp_s for t in timed], dtype=float)

    def evaluate(rows: np.ndarray, tau: np.ndarray) -> np.ndarray:
        q, dq, ddq = timed_states(parameters[rows], [timings[r] for r in rows], tau)
        return np.concatenate([np.abs(dq), np.abs(ddq), np.abs(dynamics.torque(q, dq, ddq))], axis=-1)

    # In evaluate's order: speeds, accelerations, torques.
    bounds = np.array([(*c.speed_bound_rad_s, *c.acceleration_bound_rad_s2, *c.torque_bound_n_m) for c in certificates])
    ramp, middle, fine = grid
    grid_s = piecewise_grid(durations, ramps, ramp, middle)
    maxima, where, evaluated = refined_maxima(evaluate, grid_s, fine, bounds, REST_TO_REST_ROOM)
    # Both ends, then each joint's torque peak (for RNEA).
    probe = np.column_stack([np.zeros_like(durations), durations, where[:, 4], where[:, 5]])
    q, dq, ddq = timed_states(parameters, timings, probe)
    data = _pinocchio_data(arm)
    checks = iter(range(len(timed)))
    for position, (_, error) in enumerate(out):
        if error is not None:
            continue
        k = next(checks)
        peak_torque = maxima[k, 4:6].copy()
        for joint in (0, 1):
            rnea = pin.rnea(arm.model, data, q[k, 2 + joint], dq[k, 2 + joint], ddq[k, 2 + joint])
            peak_torque[joint] = max(peak_torque[joint], abs(float(rnea[joint])))
        timing, certificate = timed[k].timing, certificates[k]
        out[position] = (
            RestToRestCheck(
                path_duration_s=float(timed[k].trajectory.duration_s),
                duration_s=float(timed[k].duration_s),
                speed_scale=float(timing.speed_scale),
                ramp_s=float(timing.ramp_s),
                speed_bound_rad_s=_pair(certificate.speed_bound_rad_s),
                acceleration_bound_rad_s2=_pair(certificate.acceleration_bound_rad_s2),
                torque_bound_n_m=_pair(certificate.torque_bound_n_m),
                sampled_speed_rad_s=_pair(maxima[k, 0:2]),
                sampled_acceleration_rad_s2=_pair(maxima[k, 2:4]),
                sampled_torque_n_m=_pair(peak_torque),
                samples=int(evaluated[k]),
                end_speed_rad_s=float(np.abs(dq[k, :2]).max()),
                end_acceleration_rad_s2=float(np.abs(ddq[k, :2]).max()),
                velocity_limits_rad_s=_pair(limits.velocity_rad_s),
                acceleration_limits_rad_s2=_pair(limits.acceleration_rad_s2),
                effort_limits_n_m=_pair(limits.effort_n_m),
                intervals=int(certificate.intervals),
            ),
            None,
        )
    return out


def acceptance_failures(measurement: Measurement, thresholds: AcceptanceThresholds) -> list[str]:
    """Every acceptance check ``measurement`` fails, in words (empty: it passes)."""
    failures: list[str] = []
    certified = measurement.clearance.certified
    if certified is None:
        failures.append("clearance not certified (certificate disabled)")
    else:
        bound = certified.certified_clearance_m
        if bound <= thresholds.min_certified_clearance_m:
            failures.append(
                f"certified clearance {bound * 1e3:.3f} mm <= {thresholds.min_certified_clearance_m * 1e3:.3f} mm"
                + ("" if certified.collision_free else " (collision not excluded)")
            )
        if thresholds.require_margin and not certified.keeps_margin:
            failures.append(f"certified clearance {bound * 1e3:.3f} mm < margin {thresholds.margin_m * 1e3:.3f} mm")
    endpoints = measurement.endpoints
    for name, value in (("start", endpoints.start_m), ("end", endpoints.end_m)):
        if value > thresholds.max_endpoint_error_m:
            failures.append(
                f"endpoint error at {name} {value * 1e3:.3f} mm > {thresholds.max_endpoint_error_m * 1e3:.3f} mm"
            )
    tracking_max = measurement.tracking.max_m
    if thresholds.max_tracking_error_m is not None and tracking_max > thresholds.max_tracking_error_m:
        failures.append(f"tracking error {tracking_max * 1e3:.3f} mm > {thresholds.max_tracking_error_m * 1e3:.3f} mm")
    if thresholds.check_joint_limits:
        j = measurement.joints
        if not j.within_velocity_limits:
            failures.append(
                f"joint speed peak {j.peak_velocity_rad_s} rad/s exceeds the URDF limits {j.velocity_limits_rad_s}"
            )
        if not j.within_position_limits:
            failures.append(f"joint range {j.range_rad} rad leaves the URDF limits {j.position_limits_rad}")
        if not j.within_effort_limits:
            failures.append(
                f"joint torque bound {j.torque_bound_n_m} N m exceeds the URDF limits {j.effort_limits_n_m}"
            )
        if any(b < p for b, p in zip(j.torque_bound_n_m, j.peak_torque_sampled_n_m, strict=True)):
            failures.append(
                f"certified torque bound {j.torque_bound_n_m} N m below a sampled torque {j.peak_torque_sampled_n_m}"
            )
        if j.within_acceleration_limits is False:
            failures.append(
                f"joint acceleration peak {j.peak_acceleration_rad_s2} rad/s^2 exceeds {j.acceleration_limits_rad_s2}"
            )
        if j.rest_to_rest is not None:
            failures += j.rest_to_rest.problems()
        elif j.rest_to_rest_error is not None:
            failures.append(j.rest_to_rest_error)
    return failures


def is_extrapolated(coefficients: Coefficients, L_m: float, W_m: float, **values: float) -> bool:
    """True if (L, W), or one of the extra variables' ``values`` (by name, [m]), lies outside the
    coefficients' fitted range."""
    fitted = coefficients.fitted_range_m
    inside = fitted["L"][0] <= L_m <= fitted["L"][1] and fitted["W"][0] <= W_m <= fitted["W"][1]
    return not (inside and all(fitted[name][0] <= value <= fitted[name][1] for name, value in values.items()))


def check_arm_matches(coefficients: Coefficients, arm: PlanarArm, option: str = "--urdf") -> None:
    """:func:`pipeline.online.check_arm_matches`, as a command-line error named after ``option``.

    Raises:
        InvalidParameterError: named after ``option``, with both arms' link lengths and radii [m].
    """
    try:
        check_arm_matches_online(coefficients, arm)
    except ArmMismatchError as exc:
        raise InvalidParameterError(
            option, str(arm.urdf_path), f"the arm the coefficients were fitted for ({exc})"
        ) from None


@dataclass(frozen=True)
class SweepCase:
    """One case of a sweep, to generate and measure.

    Attributes:
        index: Case number (kept in the result).
        L_m, W_m: The obstacle's size [m].
        extra: The extra variables' values ((name, value), ... [m], e.g. (("x", 0.01),)).
        torque_ceiling_n_m: The region map's bound of the paper timing's |tau_i| in the leaf
            holding the case, when the sweep checks the case against it (:attr:`Subject.torque_ceiling_n_m`).
    """

    index: int
    L_m: float
    W_m: float
    extra: tuple[tuple[str, float], ...] = ()
    torque_ceiling_n_m: Pair | None = None


def measure_case(
    coefficients: Coefficients,
    L_m: float,
    W_m: float,
    arm: PlanarArm,
    settings: MeasureSettings | None = None,
    *,
    index: int = 0,
    reach: LinkReach | None = None,
    extra: tuple[tuple[str, float], ...] = (),
) -> CaseResult:
    """Generate the trajectory for (L, W) and the extra variables' values ``extra`` ((name,
    value), ... [m], e.g. (("x", 0.01),) for coefficients over (L, W, x)) as an online user would,
    then measure it against the obstacle and path they place (moved to x).

    Extrapolation is allowed (and reported in ``extrapolated``). A case whose trajectory cannot
    be generated (e.g. the arm cannot reach the constraint points) is returned as failed with
    ``error`` set; it does not raise. The generator uses the link lengths stored in the
    coefficients; :func:`check_arm_matches` tells whether they are ``arm``'s.
    """
    return measure_cases(coefficients, [SweepCase(index, L_m, W_m, extra)], arm, settings, reach=reach)[0]


def measure_cases(
    coefficients: Coefficients,
    cases: Sequence[SweepCase],
    arm: PlanarArm,
    settings: MeasureSettings | None = None,
    *,
    reach: LinkReach | None = None,
) -> list[CaseResult]:
    """:func:`measure_case` of every case, measured together (:func:`measure_trajectories`);
    results in the order of ``cases``."""
    results: list[CaseResult | None] = [None] * len(cases)
    subjects: list[tuple[int, Subject]] = []
    for position, case in enumerate(cases):
        values = {name: float(value) for name, value in case.extra}
        named = tuple(values.items())
        L_m, W_m = case.L_m, case.W_m
        try:
            generated = generate(coefficients, L_m, W_m, out_of_range="ignore", **values)
        except PipelineError as exc:
            extrapolated = is_extrapolated(coefficients, L_m, W_m, **values)
            results[position] = failed_case(case.index, L_m, W_m, extrapolated, f"{type(exc).__name__}: {exc}", named)
            continue
        subject = Subject(
            generated.trajectory,
            generated.path,
            generated.obstacle,
            case.index,
            bool(generated.extrapolated),
            named,
            case.torque_ceiling_n_m,
        )
        subjects.append((position, subject))
    measured = measure_trajectories([s for _, s in subjects], arm, settings, reach=reach)
    for (position, _), result in zip(subjects, measured, strict=True):
        results[position] = result
    return results  # type: ignore[return-value]
