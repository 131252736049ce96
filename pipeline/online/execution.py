"""The second half of certify-or-repair: the answer must also execute, not only clear the obstacle.

For a trajectory already certified collision-free (:mod:`pipeline.online.repair`), this
certifies, per query:

* its endpoint errors |tip(0) - P1| and |tip(T) - P5| within the tolerance: exact values of the
  closed-form forward kinematics (Eq. 2) plus :data:`ENDPOINT_SLACK_M` for rounding (the map's
  proven bound is used instead where its cell covers the regression's unrepaired answer);
* for the chosen timing, the joint angles within their limits and |dq|, |ddq|, |tau| within the
  arm's speed, acceleration and effort limits over all of [0, T']
  (:func:`pipeline.motion.execution_certificate.certify_execution`, decide mode unless a tight
  certificate is asked for). The rest-to-rest timing is the shortest the closed-form bounds allow
  (:func:`pipeline.motion.rest_to_rest.shortest_rest_to_rest`), certified afterwards; should its
  certificate not confirm it, the speed scale is lowered by 10 % (up to :data:`RETIMING_TRIES` times).

Clearance and endpoints are statements about the configurations visited, which every timing of
the same path shares (:mod:`pipeline.motion.timing`): they are certified once, for every timing.

**From the map, at lookup cost** (:func:`execution_from_map`): for the regression's own answer
inside the fitted range, the region map's leaf holding the obstacle carries bounds proven for
every obstacle of the leaf (:mod:`pipeline.certify.execution_bounds`): the angle range, the paper
timing's speed, acceleration and torque bounds, and a rest-to-rest timing (c, r) with its bounds.
They are used when they were made for this arm (the same limits and inertias) and keep every
limit; otherwise (another arm, or a leaf whose bound exceeds a limit the trajectory may still
keep) the per-query certificate decides.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass, replace

import numpy as np

from pipeline.certify.region_map import RegionMap
from pipeline.exceptions import ExecutionRefusedError, InvalidParameterError
from pipeline.model.arm import PlanarArm
from pipeline.model.dynamics import PlanarDynamics, identify_dynamics
from pipeline.model.limits import ArmLimits
from pipeline.motion.execution_certificate import ExecutionCertificate, certify_execution
from pipeline.motion.rest_to_rest import ShortestRestToRest, shortest_rest_to_rest
from pipeline.motion.timed_trajectory import TimedTrajectory
from pipeline.motion.timing import PAPER_TIMING, PaperTiming, RestToRestTiming
from pipeline.motion.trajectory import JointTrajectory
from pipeline.online.generator import GeneratedTrajectory

__all__ = ["ENDPOINT_SLACK_M", "Execution", "certify_answer_execution", "dynamics_of", "execution_from_map", "retime"]

#: Rounding slack of a per-query endpoint error [m] (a few dozen operations on values below 1 m).
ENDPOINT_SLACK_M = 1e-12
#: Retries of the rest-to-rest timing with a 10 % lower speed scale.
RETIMING_TRIES = 5

_DYNAMICS: weakref.WeakKeyDictionary[PlanarArm, PlanarDynamics] = weakref.WeakKeyDictionary()


def dynamics_of(arm: PlanarArm) -> PlanarDynamics:
    """The arm's closed-form dynamics (:func:`pipeline.model.dynamics.identify_dynamics`), identified once per arm."""
    dynamics = _DYNAMICS.get(arm)
    if dynamics is None:
        dynamics = _DYNAMICS[arm] = identify_dynamics(arm)
    return dynamics


@dataclass(frozen=True, eq=False)
class Execution:
    """What makes an answer executable.

    Attributes:
        executed: The trajectory with its timing (``q``, ``dq``, ``ddq`` at executed times).
        certificate: Its bounds over all of [0, T'] (angles, |dq|, |ddq|, |tau|).
        limits: The limits they were checked against.
        endpoint_errors_m: Bounds on |tip(0) - P1| and |tip(T) - P5| [m].
        endpoint_tolerance_m: The tolerance they were checked against [m].
    """

    executed: TimedTrajectory
    certificate: ExecutionCertificate
    limits: ArmLimits
    endpoint_errors_m: tuple[float, float]
    endpoint_tolerance_m: float


def _endpoint_errors(
    trajectory: JointTrajectory, generated: GeneratedTrajectory, arm: PlanarArm
) -> tuple[float, float]:
    points = generated.path.points_m
    tips = arm.end_effector_planar(trajectory.q(np.array([0.0, trajectory.duration_s])))
    errors = np.linalg.norm(tips - np.array([points[0], points[-1]]), axis=1) + ENDPOINT_SLACK_M
    return float(errors[0]), float(errors[1])


def certify_answer_execution(
    generated: GeneratedTrajectory,
    trajectory: JointTrajectory,
    arm: PlanarArm,
    limits: ArmLimits,
    endpoint_tolerance_m: float,
    timing: PaperTiming | ShortestRestToRest = PAPER_TIMING,
    tight: bool = False,
    map_endpoint_bound_m: float | None = None,
) -> Execution:
    """Certify that ``trajectory`` (the answer for ``generated``'s obstacle, certified collision-free)
    ends within the tolerance and, with ``timing``, keeps ``limits`` (module docstring).

    Raises:
        ExecutionRefusedError: a check fails; its reasons name the joint, the bound, the limit and
            the excess (for the paper timing, also the rest-to-rest duration that would keep them).
    """
    size = (generated.length_m, generated.width_m)
    where = {"variables": dict(generated.variables)}  # the message names x (etc.) after L and W
    if map_endpoint_bound_m is not None and map_endpoint_bound_m <= endpoint_tolerance_m:
        errors = (map_endpoint_bound_m, map_endpoint_bound_m)
    else:
        errors = _endpoint_errors(trajectory, generated, arm)
    missed = [
        f"endpoint error at {name} {1e3 * error:.3f} mm > tolerance {1e3 * endpoint_tolerance_m:.3f} mm"
        for name, error in zip(("P1", "P5"), errors, strict=True)
        if error > endpoint_tolerance_m
    ]
    if missed:
        raise ExecutionRefusedError(*size, None, tuple(missed), **where)
    dynamics = dynamics_of(arm)
    decide = None if tight else limits
    if isinstance(timing, PaperTiming):
        paper_timed = TimedTrajectory(trajectory, PAPER_TIMING)
        paper = certify_execution(paper_timed, dynamics, decide)
        violations = paper.violations(limits)
        if violations:
            reasons = [str(v) for v in violations]
            if not any(v.quantity == "angle" for v in violations):
                reasons.append(_rest_to_rest_hint(trajectory, dynamics, limits))
            raise ExecutionRefusedError(*size, "paper", tuple(reasons), **where)
        return Execution(paper_timed, paper, limits, errors, endpoint_tolerance_m)
    if not isinstance(timing, ShortestRestToRest):
        raise InvalidParameterError("timing", type(timing).__name__, "PAPER_TIMING or REST_TO_REST")
    try:
        retimed = shortest_rest_to_rest(trajectory, dynamics, limits)
    except InvalidParameterError as exc:  # a limit binds at rest
        raise ExecutionRefusedError(*size, timing.name, (str(exc),), **where) from None
    for _ in range(RETIMING_TRIES):
        executed = TimedTrajectory(trajectory, retimed)
        certificate = certify_execution(executed, dynamics, decide)
        found = certificate.violations(limits)
        if not found:
            return Execution(executed, certificate, limits, errors, endpoint_tolerance_m)
        if any(v.quantity == "angle" for v in found):  # the same configurations under every timing
            angles = tuple(str(v) for v in found if v.quantity == "angle")
            raise ExecutionRefusedError(*size, timing.name, angles, **where)
        retimed = _slower(retimed)
    raise ExecutionRefusedError(*size, timing.name, tuple(str(v) for v in found), **where)


def execution_from_map(
    generated: GeneratedTrajectory,
    region_map: RegionMap | None,
    dynamics: PlanarDynamics,
    limits: ArmLimits,
    endpoint_tolerance_m: float,
    timing: PaperTiming | ShortestRestToRest = PAPER_TIMING,
) -> Execution | None:
    """The execution of the regression's answer ``generated`` read off the region map's leaf
    (module docstring), or None where the map does not decide it: no map or no execution bounds
    in it, another arm's limits or inertias, the obstacle outside the fitted range, an endpoint
    bound above the tolerance, or a leaf bound above a limit."""
    if region_map is None or region_map.execution is None or generated.endpoint_error_bound_m is None:
        return None
    bounds = region_map.execution
    if bounds.limits != limits or bounds.dynamics != dynamics:
        return None
    error = generated.endpoint_error_bound_m
    if error > endpoint_tolerance_m:
        return None
    if generated.variables or region_map.extra_index is not None:  # a map over (L, W, x, ...)
        names = tuple(name for name, _ in generated.variables)
        if names != region_map.axes[2:]:
            return None
        leaf = region_map.leaf_at(generated.length_m, generated.width_m, *(v for _, v in generated.variables))
    else:
        leaf = region_map.leaf_at(generated.length_m, generated.width_m)
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
    return Execution(executed, certificate, limits, (error, error), endpoint_tolerance_m)


def _slower(timing: RestToRestTiming) -> RestToRestTiming:
    scale = 0.9 * timing.speed_scale
    return replace(timing, speed_scale=scale, ramp_s=min(timing.ramp_s / 0.9, timing.path_duration_s / scale))


def _rest_to_rest_hint(trajectory: JointTrajectory, dynamics: PlanarDynamics, limits: ArmLimits) -> str:
    try:
        retimed = shortest_rest_to_rest(trajectory, dynamics, limits)
    except InvalidParameterError:  # no rest-to-rest timing keeps them either
        return "no rest-to-rest timing keeps the limits either"
    return f"the rest-to-rest timing keeps them in T' = {retimed.duration_s:.3f} s (T = {trajectory.duration_s:.3f} s)"


def retime(generated: GeneratedTrajectory, arm: PlanarArm, limits: ArmLimits, timing) -> TimedTrajectory:
    """``generated``'s trajectory with ``timing`` (PAPER_TIMING, or REST_TO_REST: the shortest
    rest-to-rest timing the closed-form bounds keep within ``limits``), without certifying it.

    Raises:
        ExecutionRefusedError: no rest-to-rest timing keeps the limits (one binds at rest).
    """
    trajectory = generated.trajectory
    if isinstance(timing, PaperTiming):
        return TimedTrajectory(trajectory, PAPER_TIMING)
    try:
        return TimedTrajectory(trajectory, shortest_rest_to_rest(trajectory, dynamics_of(arm), limits))
    except InvalidParameterError as exc:  # a limit binds at rest
        size = (generated.length_m, generated.width_m)
        raise ExecutionRefusedError(*size, "rest-to-rest", (str(exc),), variables=dict(generated.variables)) from None
