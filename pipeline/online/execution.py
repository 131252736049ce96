"""The second half of certify-or-repair: the answer must also execute, not only clear the obstacle.

For a trajectory already certified collision-free (:mod:`pipeline.online.repair`), this
certifies, per query:

* its endpoint errors |tip(0) - P1| and |tip(T) - P5| within the tolerance: exact values of the
  closed-form forward kinematics (Eq. 2) plus :data:`ENDPOINT_SLACK_M` for rounding (the map's
  proven bound is used instead where its cell covers the regression's unrepaired answer);
* for the chosen timing, the joint angles within their limits and |dq|, |ddq|, |tau|, |jerk|
  within the arm's limits over all of [0, T']
  (:func:`pipeline.motion.execution_certificate.certify_execution`, decide mode unless a tight
  certificate is asked for). The near-optimal timing (:mod:`pipeline.motion.near_optimal`) is
  built and certified within the limits with the servo defaults filled in
  (:meth:`pipeline.model.limits.ArmLimits.with_servo_defaults`). The rest-to-rest timing is the
  shortest the closed-form bounds allow (:func:`pipeline.motion.rest_to_rest.shortest_rest_to_rest`),
  certified afterwards; should its certificate not confirm it, the speed scale is lowered by 10 %
  (up to :data:`RETIMING_TRIES` times). All three take one route, :func:`timed_and_certified`,
  which also gives the duration a refusal of the paper timing suggests.

Clearance and endpoints are statements about the configurations visited, which every timing of
the same path shares (:mod:`pipeline.motion.timing`): they are certified once, for every timing.

**From the map, at lookup cost** (:func:`execution_from_map`): for the regression's own answer
inside the fitted range, the region map's leaf holding the obstacle carries bounds proven for
every obstacle of the leaf (:mod:`pipeline.certify.execution_bounds`): the angle range, the paper
timing's speed, acceleration and torque bounds, and a rest-to-rest timing (c, r) with its bounds.
They are used when they were made for this arm (the same limits and inertias) and keep every
limit; otherwise (another arm, or a leaf whose bound exceeds a limit the trajectory may still
keep) the per-query certificate decides. The near-optimal timing is certified per query.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from pipeline.certify.region_map import RegionMap
from pipeline.exceptions import ExecutionRefusedError, InvalidParameterError, TimingRefusedError
from pipeline.model.arm import PlanarArm
from pipeline.model.dynamics import PlanarDynamics, identify_dynamics
from pipeline.model.limits import ArmLimits
from pipeline.motion.execution_certificate import ExecutionCertificate, certify_execution
from pipeline.motion.near_optimal import NEAR_OPTIMAL, NearOptimal, near_optimal_timing
from pipeline.motion.rest_to_rest import ShortestRestToRest, shortest_rest_to_rest
from pipeline.motion.timed_trajectory import TimedTrajectory
from pipeline.motion.timing import PAPER_TIMING, PaperTiming, RestToRestTiming
from pipeline.motion.trajectory import JointTrajectory
from pipeline.online.generator import GeneratedTrajectory

__all__ = [
    "ENDPOINT_SLACK_M",
    "Execution",
    "certify_answer_execution",
    "dynamics_of",
    "execution_from_map",
    "measured_endpoint_errors",
    "retime",
    "timed_and_certified",
]

#: Rounding slack of a per-query endpoint error [m] (a few dozen operations on values below 1 m).
ENDPOINT_SLACK_M = 1e-12
#: Retries of the rest-to-rest timing with a 10 % lower speed scale.
RETIMING_TRIES = 5


def dynamics_of(arm: PlanarArm) -> PlanarDynamics:
    """The arm's closed-form dynamics (:func:`pipeline.model.dynamics.identify_dynamics`), identified
    once per arm and kept by it (:meth:`PlanarArm.derived`)."""
    return arm.derived(identify_dynamics)


@dataclass(frozen=True, eq=False)
class Execution:
    """What makes an answer executable.

    Attributes:
        executed: The trajectory with its timing (``q``, ``dq``, ``ddq``, ``jerk`` at executed times).
        certificate: Its bounds over all of [0, T'] (angles, |dq|, |ddq|, |tau|, |jerk|).
        limits: The limits they were checked against (for the near-optimal timing, with the servo
            defaults filled in: :meth:`pipeline.model.limits.ArmLimits.with_servo_defaults`).
        endpoint_errors_m: The measured |tip(0) - P1| and |tip(T) - P5| of this trajectory [m]
            (the closed-form forward kinematics, Eq. 2).
        endpoint_tolerance_m: The tolerance the bounds were checked against [m].
        endpoint_error_bounds_m: Proven bounds on those errors [m]: the measured values plus
            :data:`ENDPOINT_SLACK_M`, or the region map's bound for the regression's own answer.
    """

    executed: TimedTrajectory
    certificate: ExecutionCertificate
    limits: ArmLimits
    endpoint_errors_m: tuple[float, float]
    endpoint_tolerance_m: float
    endpoint_error_bounds_m: tuple[float, float]


def measured_endpoint_errors(
    trajectory: JointTrajectory, generated: GeneratedTrajectory, arm: PlanarArm
) -> tuple[float, float]:
    """|tip(0) - P1| and |tip(T) - P5| [m] of ``trajectory`` for ``generated``'s path: the
    sinusoids at 0 and T and the closed-form forward kinematics (Eq. 2,
    :meth:`pipeline.model.arm.PlanarArm.end_effector_planar`), in plain floats."""
    a1, w1, phi1, g1, a2, w2, phi2, g2 = trajectory.parameters
    l1, l2 = arm.link_lengths_m
    start, end = generated.end_points_m.tolist()
    errors = []
    for t, (px, py) in ((0.0, start), (trajectory.duration_s, end)):
        q1 = a1 * math.sin(w1 * t + phi1) + g1
        q12 = q1 + a2 * math.sin(w2 * t + phi2) + g2 + arm.elbow_offset_rad
        x, y = l1 * math.cos(q1) + l2 * math.cos(q12), l1 * math.sin(q1) + l2 * math.sin(q12)
        errors.append(math.hypot(x - px, y - py))
    return errors[0], errors[1]


def _endpoint_check(measured, map_bound_m, tolerance_m, generated) -> tuple[float, float]:
    """The proven endpoint bounds (module docstring); refused beyond the tolerance."""
    if map_bound_m is not None and map_bound_m <= tolerance_m:
        bounds = (map_bound_m, map_bound_m)
    else:
        bounds = (measured[0] + ENDPOINT_SLACK_M, measured[1] + ENDPOINT_SLACK_M)
    missed = [
        f"endpoint error bound at {name} {1e3 * error:.3f} mm > tolerance {1e3 * tolerance_m:.3f} mm"
        for name, error in zip(("P1", "P5"), bounds, strict=True)
        if error > tolerance_m
    ]
    if missed:
        raise ExecutionRefusedError(*_size(generated), None, tuple(missed), variables=dict(generated.variables))
    return bounds


def _size(generated: GeneratedTrajectory) -> tuple[float, float]:
    return generated.length_m, generated.width_m


def timed_and_certified(
    trajectory: JointTrajectory,
    dynamics: PlanarDynamics,
    limits: ArmLimits,
    timing: PaperTiming | ShortestRestToRest | NearOptimal,
    tight: bool = False,
) -> tuple[TimedTrajectory, ExecutionCertificate, ArmLimits]:
    """``trajectory`` with ``timing``, its certificate, and the limits it was decided against (for
    the near-optimal timing, ``limits`` with the servo defaults). The one route every per-query
    timing takes: the answers of :func:`certify_answer_execution` and the durations its refusals
    suggest both come from here.

    Raises:
        TimingRefusedError: no certified timing of this kind keeps the limits (the reasons name
            each bound beyond its limit).
        InvalidParameterError: an unknown timing.
    """
    decide = None if tight else limits
    if isinstance(timing, PaperTiming):
        executed = TimedTrajectory(trajectory, PAPER_TIMING)
        certificate = certify_execution(executed, dynamics, decide)
        found = certificate.violations(limits)
        if found:
            raise TimingRefusedError(tuple(str(v) for v in found))
        return executed, certificate, limits
    if isinstance(timing, NearOptimal):
        limits = limits.with_servo_defaults()
        result = near_optimal_timing(trajectory, dynamics, limits, timing.settings)
        certificate = certify_execution(result.executed, dynamics, None) if tight else result.certificate
        return result.executed, certificate, limits
    if not isinstance(timing, ShortestRestToRest):
        raise InvalidParameterError("timing", type(timing).__name__, "PAPER_TIMING, REST_TO_REST or NEAR_OPTIMAL")
    try:
        retimed = shortest_rest_to_rest(trajectory, dynamics, limits)
    except InvalidParameterError as exc:  # a limit binds at rest
        raise TimingRefusedError((str(exc),)) from None
    for _ in range(RETIMING_TRIES):
        executed = TimedTrajectory(trajectory, retimed)
        certificate = certify_execution(executed, dynamics, decide)
        found = certificate.violations(limits)
        if not found:
            return executed, certificate, limits
        if any(v.quantity == "angle" for v in found):  # the same configurations under every timing
            raise TimingRefusedError(tuple(str(v) for v in found if v.quantity == "angle"))
        retimed = _slower(retimed)
    raise TimingRefusedError(tuple(str(v) for v in found))


def certify_answer_execution(
    generated: GeneratedTrajectory,
    trajectory: JointTrajectory,
    arm: PlanarArm,
    limits: ArmLimits,
    endpoint_tolerance_m: float,
    timing: PaperTiming | ShortestRestToRest | NearOptimal = PAPER_TIMING,
    tight: bool = False,
    map_endpoint_bound_m: float | None = None,
) -> Execution:
    """Certify that ``trajectory`` (the answer for ``generated``'s obstacle, certified collision-free)
    ends within the tolerance and, with ``timing``, keeps ``limits`` (module docstring).

    Raises:
        ExecutionRefusedError: a check fails; its reasons name the joint, the bound, the limit and
            the excess (for the paper timing, also the near-optimal duration that keeps them,
            computed by the same route as ``timing=NEAR_OPTIMAL``).
    """
    where = {"variables": dict(generated.variables)}  # the message names x (etc.) after L and W
    measured = measured_endpoint_errors(trajectory, generated, arm)
    bounds = _endpoint_check(measured, map_endpoint_bound_m, endpoint_tolerance_m, generated)
    dynamics = dynamics_of(arm)
    try:
        executed, certificate, used = timed_and_certified(trajectory, dynamics, limits, timing, tight)
    except TimingRefusedError as exc:
        reasons = exc.reasons
        if isinstance(timing, PaperTiming) and not any("angle" in r for r in reasons):
            reasons = (*reasons, _near_optimal_hint(trajectory, dynamics, limits))
        raise ExecutionRefusedError(*_size(generated), timing.name, reasons, **where) from None
    return Execution(executed, certificate, used, measured, endpoint_tolerance_m, bounds)


def _near_optimal_hint(trajectory: JointTrajectory, dynamics: PlanarDynamics, limits: ArmLimits) -> str:
    """What the near-optimal timing does with the same path and limits (the route of ``timing=NEAR_OPTIMAL``)."""
    try:
        executed, _, used = timed_and_certified(trajectory, dynamics, limits, NEAR_OPTIMAL)
    except (TimingRefusedError, InvalidParameterError):
        return "no near-optimal timing keeps the limits either"
    return (
        f"the near-optimal timing (timing=NEAR_OPTIMAL, --timing near-optimal) keeps them in "
        f"T' = {executed.duration_s:.3f} s (T = {trajectory.duration_s:.3f} s; acceleration limits "
        f"{used.acceleration_rad_s2[0]:g}, {used.acceleration_rad_s2[1]:g} rad/s^2, jerk limits "
        f"{used.jerk_rad_s3[0]:g}, {used.jerk_rad_s3[1]:g} rad/s^3)"
    )


def execution_from_map(
    generated: GeneratedTrajectory,
    region_map: RegionMap | None,
    arm: PlanarArm,
    limits: ArmLimits,
    endpoint_tolerance_m: float,
    timing: PaperTiming | ShortestRestToRest | NearOptimal = PAPER_TIMING,
) -> Execution | None:
    """The execution of the regression's answer ``generated`` read off the region map's leaf
    (module docstring), or None where the map does not decide it: no map or no execution bounds
    in it, another arm's limits or inertias, the obstacle outside the fitted range, an endpoint
    bound above the tolerance, a leaf bound above a limit, or, for the near-optimal timing, no
    certified cell for this arm and limits."""
    if region_map is None or generated.endpoint_error_bound_m is None:
        return None
    if isinstance(timing, NearOptimal):
        return _near_optimal_from_cells(generated, region_map, arm, limits, endpoint_tolerance_m, timing)
    bounds = region_map.execution
    if bounds is None:
        return None
    if bounds.limits != limits or bounds.dynamics != dynamics_of(arm):
        return None
    error = generated.endpoint_error_bound_m
    if error > endpoint_tolerance_m:
        return None
    names = tuple(name for name, _ in generated.variables)
    if names != region_map.axes[2:]:
        return None
    leaf = region_map.leaf_at(generated.length_m, generated.width_m, *(v for _, v in generated.variables))
    if leaf is None:
        return None
    speed_scale, ramp, angles, rest, paper = bounds.leaf(leaf)
    trajectory = generated.trajectory
    if isinstance(timing, PaperTiming):
        chosen, bound = PAPER_TIMING, paper
    elif speed_scale == speed_scale:  # a rest-to-rest timing (not NaN)
        chosen, bound = RestToRestTiming(trajectory.duration_s, speed_scale, ramp), rest
    else:
        return None
    executed = TimedTrajectory(trajectory, chosen)
    certificate = ExecutionCertificate(
        chosen.name, executed.duration_s, angles, bound[0], bound[1], bound[2], {}, 0, limits, "range"
    )
    if certificate.violations(limits):
        return None
    measured = measured_endpoint_errors(trajectory, generated, arm)
    return Execution(executed, certificate, limits, measured, endpoint_tolerance_m, (error, error))


def _near_optimal_from_cells(
    generated: GeneratedTrajectory,
    region_map: RegionMap,
    arm: PlanarArm,
    limits: ArmLimits,
    endpoint_tolerance_m: float,
    timing: NearOptimal,
) -> Execution | None:
    """The near-optimal timing of the regression's answer from the map's cell holding the obstacle
    (:mod:`pipeline.certify.near_optimal_cells`): its T' and bounds are the cell's, proven for every
    obstacle of the cell; None where the cells do not decide it (none, another arm or limits, other
    settings or ``from_map=False`` asked for, a cell without a certified timing, a bound above a limit)."""
    cells = region_map.near_optimal_cells
    if cells is None or not timing.from_map or timing.settings != NEAR_OPTIMAL.settings:
        return None
    if not cells.made_for(limits, dynamics_of(arm)):
        return None
    used = cells.limits
    error = generated.endpoint_error_bound_m
    if error > endpoint_tolerance_m or tuple(name for name, _ in generated.variables) != cells.axes[2:]:
        return None
    cell = cells.cell_of(generated.length_m, generated.width_m, *(v for _, v in generated.variables))
    if cell is None:
        return None
    certificate = cells.certificate(cell)
    if certificate.violations(used):
        return None
    trajectory = generated.trajectory
    executed = TimedTrajectory(trajectory, cells.timing(cell, trajectory.duration_s))
    measured = measured_endpoint_errors(trajectory, generated, arm)
    return Execution(executed, certificate, used, measured, endpoint_tolerance_m, (error, error))


def _slower(timing: RestToRestTiming) -> RestToRestTiming:
    scale = 0.9 * timing.speed_scale
    return replace(timing, speed_scale=scale, ramp_s=min(timing.ramp_s / 0.9, timing.path_duration_s / scale))


def retime(generated: GeneratedTrajectory, arm: PlanarArm, limits: ArmLimits, timing) -> TimedTrajectory:
    """``generated``'s trajectory with ``timing``: PAPER_TIMING; REST_TO_REST, the shortest
    rest-to-rest timing the closed-form bounds keep within ``limits``, not certified; or
    NEAR_OPTIMAL, certified within ``limits`` with the servo defaults as it is built.

    Raises:
        ExecutionRefusedError: no timing of that kind keeps the limits.
    """
    trajectory = generated.trajectory
    if isinstance(timing, PaperTiming):
        return TimedTrajectory(trajectory, PAPER_TIMING)
    try:
        if isinstance(timing, NearOptimal):
            return timed_and_certified(trajectory, dynamics_of(arm), limits, timing)[0]
        return TimedTrajectory(trajectory, shortest_rest_to_rest(trajectory, dynamics_of(arm), limits))
    except InvalidParameterError as exc:  # a limit binds at rest
        reasons: tuple[str, ...] = (str(exc),)
    except TimingRefusedError as exc:
        reasons = exc.reasons
    raise ExecutionRefusedError(
        generated.length_m, generated.width_m, timing.name, reasons, variables=dict(generated.variables)
    )
