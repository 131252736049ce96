"""Did a build converge? Thresholds on the DOE optima and on the regression, and what missed them.

A PSO that ran too short (``python -m pipeline.build --iterations 2``) still returns *some*
parameters; regressed, they give a generator that misses P1 or P5 by decimetres. The build
therefore judges its own results before it writes them:

* **every DOE optimum keeps the margin**: its dense Coal clearance is at least the scene's
  margin. A family that pins the tip to P1 and P5 cannot do better than its end poses, so for
  such a family the requirement is the smaller of the margin and the clearance of the two end
  poses (with exact endpoints and W near 0.12 m the pose at P5 itself is within 8 mm of the
  obstacle; no trajectory of that family keeps 1 cm there, and that is not a convergence failure);
* **every DOE optimum ends near P1 and P5**: both endpoint errors at most
  :attr:`ConvergenceCriteria.endpoint_error_max_m` (10 mm by default: the default build's
  optima miss by at most 6.1 mm, a 2-iteration PSO's by 168 mm). The 2 mm endpoint tolerance
  of the build is the *regression's*, held over the whole fitted range; a DOE optimum is a
  compromise between tracking the path and keeping the margin and may miss by more;
* **the endpoint-constrained regression met its constraint**: SLSQP converged and the largest
  endpoint error on its grid is within the tolerance (plus 1 nm for rounding).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from pipeline.geometry.clearance import CoalClearance
from pipeline.model.arm import PlanarArm
from pipeline.model.scene import Scene
from pipeline.motion.trajectory import PARAMETER_NAMES, joint_angles
from pipeline.offline.experiment import ExperimentResult
from pipeline.offline.fitness import FitnessConfig, fitness_problem
from pipeline.validation import check_non_negative, check_positive

#: Rounding allowed above the regression's endpoint tolerance [m].
TOLERANCE_ROUNDING_M = 1e-9


@dataclass(frozen=True)
class ConvergenceCriteria:
    """Thresholds a build's results must meet to be written without ``--allow-unconverged``.

    Attributes:
        endpoint_error_max_m: Largest |tip(0) - P1| or |tip(T) - P5| of a DOE optimum [m].
        clearance_slack_m: How far a DOE optimum's dense clearance may fall below what is
            required of it (the margin, or the end poses' clearance) [m]; covers rounding.
    """

    endpoint_error_max_m: float = 0.010
    clearance_slack_m: float = 1e-6

    def __post_init__(self) -> None:
        check_positive("endpoint_error_max_m", self.endpoint_error_max_m)
        check_non_negative("clearance_slack_m", self.clearance_slack_m)


@dataclass(frozen=True)
class ConvergenceProblem:
    """One threshold a build's result missed.

    Attributes:
        test: The DOE experiment's Test number (1-based, Table 1 order), or None for the regression.
        length_m, width_m: The experiment's obstacle [m] (None for the regression).
        missed: What was missed, with the numbers.
    """

    test: int | None
    length_m: float | None
    width_m: float | None
    missed: str

    def __str__(self) -> str:
        if self.test is None:
            return f"regression: {self.missed}"
        return f"Test {self.test} (L = {self.length_m:.3f} m, W = {self.width_m:.3f} m): {self.missed}"


def end_pose_clearance_m(arm: PlanarArm, result: ExperimentResult, scene: Scene, fitness: FitnessConfig) -> float:
    """Smaller Coal clearance [m] of the optimum's poses at t = 0 and t = T."""
    problem = fitness_problem(arm, result.length_m, result.width_m, scene, fitness, result.family)
    full = np.array([result.parameters[name] for name in PARAMETER_NAMES])
    q = joint_angles(full, np.array([0.0, problem.path.duration_s]))
    return float(CoalClearance(arm, problem.obstacle).link_clearance(q).min())


def experiment_problems(
    results: Sequence[ExperimentResult],
    arm: PlanarArm,
    scene: Scene,
    fitness: FitnessConfig,
    criteria: ConvergenceCriteria,
) -> list[ConvergenceProblem]:
    """The DOE optima that miss the margin or the endpoint threshold, in Test order."""
    problems = []
    for test, result in enumerate(results, start=1):
        missed = []
        required_m, why = scene.margin_m, "the margin"
        if result.family.pins_endpoints and result.clearance_m < required_m - criteria.clearance_slack_m:
            pose_m = end_pose_clearance_m(arm, result, scene, fitness)
            if pose_m < required_m:
                required_m, why = pose_m, "the end poses' clearance"
        if result.clearance_m < required_m - criteria.clearance_slack_m:
            missed.append(f"clearance {result.clearance_m * 1e3:.2f} mm < {why} {required_m * 1e3:.2f} mm")
        worst_m = max(result.endpoint_error_start_m, result.endpoint_error_end_m)
        if not worst_m <= criteria.endpoint_error_max_m:
            missed.append(
                f"endpoint errors {result.endpoint_error_start_m * 1e3:.1f} mm at P1 and "
                f"{result.endpoint_error_end_m * 1e3:.1f} mm at P5 > {criteria.endpoint_error_max_m * 1e3:.1f} mm"
            )
        if missed:
            problems.append(ConvergenceProblem(test, result.length_m, result.width_m, "; ".join(missed)))
    return problems


def regression_problems(fit: Mapping) -> list[ConvergenceProblem]:
    """What the regression missed, from the ``fit`` block of a coefficients file (empty for a
    plain fit, which has no constraint to miss)."""
    report = fit.get("endpoint_constraint")
    if not report:
        return []
    tolerance_m, reached_m = report["tolerance_m"], report["grid_endpoint_error_max_m"]
    missed = []
    if not report.get("converged", False):
        missed.append("SLSQP did not converge")
    if not reached_m <= tolerance_m + TOLERANCE_ROUNDING_M:
        missed.append(
            f"endpoint error on the {report['grid_points']}x{report['grid_points']} grid {reached_m * 1e3:.2f} mm "
            f"> tolerance {tolerance_m * 1e3:.2f} mm"
        )
    return [ConvergenceProblem(None, None, None, "; ".join(missed))] if missed else []
