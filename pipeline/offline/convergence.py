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
  :attr:`ConvergenceCriteria.endpoint_error_max_m`, 50 mm by default. The default build's
  optima miss by at most 6.1 mm; with the obstacle moved 2 cm towards the base
  (``top_y_m = 0.54``) the optima at W = 0.12 m miss P5 by up to 27 mm, a compromise between
  tracking and keeping the margin that a single sinusoid per joint cannot avoid; a PSO stopped
  after 2 iterations misses by 168 mm. The 2 mm endpoint tolerance of the build is the
  *regression's*, held over the whole fitted range, not the optima's;
* **the endpoint-constrained regression met its constraint**: SLSQP converged (or stopped at its
  iteration budget at an iterate that holds the fit tolerance on its grid, as the report's
  ``solver`` says) and the largest endpoint error on its grid and on its denser check grid is
  within the tolerance (plus 1 nm for rounding);
* **the regressed trajectories do not collide**: on a 21 x 21 grid over the fitted range, each
  trajectory the coefficients give has a positive clearance at 1001 uniform times (a sampled
  check, the configured clearance route; ``python -m verify.sweep`` certifies it in continuous
  time). Holding the endpoints within 2 mm moves the optima, and where the end pose is close to
  the obstacle it can move them into it. Where the build runs the certifiable regression, the
  check judges the coefficients it writes, the refit's, after it (:mod:`pipeline.build.run`):
  over (L, W, x, d) in the arm's window of d the first fit crosses the obstacle near the window's
  lower edge, and the refit's clearance constraints move it off.

Before any of that, :func:`end_pose_collisions` finds obstacles of the range where the pose at P1
or P5 itself collides (on the family's elbow branch): there no trajectory that ends at the
point is collision-free, and the build refuses to start (e.g. ``top_y_m = 0.54`` with W up to
0.12 m: the pose at P5 is 5.8 mm inside the obstacle's corner).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from pipeline.exceptions import InfeasibleSceneError
from pipeline.geometry.clearance import CoalClearance
from pipeline.model.arm import PlanarArm
from pipeline.model.scene import Scene
from pipeline.motion.families import TrajectoryFamily
from pipeline.motion.trajectory import PARAMETER_NAMES, joint_angles
from pipeline.offline.experiment import ExperimentResult
from pipeline.offline.fitness import FitnessConfig, FitnessProblem, fitness_problem
from pipeline.validation import check_non_negative, check_positive

#: Rounding allowed above the regression's endpoint tolerance [m].
TOLERANCE_ROUNDING_M = 1e-9
#: Obstacle sizes per axis of the grids over the fitted range (as the endpoint constraint's).
GRID_POINTS = 21
#: Uniform times per trajectory of the regression's sampled collision check.
COLLISION_SAMPLES = 1001


@dataclass(frozen=True)
class ConvergenceCriteria:
    """Thresholds a build's results must meet to be written without ``--allow-unconverged``.

    Attributes:
        endpoint_error_max_m: Largest |tip(0) - P1| or |tip(T) - P5| of a DOE optimum [m].
        clearance_slack_m: How far a DOE optimum's dense clearance may fall below what is
            required of it (the margin, or the end poses' clearance) [m]; covers rounding.
    """

    endpoint_error_max_m: float = 0.050
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
    tolerance_m = report["tolerance_m"]
    missed = []
    if not report.get("converged", False):
        missed.append("SLSQP did not converge")
    for points_key, max_key in (
        ("grid_points", "grid_endpoint_error_max_m"),
        ("check_grid_points", "check_grid_endpoint_error_max_m"),
    ):
        reached_m = report.get(max_key)
        if reached_m is not None and not reached_m <= tolerance_m + TOLERANCE_ROUNDING_M:
            points = report[points_key]
            missed.append(
                f"endpoint error on the {points}x{points} grid {reached_m * 1e3:.4f} mm > tolerance "
                f"{tolerance_m * 1e3:.2f} mm"
            )
    return [ConvergenceProblem(None, None, None, "; ".join(missed))] if missed else []


def grid_problems(
    arm: PlanarArm,
    scene: Scene,
    fitness: FitnessConfig,
    family: TrajectoryFamily,
    length_range_m: tuple[float, float],
    width_range_m: tuple[float, float],
    grid_points: int = GRID_POINTS,
) -> list[FitnessProblem]:
    """The objective's precomputed problem (path, IK context, clearance function) for every obstacle
    of a grid_points x grid_points grid over the range.

    Raises:
        UnreachableObstacleError: a grid obstacle's path leaves the arm's reach.
    """
    lengths = np.linspace(*length_range_m, grid_points)
    widths = np.linspace(*width_range_m, grid_points)
    return [fitness_problem(arm, L, W, scene, fitness, family) for W in widths for L in lengths]


def end_pose_collisions(problems: list[FitnessProblem]) -> None:
    """Refuse a range where the pose at P1 or P5 (inverse kinematics on the family's elbow
    branch) collides with the obstacle.

    Raises:
        InfeasibleSceneError: at least one such obstacle (the deepest one is named).
    """
    worst, count = None, 0
    for problem in problems:
        q = np.array([problem.context.theta_start_rad, problem.context.theta_end_rad])
        clearance = problem.clearance_at(q).min(axis=-1)
        if clearance.min() <= 0:
            count += 1
            index = int(np.argmin(clearance))
            if worst is None or clearance[index] < worst[3]:
                worst = (problem.obstacle.length_m, problem.obstacle.width_m, ("P1", "P5")[index], clearance[index])
    if worst is not None:
        raise InfeasibleSceneError(worst[0], worst[1], worst[2], float(worst[3]), count, len(problems))


def regression_collisions(free_at, problems: list[FitnessProblem]) -> list[ConvergenceProblem]:
    """The regressed trajectories that collide at :data:`COLLISION_SAMPLES` uniform times.

    Args:
        free_at: (L, W) [m] -> the family's free parameters the coefficients give there.
        problems: :func:`grid_problems` over the fitted range.
    """
    worst, count = None, 0
    for problem in problems:
        L, W = problem.obstacle.length_m, problem.obstacle.width_m
        full = problem.full_parameters(free_at(L, W))
        times = np.linspace(0.0, problem.path.duration_s, COLLISION_SAMPLES)
        clearance = float(problem.clearance_at(joint_angles(full, times)).min())
        if clearance <= 0:
            count += 1
            if worst is None or clearance < worst[2]:
                worst = (L, W, clearance)
    if worst is None:
        return []
    return [
        ConvergenceProblem(
            None,
            None,
            None,
            f"its trajectories collide at {count} of {len(problems)} grid obstacles (sampled clearance down to "
            f"{worst[2] * 1e3:.2f} mm at L = {worst[0]:.3f} m, W = {worst[1]:.3f} m)",
        )
    ]
