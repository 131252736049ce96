"""The build's first stage: the DOE (PSO + polish + dense Coal check per obstacle), the
convergence check (:mod:`pipeline.offline.convergence`) and the regression, in memory.

Every check that can fail on the configuration runs before the work: the configuration's
values (:class:`pipeline.build.config.BuildConfig` validates them on construction), the URDF,
and the path and inverse kinematics of every DOE obstacle and of the regression's endpoint grid.
"""

from __future__ import annotations

import hashlib
import json
import warnings
from dataclasses import asdict, dataclass

import numpy as np

from pipeline.build.config import SCENE_OPTIONS, BuildConfig
from pipeline.exceptions import EndpointConstraintWarning, InvalidParameterError
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
from pipeline.offline.doe import DoeData, doe_document, doe_from_json, load_doe, run_doe
from pipeline.offline.experiment import ExperimentResult, SolverConfig, score_parameters
from pipeline.offline.fitness import fitness_problem

__all__ = ["DOE_STAGE", "DoeFit", "fit_doe"]

#: Progress stage name of the DOE.
DOE_STAGE = "DOE"


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
        timing: The DOE's part of build_timing.json (per experiment, query counts).
    """

    experiments: tuple[ExperimentResult, ...]
    doe_document: dict
    doe_text: str
    doe: DoeData
    paper_rows: list[dict] | None
    coefficients: Coefficients
    problems: tuple[ConvergenceProblem, ...]
    timing: dict


def _check_before_work(config: BuildConfig, arm: PlanarArm) -> list:
    """Every obstacle's path and IK, and those of a grid over the range (where no end pose may
    collide), before any PSO; returns the grid's problems for the check after the regression."""
    solver = config.solver()
    for L, W in config.design().points():
        try:
            fitness_problem(arm, L, W, config.scene, solver.fitness, solver.family)
        except InvalidParameterError as exc:  # a scene value that does not fit this obstacle
            option = SCENE_OPTIONS.get(exc.name, f"--scene key {exc.name}")
            raise InvalidParameterError(option, exc.value, f"{exc.expected} (obstacle L = {L} m, W = {W} m)") from None
    grid = grid_problems(arm, config.scene, solver.fitness, solver.family, config.length_range_m, config.width_range_m)
    end_pose_collisions(grid)
    return grid


def _paper_rows(arm: PlanarArm, config: BuildConfig) -> list[dict] | None:
    """The paper's Table 2 rows scored on our fitness, if our design and scene are the paper's.

    The fitness is a function of the 8 parameters, so the comparison holds for either family."""
    if not config.scene.is_close(Scene()):
        return None
    paper = load_doe(paper_data_path("paper_table2_doe.json"))
    points = config.design().points()
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
        "levels": config.levels,
        "family": solver.family.name,
        "urdf": arm_file_name(arm),
        "urdf_sha256": sha256_file(arm.urdf_path),
        "pso": asdict(solver.pso),
        "fitness": solver.fitness.to_json(),
        "polish": solver.polish,
        "versions": package_versions(),
    }
    if config.acceleration_limits_rad_s2 is not None:
        provenance[ACCELERATION_LIMITS_KEY] = list(config.acceleration_limits_rad_s2)
    return provenance


def _timing_document(results: list[ExperimentResult], jobs: int) -> dict:
    """build_timing.json's DOE part (its totals are set by the build)."""
    return {
        "total_s": 0.0,
        "jobs": jobs,
        "experiments": [
            {
                "test": i + 1,
                "L": r.length_m,
                "W": r.width_m,
                "seconds": r.seconds,
                "coal_queries": r.coal_queries,
                "objective_evaluations": r.objective_evaluations,
            }
            for i, r in enumerate(results)
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
    grid = _check_before_work(config, arm)
    solver, design = config.solver(), config.design()
    total, done = len(design.points()), []
    report = None
    if progress is not None:
        progress(DOE_STAGE, 0, total)

        def report(_: ExperimentResult) -> None:
            done.append(1)
            progress(DOE_STAGE, len(done), total)

    results = run_doe(arm, design, config.scene, solver, int(config.seed), config.executor, progress=report)
    problems = experiment_problems(results, arm, config.scene, solver.fitness, config.criteria())

    provenance = _provenance(config, arm, solver)
    document = doe_document(results, design, config.scene, arm, solver, provenance, solver.fitness.elbow)
    paper_rows = _paper_rows(arm, config)
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
    with warnings.catch_warnings():
        # A constraint the fit did not meet is reported as a convergence problem, not a warning.
        warnings.simplefilter("ignore", EndpointConstraintWarning)
        coefficients, _ = fit_coefficients(
            doe,
            {"provenance": {**provenance, "doe_sha256": hashlib.sha256(doe_text.encode()).hexdigest()}},
            config.endpoint_constraint(),
        )
    problems += regression_problems(coefficients.extra["fit"])
    problems += regression_collisions(coefficients.predict_free, grid)
    if problems:
        coefficients = coefficients.marked_unconverged(problems)
    timing = _timing_document(results, config.workers)
    if config.scheduler is not None:
        timing["scheduler"] = config.scheduler
    return DoeFit(tuple(results), document, doe_text, doe, paper_rows, coefficients, tuple(problems), timing)
