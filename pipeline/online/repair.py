"""Certify-or-repair: the online generator that never returns an uncertified trajectory as safe.

0. Take the arm recorded with the coefficients (:func:`pipeline.online.arm_check.arm_for`), or
   refuse a given arm they were not fitted for (:func:`pipeline.online.arm_check.check_arm_matches`).
1. Generate the trajectory from the regression (:func:`pipeline.online.generator.generate`).
2. Certify it (:func:`pipeline.geometry.sinusoid_certificate.certify_trajectory`, adaptive, Coal): a
   rigorous lower bound on the clearance over the whole of [0, T]; by default it only decides
   whether the clearance exceeds the margin (``decide_above_m``), the fastest question; with
   ``RepairConfig(certificate_tolerance_m=...)`` it tightens the bound to that tolerance.
3. If the certified clearance is below the margin, repair: a short
   ``scipy.optimize.least_squares`` on the build's objective (Eq. 5 + clearance penalty),
   warm-started from the regression's parameters, its Jacobian one vectorised forward
   difference, stopped at the first point whose sampled clearance exceeds the margin by half
   the build's buffer, and bounded in wall time and evaluations; then certify again. Its wall
   time is returned (``CertifiedTrajectory.repair_seconds``).
4. Certify that it executes (:mod:`pipeline.online.execution`): endpoint errors within the
   tolerance, and, for the chosen timing (the paper's by default, or the shortest rest-to-rest
   timing within the limits), joint angles, speeds, accelerations and torques within the arm's
   limits over all of [0, T']. For the regression's own answer, the region map's leaf answers
   this at lookup cost where its bounds were made for this arm and keep the limits
   (:func:`pipeline.online.execution.execution_from_map`); the per-query certificate elsewhere.
5. Return the trajectory with its certificates, or raise NoCertifiedTrajectoryError (clearance)
   or ExecutionRefusedError (endpoints, limits) saying why.
   A refusal quotes a tight bound (within :data:`pipeline.geometry.motion_certificate.DEFAULT_TOLERANCE_M`
   of the sampled minimum) of the best trajectory tried, never a decide-mode bound, which only
   says "below the margin" and may lie far below the clearance.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares

from pipeline.certify.region_map import RegionMap
from pipeline.exceptions import InvalidParameterError, NoCertifiedTrajectoryError
from pipeline.geometry.clearance import COAL, ClearanceRoute, CoalClearance
from pipeline.geometry.motion_certificate import DEFAULT_TOLERANCE_M, Certificate
from pipeline.geometry.sinusoid_certificate import certify_trajectory
from pipeline.model.arm import PlanarArm
from pipeline.model.limits import ArmLimits
from pipeline.motion.near_optimal import NearOptimal
from pipeline.motion.rest_to_rest import ShortestRestToRest
from pipeline.motion.timed_trajectory import TimedTrajectory
from pipeline.motion.timing import PAPER_TIMING, PaperTiming
from pipeline.motion.trajectory import JointTrajectory
from pipeline.offline.coefficients import Coefficients
from pipeline.offline.fitness import FitnessConfig, FitnessProblem, fitness_problem
from pipeline.online.arm_check import check_arm_matches
from pipeline.online.execution import Execution, certify_answer_execution, execution_from_map
from pipeline.online.generator import ATTACHED, GeneratedTrajectory, _Attached, generate
from pipeline.online.query_state import state_of
from pipeline.online.tolerance import (
    endpoint_tolerance_of,
)
from pipeline.validation import check_non_negative, check_positive, check_positive_int


@dataclass(frozen=True)
class RepairConfig:
    """Settings of certify-or-repair.

    Attributes:
        margin_m: Certified clearance required [m]; None means the coefficients' scene margin.
        route: Clearance route of the certificate: COAL (canonical) or ANALYTIC.
        repair: Try a local repair when certification fails (else refuse at once).
        max_seconds: Wall-time budget of the repair's optimisation [s].
        max_evaluations: Budget of objective evaluations of the repair.
        fitness: Objective of the repair (the build's, by default).
        certificate_tolerance_m: None (default): the certificates only decide whether the clearance
            exceeds the margin and whether each limit is kept, and their bounds may lie well
            beyond the true extremes; a value [m]: the clearance bound is tightened to within that
            of the smallest sampled clearance, and the limit bounds to within 0.01 % of the
            sampled maxima (slower).
        endpoint_tolerance_m: Largest endpoint error accepted [m]; None: the coefficients' own
            (:func:`endpoint_tolerance_of`).
    """

    margin_m: float | None = None
    route: ClearanceRoute = COAL
    repair: bool = True
    max_seconds: float = 0.5
    max_evaluations: int = 400
    fitness: FitnessConfig = field(default_factory=FitnessConfig)
    certificate_tolerance_m: float | None = None
    endpoint_tolerance_m: float | None = None

    def __post_init__(self) -> None:
        if self.margin_m is not None:
            check_non_negative("margin_m", self.margin_m)
        check_positive("max_seconds", self.max_seconds)
        check_positive_int("max_evaluations", self.max_evaluations)
        if self.certificate_tolerance_m is not None:
            check_positive("certificate_tolerance_m", self.certificate_tolerance_m)
        if self.endpoint_tolerance_m is not None:
            check_non_negative("endpoint_tolerance_m", self.endpoint_tolerance_m)


@dataclass(frozen=True, eq=False)
class CertifiedTrajectory:
    """A trajectory with a certified clearance of at least the margin.

    Attributes:
        generated: The generator's output (obstacle, path, trajectory); after a repair its
            ``trajectory`` holds the repaired parameters.
        certificate: The per-query certificate of ``generated.trajectory``, or None where the
            range certificate already proves the margin (``certificate_source == "range"``).
        margin_m: The margin that was required [m].
        repaired: True if the regression's answer failed and a repair succeeded.
        regression_certificate: The per-query certificate of the regression's own answer (None as above).
        repair_seconds: Wall time spent repairing [s] (0 if none).
        execution: Endpoint errors, timing and limit bounds (:class:`pipeline.online.execution.Execution`).
    """

    generated: GeneratedTrajectory
    certificate: Certificate | None
    margin_m: float
    repaired: bool
    regression_certificate: Certificate | None
    repair_seconds: float
    execution: Execution | None = None

    @property
    def trajectory(self) -> JointTrajectory:
        """The certified joint path (the paper's sinusoids over the path time [0, T])."""
        return self.generated.trajectory

    @property
    def executed(self) -> TimedTrajectory:
        """The path with its certified timing: ``q``, ``dq``, ``ddq`` at executed times in [0, T']."""
        return self.execution.executed

    @property
    def duration_s(self) -> float:
        """T', the executed duration [s] (T for the paper timing)."""
        return self.execution.executed.duration_s

    @property
    def endpoint_errors_m(self) -> tuple[float, float]:
        """The measured |tip(0) - P1| and |tip(T) - P5| of the answer [m]."""
        return self.execution.endpoint_errors_m

    @property
    def endpoint_error_bounds_m(self) -> tuple[float, float]:
        """Proven bounds on |tip(0) - P1| and |tip(T) - P5| [m] (the map's, or the measured ones plus rounding)."""
        return self.execution.endpoint_error_bounds_m

    @property
    def certified_clearance_m(self) -> float:
        """Certified lower bound on the clearance over [0, T] [m]."""
        if self.certificate is None:
            return float(self.generated.certified_clearance_m)
        return self.certificate.certified_clearance_m

    @property
    def certificate_source(self) -> str:
        """Where the certified clearance comes from: "range" (the region map) or "query"."""
        return "query" if self.certificate is not None else str(self.generated.certificate_source)

    @property
    def execution_source(self) -> str:
        """Where the limit bounds come from: "range" (the region map's leaf) or "query"."""
        return self.execution.certificate.source


_DEFAULT_CONFIG = RepairConfig()
#: Relative forward-difference step of the repair's Jacobian (about sqrt of the float epsilon).
_FD_STEP = 1.5e-8


class _Stop(Exception):
    """Ends the repair's optimisation early (time budget spent, or the margin is cleared)."""


def batch_residuals(problem: FitnessProblem, free: np.ndarray) -> np.ndarray:
    """:meth:`FitnessProblem.residuals` of P points at once: free (P, k) -> (P, m), one vectorised pass."""
    full = problem.full_parameters(free)
    tracking = problem.tracking_errors(full) * np.sqrt(problem.weights)[:, None]
    penalty = np.sqrt(problem.config.penalty_weight) * problem.violations(full)
    return np.concatenate([tracking.reshape(len(free), -1), penalty.reshape(len(free), -1)], -1)


def _repair(
    generated: GeneratedTrajectory, arm: PlanarArm, coefficients: Coefficients, config: RepairConfig
) -> JointTrajectory:
    """A short local least-squares repair, warm-started at the regression's answer (module docstring).

    The Jacobian is a forward difference over all free parameters in one vectorised evaluation
    (:func:`batch_residuals`), and the stop test reads the clearance shortfalls off the residual
    vector itself, so each iteration costs two objective passes.
    """
    problem = fitness_problem(
        arm, generated.length_m, generated.width_m, generated.scene, config.fitness, coefficients.family
    )
    variables = coefficients.variables.values_of(generated.scene)  # e.g. the obstacle's centre x
    start = coefficients.predict_free(generated.length_m, generated.width_m, **variables)
    deadline = time.perf_counter() + config.max_seconds
    slack = 0.5 * config.fitness.margin_buffer_m
    tracking_size = problem.times_s.size * 2
    penalty_scale = math.sqrt(problem.config.penalty_weight)
    best = {"x": start, "cost": math.inf}

    def residuals(x: np.ndarray) -> np.ndarray:
        if time.perf_counter() > deadline:
            raise _Stop
        r = problem.residuals(x)
        cost = float(r @ r)
        if cost < best["cost"]:
            best["x"], best["cost"] = np.array(x), cost
        violation = r[tracking_size:].reshape(-1, 3) / penalty_scale
        if violation[:, :2].max() <= slack and not np.any(violation[:, 2]):
            # First point whose sampled clearance is within half the buffer of the penalty
            # margin (so above the margin itself): the certificate decides if it is enough.
            best["x"] = np.array(x)
            raise _Stop
        return r

    def jacobian(x: np.ndarray) -> np.ndarray:
        if time.perf_counter() > deadline:
            raise _Stop
        steps = _FD_STEP * np.maximum(1.0, np.abs(x))
        values = batch_residuals(problem, np.vstack([x, x + np.diag(steps)]))
        return ((values[1:] - values[0]) / steps[:, None]).T

    lower, upper = coefficients.family.polish_bounds()
    try:
        least_squares(
            residuals,
            np.clip(start, lower, upper),
            jac=jacobian,
            method="trf",
            x_scale="jac",
            bounds=(lower, upper),
            max_nfev=config.max_evaluations,
        )
    except _Stop:
        pass
    full = problem.full_parameters(coefficients.family.canonical_free(best["x"]))
    return JointTrajectory(tuple(full), generated.duration_s)


def generate_certified(
    coefficients: Coefficients,
    length_m: float,
    width_m: float,
    arm: PlanarArm | None = None,
    *,
    x: float | None = None,
    d: float | None = None,
    out_of_range: str = "warn",
    config: RepairConfig | None = None,
    region_map: RegionMap | _Attached | None = ATTACHED,
    timing: PaperTiming | ShortestRestToRest | NearOptimal = PAPER_TIMING,
    limits: ArmLimits | None = None,
) -> CertifiedTrajectory:
    """Generate, certify and if needed repair the trajectory for the obstacle L x W [m].

    Args:
        coefficients: The regression coefficients.
        length_m, width_m: Obstacle size [m].
        x, d: The obstacle's centre x and far edge y [m], for coefficients that vary them (as
            :func:`pipeline.online.generator.generate`): the certificates and the repair then
            take the moved obstacle and path (``generated.scene``).
        arm: The arm; None (default): the one recorded with the coefficients
            (:func:`pipeline.online.arm_check.arm_for`); a given arm must be the one they were fitted for.
        out_of_range: As :func:`pipeline.online.generator.generate`.
        config: Margin, route, repair budget, certificate mode.
        region_map: The range certificate of the coefficients (default: the one attached to them,
            as :func:`pipeline.online.generator.generate`): inside a cell certified to keep at
            least the margin the answer is returned at once, its bound taken from the map; elsewhere
            the per-query certify-or-repair runs.
        timing: ``PAPER_TIMING`` (default: the paper's constant path speed from t = 0, the
            generator's own timing), ``NEAR_OPTIMAL`` (near time-optimal, smooth, at rest at both
            ends, :mod:`pipeline.motion.near_optimal`: what a controller should get) or
            ``REST_TO_REST`` (the paper's speed scaled, with smooth ramps, :mod:`pipeline.motion.timing`).
        limits: The limits to certify (default: the arm's URDF limits and the acceleration
            limits recorded with the coefficients, if the build was given any; the near-optimal
            timing fills in the servo defaults for acceleration and jerk where none is given,
            :meth:`pipeline.model.limits.ArmLimits.with_servo_defaults`).

    Raises:
        InvalidParameterError: ``config`` is not a RepairConfig, ``arm`` not a PlanarArm.
        DataFileError: ``arm`` is None and the recorded arm's URDF is missing.
        ArmMismatchError: the arm's link lengths or radii differ from the coefficients'.
        NoCertifiedTrajectoryError: neither the regression's answer nor its repair has a
            certified clearance of at least the margin.
        ExecutionRefusedError: the certified trajectory misses an endpoint by more than the
            tolerance, or breaks a limit of the arm with this timing (the reasons name each).
        InvalidParameterError, UnreachableObstacleError, OutOfFittedRangeError: as
            :func:`pipeline.online.generator.generate`.
    """
    config = _DEFAULT_CONFIG if config is None else config
    if not isinstance(config, RepairConfig):
        raise InvalidParameterError("config", type(config).__name__, "a RepairConfig or None")
    generated = generate(coefficients, length_m, width_m, x=x, d=d, out_of_range=out_of_range, region_map=region_map)
    state = state_of(coefficients)
    if arm is None:
        arm = state.arm
    else:
        check_arm_matches(coefficients, arm)
    if not isinstance(timing, PaperTiming | ShortestRestToRest | NearOptimal):
        raise InvalidParameterError("timing", type(timing).__name__, "PAPER_TIMING, REST_TO_REST or NEAR_OPTIMAL")
    if limits is None:
        limits = state.limits_of(arm)
    elif not isinstance(limits, ArmLimits):
        raise InvalidParameterError("limits", type(limits).__name__, "an ArmLimits or None")
    answer = _certify_clearance(generated, coefficients, arm, config)
    return _with_execution(answer, coefficients, arm, config, timing, limits, region_map)


def _with_execution(answer, coefficients, arm, config, timing, limits, region_map) -> CertifiedTrajectory:
    """``answer`` (certified collision-free) with its execution certified: from the map's leaf where
    it decides it, else per query (:mod:`pipeline.online.execution`)."""
    tolerance = (
        endpoint_tolerance_of(coefficients) if config.endpoint_tolerance_m is None else config.endpoint_tolerance_m
    )
    if not answer.repaired:
        execution = execution_from_map(
            answer.generated,
            coefficients.region_map if region_map is ATTACHED else region_map,
            arm,
            limits,
            tolerance,
            timing,
        )
        if execution is not None:
            return replace(answer, execution=execution)
    from_map = answer.generated.endpoint_error_bound_m if not answer.repaired else None
    execution = certify_answer_execution(
        answer.generated,
        answer.trajectory,
        arm,
        limits,
        tolerance,
        timing,
        tight=config.certificate_tolerance_m is not None,
        map_endpoint_bound_m=from_map,
    )
    return replace(answer, execution=execution)


def _certify_clearance(
    generated: GeneratedTrajectory, coefficients: Coefficients, arm: PlanarArm, config: RepairConfig
) -> CertifiedTrajectory:
    """Steps 2-3 of the module docstring: the clearance certified >= the margin, repairing if needed."""
    margin = coefficients.scene.margin_m if config.margin_m is None else config.margin_m
    if (
        generated.certificate_source is not None
        and generated.range_status == "margin"
        and generated.certified_clearance_m >= margin
    ):
        return CertifiedTrajectory(generated, None, margin, False, None, 0.0)

    def certify(trajectory: JointTrajectory) -> Certificate:
        if config.certificate_tolerance_m is None:
            return certify_trajectory(trajectory, arm, generated.obstacle, route=config.route, decide_above_m=margin)
        return certify_trajectory(
            trajectory, arm, generated.obstacle, route=config.route, tolerance_m=config.certificate_tolerance_m
        )

    first = certify(generated.trajectory)
    if first.certified_clearance_m >= margin:
        return CertifiedTrajectory(generated, first, margin, False, first, 0.0)
    variables = dict(generated.variables)  # the message names x (etc.) after L and W
    if not config.repair:
        raise NoCertifiedTrajectoryError(
            generated.length_m,
            generated.width_m,
            _tight(first, generated, arm, config),
            margin,
            "repair disabled",
            variables,
        )
    started = time.perf_counter()
    repaired = _repair(generated, arm, coefficients, config)
    seconds = time.perf_counter() - started
    second = certify(repaired)
    if second.certified_clearance_m >= margin:
        fixed = replace(generated, trajectory=repaired)
        return CertifiedTrajectory(fixed, second, margin, True, first, seconds)
    best = max(
        _tight(first, generated, arm, config),
        _tight(second, replace(generated, trajectory=repaired), arm, config),
    )
    raise NoCertifiedTrajectoryError(
        generated.length_m,
        generated.width_m,
        best,
        margin,
        _refusal_reason(generated, arm, coefficients, margin),
        variables,
    )


def _tight(certificate: Certificate, generated: GeneratedTrajectory, arm: PlanarArm, config: RepairConfig) -> float:
    """The certified clearance of ``generated`` to quote in a refusal [m]: ``certificate``'s if it
    was tightened, else a tight certificate's (a decide-mode bound below the margin only says so)."""
    if config.certificate_tolerance_m is not None:
        return certificate.certified_clearance_m
    tight = certify_trajectory(
        generated.trajectory, arm, generated.obstacle, route=config.route, tolerance_m=DEFAULT_TOLERANCE_M
    )
    return tight.certified_clearance_m


def _refusal_reason(generated: GeneratedTrajectory, arm: PlanarArm, coefficients: Coefficients, margin: float) -> str:
    """Why the repair could not reach the margin, in words that group well across cases."""
    family = coefficients.family
    if family.pins_endpoints:
        # The family pins the poses at P1 and P5: if one of them is closer than the margin,
        # no trajectory of the family can keep it.
        ends = np.array([0.0, generated.duration_s])
        clearance = CoalClearance(arm, generated.obstacle).link_clearance(generated.trajectory.q(ends))
        closest = clearance.min(axis=1)
        if closest.min() < margin:
            name = "P1" if closest[0] <= closest[1] else "P5"
            return f"the end pose at {name}, fixed by the {family.name} family, is closer than the margin"
    return "the repair did not reach the margin"
