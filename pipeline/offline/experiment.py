"""One DOE experiment: the best sinusoid parameters for one obstacle (L, W).

PSO (:mod:`pipeline.offline.pso`) searches the family's free parameters on the fitness of
:mod:`pipeline.offline.fitness`; every restart's best point is then polished by
``scipy.optimize.least_squares`` on the same objective (written as residuals) and the best
polished point wins. The winner is mapped to the canonical form of Eq. 8 and checked on a
dense time grid with the canonical Pinocchio + Coal route. If that dense clearance falls
below the scene's margin, the polish is repeated with the penalty margin raised by the
shortfall and the penalty weight multiplied by 100 (at most ``margin_retries`` times),
kept only if the clearance improves: where the margin is geometrically out of reach (with
exact endpoints, the pose at P5 itself can be closer than the margin) the result says so in
``clearance_m`` instead of trading tracking for nothing. The reported fitness is always on
the configured objective.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares

from pipeline.geometry.clearance import CoalClearance
from pipeline.model.arm import PlanarArm
from pipeline.model.scene import Scene
from pipeline.motion.families import PAPER, TrajectoryFamily
from pipeline.motion.trajectory import PARAMETER_NAMES, joint_angles
from pipeline.offline.fitness import FitnessConfig, FitnessProblem, fitness_problem
from pipeline.offline.pso import PsoConfig, minimize
from pipeline.validation import check_non_negative, check_positive_int


@dataclass(frozen=True)
class SolverConfig:
    """How one experiment is solved.

    Attributes:
        family: The trajectory family (see :mod:`pipeline.motion.families`).
        fitness: Objective settings.
        pso: PSO settings.
        polish: Polish each PSO restart with least_squares.
        verify_samples: Time samples of the dense Coal clearance check.
        margin_retries: Re-polishes with a raised penalty margin if the dense check fails.
    """

    family: TrajectoryFamily = PAPER
    fitness: FitnessConfig = field(default_factory=FitnessConfig)
    pso: PsoConfig = field(default_factory=PsoConfig)
    polish: bool = True
    verify_samples: int = 2001
    margin_retries: int = 3

    def __post_init__(self) -> None:
        check_positive_int("verify_samples", self.verify_samples, minimum=2)
        check_non_negative("margin_retries", self.margin_retries)


@dataclass(frozen=True)
class ExperimentResult:
    """The optimum for one obstacle.

    Attributes:
        length_m, width_m: The obstacle L, W [m].
        family: Trajectory family.
        parameters: The 8 sinusoid parameters (rad, rad/s); canonical (Eq. 8) for the paper
            family; for exact-endpoints, joint 2's phase is the pinned one ((pi - w2 T) / 2 for
            an obstacle centred on the y axis).
        free_parameters: The family's free parameters, canonical (what the regression fits).
        fitness: Objective at the optimum (Eq. 5 + penalties) [m^2].
        tracking_fitness: Eq. 5 alone at the optimum [m^2].
        clearance_m: Minimum Coal clearance over ``verify_samples`` times [m].
        endpoint_error_start_m: |tip(0) - P1| [m].
        endpoint_error_end_m: |tip(T) - P5| [m].
        duration_s: T [s].
        solver: "pso" or "pso+least_squares" (which produced the result).
        pso_fitness: Best objective PSO reached before polishing [m^2].
        objective_evaluations: Objective evaluations by PSO and polish (analytic route).
        coal_queries: Coal distance queries made (dense check, plus any Coal-route fitness).
        seconds: Wall time of this experiment [s] (not part of the deterministic output).
    """

    length_m: float
    width_m: float
    family: TrajectoryFamily
    parameters: dict[str, float]
    free_parameters: dict[str, float]
    fitness: float
    tracking_fitness: float
    clearance_m: float
    endpoint_error_start_m: float
    endpoint_error_end_m: float
    duration_s: float
    solver: str
    pso_fitness: float
    objective_evaluations: int
    coal_queries: int
    seconds: float

    def to_json(self) -> dict:
        """The doe.json record of this experiment (without wall time)."""
        return {
            "L": self.length_m,
            "W": self.width_m,
            "parameters": dict(self.parameters),
            "free_parameters": dict(self.free_parameters),
            "fitness": self.fitness,
            "tracking_fitness": self.tracking_fitness,
            "clearance_m": self.clearance_m,
            "endpoint_error_start_m": self.endpoint_error_start_m,
            "endpoint_error_end_m": self.endpoint_error_end_m,
            "T_s": self.duration_s,
            "solver": self.solver,
            "pso_fitness": self.pso_fitness,
            "objective_evaluations": self.objective_evaluations,
            "coal_queries": self.coal_queries,
        }


def dense_coal_clearance(problem: FitnessProblem, full: np.ndarray, samples: int) -> tuple[float, int]:
    """Minimum Coal clearance [m] over ``samples`` uniform times in [0, T], and queries made."""
    checker = CoalClearance(problem.arm, problem.obstacle)
    times = np.linspace(0.0, problem.path.duration_s, samples)
    clearance = checker.link_clearance(joint_angles(full, times))
    return float(clearance.min()), checker.queries


def _polish(problem: FitnessProblem, starts: np.ndarray, evaluations: list[int]) -> tuple[np.ndarray, float]:
    """least_squares from each start, inside the search box but for the phases; the best result."""
    lower, upper = problem.family.polish_bounds()
    best_x, best_f = None, np.inf
    for start in starts:
        start = np.clip(start, lower, upper)
        result = least_squares(problem.residuals, start, method="trf", x_scale="jac", bounds=(lower, upper))
        evaluations.append(int(result.nfev) * (1 + start.size))
        value = float(problem.evaluate(result.x))
        if value < best_f:
            best_x, best_f = result.x, value
    return best_x, best_f


def solve_experiment(
    arm: PlanarArm,
    length_m: float,
    width_m: float,
    scene: Scene,
    config: SolverConfig,
    rng: np.random.Generator,
) -> ExperimentResult:
    """Find the best trajectory parameters for the obstacle L x W.

    Raises:
        InvalidParameterError: non-positive or NaN L or W.
        UnreachableObstacleError: the arm cannot reach the path around this obstacle.
    """
    start = time.perf_counter()
    problem = fitness_problem(arm, length_m, width_m, scene, config.fitness, config.family)
    lower, upper = config.family.search_bounds()
    swarm = minimize(problem.evaluate, lower, upper, rng, config.pso)
    evaluations = [swarm.evaluations]
    best_x, best_f, solver = swarm.x, swarm.value, "pso"
    if config.polish:
        polished_x, polished_f = _polish(problem, swarm.restart_x, evaluations)
        if polished_f < best_f:
            best_x, best_f, solver = polished_x, polished_f, "pso+least_squares"

    free = config.family.canonical_free(best_x)
    full = problem.full_parameters(free)
    clearance, queries = dense_coal_clearance(problem, full, config.verify_samples)
    coal_queries = queries
    retry = problem
    for _ in range(config.margin_retries):
        shortfall = scene.margin_m - clearance
        if shortfall <= 0 or not config.polish:
            break
        stiffer = replace(retry.config, penalty_weight=retry.config.penalty_weight * 100.0)
        retry = replace(retry, config=stiffer, penalty_margin_m=retry.penalty_margin_m + shortfall + 1e-4)
        retry_x, _ = _polish(retry, free[None, :], evaluations)
        retry_free = config.family.canonical_free(retry_x)
        retry_full = retry.full_parameters(retry_free)
        retry_clearance, queries = dense_coal_clearance(retry, retry_full, config.verify_samples)
        coal_queries += queries
        if retry_clearance <= clearance + 1e-6:
            break  # the margin is out of reach here (e.g. the endpoint pose itself is closer)
        free, full, clearance = retry_free, retry_full, retry_clearance

    errors = problem.tracking_errors(full)
    start_err, end_err = problem.endpoint_errors_m(full)
    return ExperimentResult(
        length_m=float(length_m),
        width_m=float(width_m),
        family=config.family,
        parameters=dict(zip(PARAMETER_NAMES, (float(v) for v in full), strict=True)),
        free_parameters=dict(zip(config.family.free_parameter_names, (float(v) for v in free), strict=True)),
        fitness=float(problem.evaluate(free)),
        tracking_fitness=float(np.sum(problem.weights * np.sum(errors * errors, axis=-1))),
        clearance_m=clearance,
        endpoint_error_start_m=start_err,
        endpoint_error_end_m=end_err,
        duration_s=problem.path.duration_s,
        solver=solver,
        pso_fitness=float(swarm.value),
        objective_evaluations=int(sum(evaluations)),
        coal_queries=int(coal_queries),
        seconds=time.perf_counter() - start,
    )


def score_parameters(
    arm: PlanarArm, length_m: float, width_m: float, scene: Scene, config: SolverConfig, parameters: np.ndarray
) -> dict[str, float]:
    """Our fitness, dense Coal clearance and endpoint errors of given 8 parameters (e.g. the
    paper's Table 2 row) at the obstacle L x W, on the paper family's objective."""
    problem = fitness_problem(arm, length_m, width_m, scene, config.fitness, PAPER)
    full = np.asarray(parameters, dtype=float)
    clearance, _ = dense_coal_clearance(problem, full, config.verify_samples)
    start_err, end_err = problem.endpoint_errors_m(full)
    return {
        "fitness": float(problem.evaluate(full)),
        "clearance_m": clearance,
        "endpoint_error_start_m": start_err,
        "endpoint_error_end_m": end_err,
    }
