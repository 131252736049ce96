"""The build's first stage: the DOE (PSO + polish + dense Coal check per obstacle), the
convergence check (:mod:`pipeline.offline.convergence`) and the regression, in memory.

Every check that can fail on the configuration runs before the work: the configuration's
values (:class:`pipeline.build.config.BuildConfig` validates them on construction), the URDF,
and the path and inverse kinematics of every DOE obstacle and of the regression's endpoint grid.

A DOE over more scene variables than (L, W) (``BuildConfig.vary``, e.g. the obstacle's centre
x) solves each run in its moved scene, checks each run and a grid over the whole box (every
extra variable at :data:`EXTRA_GRID_POINTS` levels) before the work, and regresses the full
quadratic in the k variables (:func:`fit_variables`), with the endpoint constraint on a coarser
grid per variable (``endpoint_regression.K_ENDPOINT_GRID``: grid_points^k obstacles in all).
"""

from __future__ import annotations

import hashlib
import itertools
import json
import time
import warnings
from dataclasses import asdict, dataclass, replace

import numpy as np

from pipeline.build.config import OPTIONS, SCENE_OPTIONS, BuildConfig
from pipeline.exceptions import EndpointConstraintWarning, InvalidParameterError, UnreachableObstacleError
from pipeline.io.jsonio import dumps
from pipeline.io.progress import ProgressCallback
from pipeline.io.provenance import package_versions, sha256_file
from pipeline.model.arm import ARM_FILE_NAME, DEFAULT_URDF, PlanarArm
from pipeline.model.limits import ACCELERATION_LIMITS_KEY
from pipeline.model.scene import Scene
from pipeline.motion.trajectory import PARAMETER_NAMES
from pipeline.offline.coefficients import (
    CONVERGED_KEY,
    UNCONVERGED_REASONS_KEY,
    Coefficients,
    fit_coefficients,
    fit_over_variables,
    paper_data_path,
)
from pipeline.offline.convergence import (
    ConvergenceProblem,
    end_pose_collisions,
    experiment_problems,
    grid_problems,
    regression_collisions,
    regression_problems,
)
from pipeline.offline.designs import ScaledDesign
from pipeline.offline.doe import DoeData, doe_document, doe_from_json, load_doe, run_doe
from pipeline.offline.endpoint_regression import EndpointConstraint, endpoint_targets
from pipeline.offline.experiment import ExperimentResult, SolverConfig, score_parameters
from pipeline.offline.fitness import FitnessProblem, fitness_problem
from pipeline.offline.variables import SIZE

__all__ = ["DOE_STAGE", "DoeFit", "check_before_work", "fit_doe", "fit_variables", "grid_collisions"]

#: Progress stage name of the DOE.
DOE_STAGE = "DOE"
#: Levels of each variable beyond L and W in the grid checked before the work and for collisions
#: of the regressed trajectories (the (L, W) grid keeps its 21 x 21).
EXTRA_GRID_POINTS = 5

#: One group of the grid: the extra variables' values and the (L, W) grid's problems in that scene.
_GridGroup = tuple[dict[str, float], list[FitnessProblem]]


@dataclass(frozen=True, eq=False)
class DoeFit:
    """The DOE and its regression, not yet written.

    Attributes:
        experiments: The DOE optima in Table 1 order.
        doe_document: The doe.json document; ``doe_text`` its file content.
        doe: The DOE as read back from ``doe_text`` (what the regression and refit see).
        paper_rows: The paper's Table 2 scored on our fitness (None unless the design and scene are the paper's).
        coefficients: The regressed coefficients (marked if the build did not converge).
        problems: What missed the convergence thresholds (empty: converged).
        collision_grid: The grid on which the written coefficients' trajectories must not collide,
            when that check waits for the certifiable regression (its coefficients are the ones
            written; the first fit may cross an obstacle its constraints then move it off);
            empty when the check ran on these coefficients.
        timing: The DOE's part of build_timing.json: the wall times [s] of its stages
            (``stages_s``: ``checks``, the checks before the work and of its results; ``doe``;
            ``regression``), per experiment, query counts.
    """

    experiments: tuple[ExperimentResult, ...]
    doe_document: dict
    doe_text: str
    doe: DoeData
    paper_rows: list[dict] | None
    coefficients: Coefficients
    problems: tuple[ConvergenceProblem, ...]
    timing: dict
    collision_grid: tuple[_GridGroup, ...] = ()


def _run_problem(arm: PlanarArm, config: BuildConfig, values: dict[str, float]) -> FitnessProblem:
    """The objective's problem of one run (its path and IK checked), errors naming the option."""
    solver = config.solver()
    L, W = values["L"], values["W"]
    extra = {name: value for name, value in values.items() if name not in SIZE}
    scene = config.variables.scene_for(config.scene, extra)
    try:
        return fitness_problem(arm, L, W, scene, solver.fitness, solver.family)
    except UnreachableObstacleError as exc:
        if not extra:
            raise
        where = ", ".join(f"{name} = {value} m" for name, value in values.items())
        raise _unreachable_range(config, f"obstacle {where}: {exc}") from None
    except InvalidParameterError as exc:  # a scene value that does not fit this obstacle
        option = SCENE_OPTIONS.get(exc.name, f"--scene key {exc.name}")
        where = ", ".join(f"{name} = {value} m" for name, value in values.items())
        raise InvalidParameterError(option, exc.value, f"{exc.expected} (obstacle {where})") from None


def _unreachable_range(config: BuildConfig, why: str) -> InvalidParameterError:
    """The one-line error of ``--vary`` ranges the arm cannot reach."""
    ranges = " ".join(f"{f.name} {f.range_m[0]} {f.range_m[1]}" for f in config.design.vary)
    return InvalidParameterError(OPTIONS["vary"], ranges, f"a range the arm reaches ({why})")


def _grid_groups(config: BuildConfig, arm: PlanarArm) -> list[_GridGroup]:
    """The (L, W) grid over the range in the scene of every combination of the extra variables'
    :data:`EXTRA_GRID_POINTS` levels (one group, the base scene, for (L, W))."""
    solver, variables = config.solver(), config.variables
    ranges = config.design.scaled_design().ranges_m
    axes = [np.linspace(*ranges[name], EXTRA_GRID_POINTS) for name in variables.extra]
    groups = []
    for combination in itertools.product(*axes):
        values = {name: float(v) for name, v in zip(variables.extra, combination, strict=True)}
        scene = variables.scene_for(config.scene, values)
        try:
            problems = grid_problems(
                arm, scene, solver.fitness, solver.family, config.design.length_range_m, config.design.width_range_m
            )
        except UnreachableObstacleError as exc:
            if not values:
                raise
            where = ", ".join(f"{name} = {value} m" for name, value in values.items())
            raise _unreachable_range(config, f"the (L, W) range at {where}: {exc}") from None
        groups.append((values, problems))
    return groups


def check_before_work(config: BuildConfig, arm: PlanarArm) -> list[_GridGroup]:
    """Every run's path and IK, and those of a grid over the range (where no end pose may
    collide), before any PSO; returns the grid for the check after the regression. Over more
    variables than (L, W), the regression's endpoint grid too."""
    design = config.design.scaled_design()
    for values in design.runs():
        _run_problem(arm, config, values)
    groups = _grid_groups(config, arm)
    end_pose_collisions([problem for _, problems in groups for problem in problems])
    constraint = _endpoint_constraint(config)
    if constraint is not None and not config.variables.is_size_only:
        try:
            endpoint_targets(
                design.ranges_m, config.scene, arm.link_lengths_m, constraint.grid_points, config.variables
            )
        except UnreachableObstacleError as exc:
            raise _unreachable_range(config, f"the regression's endpoint grid: {exc}") from None
    return groups


def _endpoint_constraint(config: BuildConfig) -> EndpointConstraint | None:
    """The regression's endpoint constraint, on the coarser grids over more variables than (L, W)
    (:meth:`pipeline.offline.endpoint_regression.EndpointConstraint.for_variables`)."""
    constraint = config.endpoint_constraint()
    return None if constraint is None else constraint.for_variables(config.variables)


def _paper_rows(arm: PlanarArm, config: BuildConfig) -> list[dict] | None:
    """The paper's Table 2 rows scored on our fitness, if our design and scene are the paper's.

    The fitness is a function of the 8 parameters, so the comparison holds for either family."""
    if not config.scene.is_close(Scene()) or not config.variables.is_size_only:
        return None
    paper = load_doe(paper_data_path("paper_table2_doe.json"))
    points = config.design.scaled_design().points()
    if len(points) != len(paper.lengths_m) or not np.allclose(points, np.c_[paper.lengths_m, paper.widths_m]):
        return None
    rows = []
    for (L, W), params in zip(points, paper.parameters, strict=True):
        score = score_parameters(arm, L, W, config.scene, config.solver(), params)
        rows.append({"L": L, "W": W, "parameters": dict(zip(PARAMETER_NAMES, params, strict=True)), **score})
    return rows


def arm_file_name(arm: PlanarArm) -> str:
    """The name the coefficients record for the arm's URDF: the shipped file's name, or
    :data:`pipeline.model.arm.ARM_FILE_NAME` for any other URDF (copied beside them by the build)."""
    digest = sha256_file(arm.urdf_path)
    return arm.urdf_path.name if digest == sha256_file(DEFAULT_URDF) else ARM_FILE_NAME


def _provenance(config: BuildConfig, arm: PlanarArm, solver: SolverConfig) -> dict:
    """The provenance block of doe.json and coefficients.json (no timestamps: deterministic); the
    arm's acceleration limits, when given, are recorded there too."""
    provenance = {
        "seed": int(config.seed),
        "levels": config.design.levels,
        "family": solver.family.name,
        "urdf": arm_file_name(arm),
        "urdf_sha256": sha256_file(arm.urdf_path),
        "pso": asdict(solver.pso),
        "fitness": solver.fitness.to_json(),
        "polish": solver.polish,
        "versions": package_versions(),
    }
    design = config.design.scaled_design()
    if not (design.variables.is_size_only and design.kind == "full-factorial"):  # the paper's: no key
        provenance["design"] = design.kind
        provenance["variables"] = list(design.variables.names)
    if config.acceleration_limits_rad_s2 is not None:
        provenance[ACCELERATION_LIMITS_KEY] = list(config.acceleration_limits_rad_s2)
    return provenance


def _timing_document(results: list[ExperimentResult], jobs: int, design: ScaledDesign) -> dict:
    """build_timing.json's DOE part but its stages (the build adds the total)."""
    extra = design.variables.extra
    return {
        "jobs": jobs,
        "experiments": [
            {
                "test": i + 1,
                "L": r.length_m,
                "W": r.width_m,
                **{name: values[name] for name in extra},
                "seconds": r.seconds,
                "coal_queries": r.coal_queries,
                "objective_evaluations": r.objective_evaluations,
            }
            for i, (r, values) in enumerate(zip(results, design.runs(), strict=True))
        ],
        "coal_queries": int(sum(r.coal_queries for r in results)),
        "objective_evaluations": int(sum(r.objective_evaluations for r in results)),
    }


def fit_doe(config: BuildConfig, arm: PlanarArm, progress: ProgressCallback | None = None) -> DoeFit:
    """Run the DOE and regress it, in memory.

    Args:
        config: What to build.
        arm: The arm of ``config.urdf_path``.
        progress: Called with (:data:`DOE_STAGE`, experiments done, experiments in all) once
            every check has passed (0 done) and after each experiment.

    Raises:
        InvalidParameterError, UnreachableObstacleError, InfeasibleSceneError: a DOE obstacle
            the arm cannot pass or whose end pose collides (before any work).
    """
    started = time.perf_counter()
    grid = check_before_work(config, arm)
    checks_s = time.perf_counter() - started
    solver, design = config.solver(), config.design.scaled_design()
    total, done = len(design.points()), []
    report = None
    if progress is not None:
        progress(DOE_STAGE, 0, total)

        def report(_: ExperimentResult) -> None:
            done.append(1)
            progress(DOE_STAGE, len(done), total)

    started = time.perf_counter()
    results = run_doe(arm, design, config.scene, solver, int(config.seed), config.execution.executor, progress=report)
    doe_s = time.perf_counter() - started
    started = time.perf_counter()
    problems = _experiment_problems(results, design, arm, config)
    paper_rows = _paper_rows(arm, config)
    checks_s += time.perf_counter() - started

    provenance = _provenance(config, arm, solver)
    document = doe_document(results, design, config.scene, arm, solver, provenance, solver.fitness.elbow)
    if paper_rows is not None:
        for row, paper in zip(document["experiments"], paper_rows, strict=True):
            row["paper_table2"] = {k: paper[k] for k in ("fitness", "clearance_m")}
            row["beats_paper"] = bool(row["fitness"] < paper["fitness"])
    if problems:  # the DOE's own problems; the regression's go into the coefficients only
        document[CONVERGED_KEY] = False
        document[UNCONVERGED_REASONS_KEY] = [str(p) for p in problems]
    doe_path = config.out_folder / "doe.json"
    doe_text = dumps(document)
    doe = doe_from_json(json.loads(doe_text), str(doe_path))
    extra = {"provenance": {**provenance, "doe_sha256": hashlib.sha256(doe_text.encode()).hexdigest()}}
    started = time.perf_counter()
    with warnings.catch_warnings():
        # A constraint the fit did not meet is reported as a convergence problem, not a warning.
        warnings.simplefilter("ignore", EndpointConstraintWarning)
        if doe.variables.is_size_only:
            coefficients, _ = fit_coefficients(doe, extra, config.endpoint_constraint())
        else:
            coefficients = fit_variables(doe, design.ranges_m, extra, _endpoint_constraint(config))
    regression_s = time.perf_counter() - started
    started = time.perf_counter()
    problems += regression_problems(coefficients.extra["fit"])
    collision_grid = tuple(grid)
    if problems or not config.certifiable_refit:  # otherwise the refit's coefficients are written: checked after it
        problems += grid_collisions(coefficients, collision_grid)
        collision_grid = ()
    if problems:
        coefficients = coefficients.marked_unconverged(problems)
    checks_s += time.perf_counter() - started
    stages = {"checks": checks_s, "doe": doe_s, "regression": regression_s}
    timing = {"stages_s": stages, **_timing_document(results, config.execution.workers, design)}
    if config.execution.scheduler is not None:
        timing["scheduler"] = config.execution.scheduler
    return DoeFit(
        tuple(results), document, doe_text, doe, paper_rows, coefficients, tuple(problems), timing, collision_grid
    )


def grid_collisions(coefficients: Coefficients, grid: tuple[_GridGroup, ...]) -> list[ConvergenceProblem]:
    """The sampled collision check of ``coefficients`` on ``grid`` (:func:`check_before_work`'s
    groups): one problem per group whose trajectories collide, naming the group's values."""
    problems = []
    for values, group in grid:
        collisions = regression_collisions(lambda L, W, v=values: coefficients.predict_free(L, W, **v), group)
        where = ", ".join(f"{name} = {value:.3f} m" for name, value in values.items())
        problems += [replace(p, missed=f"at {where}: {p.missed}") if where else p for p in collisions]
    return problems


def _experiment_problems(
    results: list[ExperimentResult], design: ScaledDesign, arm: PlanarArm, config: BuildConfig
) -> list[ConvergenceProblem]:
    """:func:`pipeline.offline.convergence.experiment_problems`, each run checked in its own scene."""
    solver, criteria = config.solver(), config.regression.criteria()
    if design.variables.is_size_only:
        return experiment_problems(results, arm, config.scene, solver.fitness, criteria)
    problems = []
    for test, (result, values) in enumerate(zip(results, design.runs(), strict=True), start=1):
        scene = design.variables.scene_for(config.scene, {k: v for k, v in values.items() if k not in SIZE})
        for problem in experiment_problems([result], arm, scene, solver.fitness, criteria):
            where = ", ".join(f"{name} = {values[name]:.3f} m" for name in design.variables.extra)
            problems.append(replace(problem, test=test, missed=f"{problem.missed} ({where})"))
    return problems


def fit_variables(
    doe: DoeData,
    ranges_m: dict[str, tuple[float, float]],
    extra: dict | None = None,
    endpoint_constraint: EndpointConstraint | None = None,
) -> Coefficients:
    """Regress a DOE over k scene variables (``doe.variables``, L and W among them) into
    coefficients over those variables, fitted on the design's box:
    :func:`pipeline.offline.coefficients.fit_over_variables`, the route of every fit.

    Args:
        doe: The DOE as read back from its file.
        ranges_m: The fitted range, (lo, hi) per variable [m] (the design's box).
        extra: More top-level keys of the coefficients (provenance).
        endpoint_constraint: The endpoint constraint (paper family), or None for the plain fit.
    """
    coefficients, _ = fit_over_variables(doe, doe.variables, ranges_m, extra, endpoint_constraint)
    return coefficients
