"""The whole offline pipeline as one library call: :func:`run_build` (:class:`BuildConfig`) ->
:class:`BuildResult`. ``python -m pipeline.build`` is a thin command line on it.

DOE (PSO + polish + dense Coal check per obstacle) -> convergence check
(:mod:`pipeline.offline.convergence`) -> regression -> ``doe.json`` and ``coefficients.json``
(written as a pair, atomically, deterministic for a seed whatever ``jobs``) and
``build_timing.json`` (wall times and query counts, which vary run to run).

Every check that can fail on the configuration runs before the work: the configuration's
values (:class:`BuildConfig` validates them on construction, naming the command-line option),
the output folder (writable, created only when the files are written), the URDF, and the path
and inverse kinematics of every DOE obstacle and of the regression's endpoint grid.

A build whose results miss the convergence thresholds writes nothing and raises
:class:`pipeline.exceptions.BuildNotConvergedError`, unless ``allow_unconverged``: then the
files are written and the coefficients marked (``"converged": false`` and the reasons), and
:func:`pipeline.offline.coefficients.load_coefficients` warns whenever such a file is loaded.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
import warnings
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from pipeline.exceptions import (
    BuildNotConvergedError,
    DataFileError,
    EndpointConstraintWarning,
    InvalidParameterError,
    PipelineError,
)
from pipeline.io.jsonio import dumps, write_json_atomic, write_text_atomic
from pipeline.io.output_paths import check_output_folder
from pipeline.io.provenance import package_versions, sha256_file
from pipeline.model.arm import DEFAULT_URDF, PlanarArm, load_planar_arm
from pipeline.model.scene import Scene, read_scene_file
from pipeline.motion.families import PAPER, TrajectoryFamily, family_from_name
from pipeline.motion.trajectory import PARAMETER_NAMES
from pipeline.offline.coefficients import (
    CONVERGED_KEY,
    UNCONVERGED_REASONS_KEY,
    Coefficients,
    fit_coefficients,
    paper_data_path,
)
from pipeline.offline.convergence import (
    ConvergenceCriteria,
    ConvergenceProblem,
    end_pose_collisions,
    experiment_problems,
    grid_problems,
    regression_collisions,
    regression_problems,
)
from pipeline.offline.doe import Design, doe_document, doe_from_json, load_doe, run_doe
from pipeline.offline.endpoint_regression import EndpointConstraint
from pipeline.offline.experiment import ExperimentResult, SolverConfig, score_parameters
from pipeline.offline.fitness import FitnessConfig, fitness_problem
from pipeline.offline.pso import PsoConfig

_PSO, _FITNESS, _CRITERIA = PsoConfig(), FitnessConfig(), ConvergenceCriteria()

#: Command-line option of each :class:`BuildConfig` field, named in error messages.
OPTIONS: dict[str, str] = {
    "out_folder": "--out",
    "seed": "--seed",
    "levels": "--levels",
    "length_range_m": "--L-range",
    "width_range_m": "--W-range",
    "family": "--family",
    "jobs": "--jobs",
    "urdf_path": "--urdf",
    "scene": "--scene",
    "swarm_size": "--swarm-size",
    "iterations": "--iterations",
    "restarts": "--restarts",
    "polish": "--no-polish",
    "n_points": "--n-points",
    "endpoint_weight": "--endpoint-weight",
    "penalty_weight": "--penalty-weight",
    "margin_buffer_m": "--margin-buffer",
    "endpoint_tolerance_m": "--endpoint-tolerance",
    "doe_endpoint_error_max_m": "--max-doe-endpoint-error",
    "allow_unconverged": "--allow-unconverged",
}
#: Command-line option of each scene field that has one; the others are set by ``--scene FILE``.
SCENE_OPTIONS: dict[str, str] = {
    "top_y_m": "--top-y",
    "start_y_m": "--start-y",
    "speed_m_s": "--speed",
    "margin_m": "--margin",
    "corner_radius_m": "--corner-radius",
}
# Names the sub-configurations use in their own errors -> the BuildConfig field.
_SUB_NAMES = {
    "L range": "length_range_m",
    "L range min": "length_range_m",
    "L range max": "length_range_m",
    "W range": "width_range_m",
    "W range min": "width_range_m",
    "W range max": "width_range_m",
    "tolerance_m": "endpoint_tolerance_m",
    "endpoint_error_max_m": "doe_endpoint_error_max_m",
}


def _renamed(exc: InvalidParameterError, option: str) -> InvalidParameterError:
    return InvalidParameterError(option, exc.value, exc.expected)


@dataclass(frozen=True)
class BuildConfig:
    """Everything a build needs; validated on construction (errors name the command-line option).

    Attributes:
        out_folder: Where doe.json, coefficients.json and build_timing.json go (created when
            they are written, not before).
        seed: Master random seed (integer >= 0); the same seed gives byte-identical doe.json
            and coefficients.json whatever ``jobs``.
        levels: K, levels per factor of the K x K design (>= 3).
        length_range_m, width_range_m: (min, max) of L and W [m].
        family: Trajectory family (object, or its name as on the command line).
        jobs: Worker processes (>= 1; does not change the result).
        urdf_path: URDF of the arm (None: the paper's arm shipped with the package).
        scene: The scene (obstacle placement, path, speed, margin); see :func:`scene_from_options`.
        swarm_size, iterations, restarts: PSO settings (:class:`pipeline.offline.pso.PsoConfig`).
        polish: Polish every PSO restart with least_squares.
        n_points, endpoint_weight, penalty_weight, margin_buffer_m: Objective settings
            (:class:`pipeline.offline.fitness.FitnessConfig`; margin buffer [m]).
        endpoint_tolerance_m: Endpoint tolerance of the regression [m] (paper family), or None
            for the plain least-squares fit (the paper's Eq. 9). Ignored by a family that pins
            the endpoints.
        doe_endpoint_error_max_m: Largest endpoint error of a DOE optimum for the build to
            count as converged [m] (:mod:`pipeline.offline.convergence`).
        allow_unconverged: Write the files (marked) even if the build did not converge.
    """

    out_folder: Path = Path("results")
    seed: int = 0
    levels: int = 3
    length_range_m: tuple[float, float] = (0.20, 0.30)
    width_range_m: tuple[float, float] = (0.08, 0.12)
    family: TrajectoryFamily | str = PAPER
    jobs: int = 1
    urdf_path: Path = DEFAULT_URDF
    scene: Scene = field(default_factory=Scene)
    swarm_size: int = _PSO.swarm_size
    iterations: int = _PSO.iterations
    restarts: int = _PSO.restarts
    polish: bool = True
    n_points: int = _FITNESS.n_points
    endpoint_weight: float = _FITNESS.endpoint_weight
    penalty_weight: float = _FITNESS.penalty_weight
    margin_buffer_m: float = _FITNESS.margin_buffer_m
    endpoint_tolerance_m: float | None = EndpointConstraint.tolerance_m
    doe_endpoint_error_max_m: float = _CRITERIA.endpoint_error_max_m
    allow_unconverged: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.out_folder, str | os.PathLike):
            raise InvalidParameterError(OPTIONS["out_folder"], self.out_folder, "a folder path")
        object.__setattr__(self, "out_folder", Path(self.out_folder))
        if self.urdf_path is None:
            object.__setattr__(self, "urdf_path", DEFAULT_URDF)
        if not isinstance(self.urdf_path, str | os.PathLike):
            raise InvalidParameterError(OPTIONS["urdf_path"], self.urdf_path, "a URDF file path")
        object.__setattr__(self, "urdf_path", Path(self.urdf_path))
        if isinstance(self.seed, bool) or not isinstance(self.seed, int | np.integer) or self.seed < 0:
            raise InvalidParameterError(OPTIONS["seed"], self.seed, "an integer >= 0")
        if isinstance(self.jobs, bool) or not isinstance(self.jobs, int) or self.jobs < 1:
            raise InvalidParameterError(OPTIONS["jobs"], self.jobs, "an integer >= 1")
        if isinstance(self.family, str):
            try:
                object.__setattr__(self, "family", family_from_name(self.family))
            except PipelineError:
                raise InvalidParameterError(OPTIONS["family"], self.family, "a trajectory family name") from None
        if not isinstance(self.family, TrajectoryFamily):
            raise InvalidParameterError(OPTIONS["family"], self.family, "a TrajectoryFamily or its name")
        if not isinstance(self.scene, Scene):
            raise InvalidParameterError(OPTIONS["scene"], self.scene, "a pipeline.model.scene.Scene")
        for name in ("polish", "allow_unconverged"):
            if not isinstance(getattr(self, name), bool):
                raise InvalidParameterError(OPTIONS[name], getattr(self, name), "True or False")
        # Build every sub-configuration once, so that a bad value fails here.
        self.design()
        self.solver()
        self.endpoint_constraint()
        self.criteria()

    @staticmethod
    def _named(build: Callable):
        """``build()``, with a sub-configuration's error renamed to the command-line option."""
        try:
            return build()
        except InvalidParameterError as exc:
            name = _SUB_NAMES.get(exc.name, exc.name)
            raise _renamed(exc, OPTIONS.get(name, name)) from None

    def design(self) -> Design:
        """The K x K design over (L, W)."""
        for name in ("length_range_m", "width_range_m"):
            value = getattr(self, name)
            if not isinstance(value, tuple | list) or len(value) != 2:
                raise InvalidParameterError(OPTIONS[name], value, "(min, max) [m]")
            object.__setattr__(self, name, tuple(value))
        return self._named(lambda: Design(self.levels, tuple(self.length_range_m), tuple(self.width_range_m)))

    def solver(self) -> SolverConfig:
        """PSO, polish and objective settings of every experiment."""
        pso = self._named(
            lambda: PsoConfig(swarm_size=self.swarm_size, iterations=self.iterations, restarts=self.restarts)
        )
        fitness = self._named(
            lambda: FitnessConfig(
                n_points=self.n_points,
                endpoint_weight=self.endpoint_weight,
                penalty_weight=self.penalty_weight,
                margin_buffer_m=self.margin_buffer_m,
            )
        )
        return SolverConfig(family=self.family, fitness=fitness, pso=pso, polish=self.polish)

    def endpoint_constraint(self) -> EndpointConstraint | None:
        """The regression's endpoint constraint, or None (plain fit, or a family exact by construction)."""
        if self.endpoint_tolerance_m is None:
            return None
        constraint = self._named(lambda: EndpointConstraint(tolerance_m=self.endpoint_tolerance_m))
        return None if self.family.pins_endpoints else constraint

    def criteria(self) -> ConvergenceCriteria:
        """The thresholds the results must meet."""
        return self._named(lambda: ConvergenceCriteria(endpoint_error_max_m=self.doe_endpoint_error_max_m))


def scene_from_options(scene_file: str | Path | None = None, **options: float | None) -> Scene:
    """The scene of a build: the defaults, then the keys of ``scene_file`` (TOML or JSON, keys
    as :data:`pipeline.model.scene.SCENE_FIELDS`), then the ``options`` that are not None
    (scene field name -> value, e.g. ``top_y_m=0.54``). Errors name the option or the file's key.

    Raises:
        DataFileError: the scene file is unreadable or has an unknown key or a non-number.
        InvalidParameterError: a value is out of its domain.
    """
    values: dict[str, float | None] = {}
    origin: dict[str, str] = {}
    if scene_file is not None:
        try:
            values.update(read_scene_file(scene_file))
        except DataFileError as exc:
            raise DataFileError(f"--scene {exc.path}", exc.reason) from None
        origin.update({key: f"--scene {scene_file}: {key}" for key in values})
    for key, value in options.items():
        if key not in SCENE_OPTIONS:
            raise InvalidParameterError("scene option", key, f"one of {', '.join(SCENE_OPTIONS)}")
        if value is not None:
            values[key], origin[key] = value, SCENE_OPTIONS[key]
    try:
        return Scene(**values)
    except InvalidParameterError as exc:
        raise _renamed(exc, origin.get(exc.name, exc.name)) from None


@dataclass(frozen=True, eq=False)
class BuildResult:
    """What a build produced.

    Attributes:
        config: The configuration it ran.
        experiments: The DOE optima in Table 1 order.
        doe_document: The doe.json document.
        paper_rows: The paper's Table 2 scored on our fitness (None unless the design and scene are the paper's).
        coefficients: The regressed coefficients (marked if the build did not converge).
        problems: What missed the convergence thresholds (empty: converged).
        timing: The build_timing.json document.
        written: Paths written, each with whether it replaced a file (empty if nothing was written).
    """

    config: BuildConfig
    experiments: tuple[ExperimentResult, ...]
    doe_document: dict
    paper_rows: list[dict] | None
    coefficients: Coefficients
    problems: tuple[ConvergenceProblem, ...]
    timing: dict
    written: tuple[tuple[Path, bool], ...] = ()

    @property
    def converged(self) -> bool:
        """True if every DOE optimum and the regression met the thresholds."""
        return not self.problems


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


def write_pair(first: Path, first_text: str, second: Path, second_text: str) -> tuple[bool, bool]:
    """Write two files atomically as a pair: if the second write fails, the first file is put
    back as it was (or removed if it was new), so doe.json and coefficients.json always match.

    Returns:
        Whether each file replaced an existing one.
    """
    previous = first.read_bytes() if first.is_file() else None
    first_replaced = write_text_atomic(first, first_text)
    try:
        second_replaced = write_text_atomic(second, second_text)
    except BaseException:
        if previous is None:
            first.unlink(missing_ok=True)
        else:
            write_text_atomic(first, previous.decode("utf-8"))
        raise
    return first_replaced, second_replaced


def _make_folder(folder: Path) -> list[Path]:
    """mkdir -p; returns the folders it created, outermost first."""
    created = []
    for candidate in reversed([folder, *folder.parents]):
        if not candidate.exists():
            candidate.mkdir()
            created.append(candidate)
    return created


def _remove_if_empty(created: list[Path]) -> None:
    for folder in reversed(created):
        try:
            folder.rmdir()
        except OSError:
            return


def _provenance(config: BuildConfig, arm: PlanarArm, solver: SolverConfig) -> dict:
    """The provenance block of doe.json and coefficients.json (no timestamps: deterministic)."""
    return {
        "seed": int(config.seed),
        "levels": config.levels,
        "family": solver.family.name,
        "urdf": arm.urdf_path.name,
        "urdf_sha256": sha256_file(arm.urdf_path),
        "pso": asdict(solver.pso),
        "fitness": solver.fitness.to_json(),
        "polish": solver.polish,
        "versions": package_versions(),
    }


def _timing_document(results: list[ExperimentResult], jobs: int) -> dict:
    """build_timing.json without its total (set when the files are written)."""
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


def run_build(config: BuildConfig, progress: Callable[[int, int], None] | None = None) -> BuildResult:
    """Run the offline pipeline: DOE, convergence check, regression, files.

    Args:
        config: What to build.
        progress: Called with (experiments done, experiments in all) once every check has
            passed (0 done) and after each experiment (e.g. to drive a progress bar).

    Returns:
        The result, with the files written (``result.written``).

    Raises:
        InvalidParameterError, DataFileError, RobotModelError, UnreachableObstacleError,
        InfeasibleSceneError: bad configuration, output folder or URDF, an obstacle the arm
            cannot pass or whose end pose collides (all before any work; nothing written or created).
        BuildNotConvergedError: the results missed the thresholds and ``allow_unconverged``
            is False (nothing written; ``exc.result`` holds the unwritten result).
    """
    started = time.perf_counter()
    check_output_folder(config.out_folder, OPTIONS["out_folder"])
    arm = load_planar_arm(config.urdf_path)
    grid = _check_before_work(config, arm)
    solver, design = config.solver(), config.design()

    total, done = len(design.points()), []
    report = None
    if progress is not None:
        progress(0, total)

        def report(_: ExperimentResult) -> None:
            done.append(1)
            progress(len(done), total)

    results = run_doe(arm, design, config.scene, solver, int(config.seed), config.jobs, progress=report)
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
    doe_path, coefficients_path = config.out_folder / "doe.json", config.out_folder / "coefficients.json"
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
    timing = _timing_document(results, config.jobs)
    result = BuildResult(config, tuple(results), document, paper_rows, coefficients, tuple(problems), timing)
    if problems and not config.allow_unconverged:
        timing["total_s"] = time.perf_counter() - started
        raise BuildNotConvergedError(problems, result)

    created = _make_folder(config.out_folder)
    try:
        replaced = write_pair(doe_path, doe_text, coefficients_path, dumps(coefficients.to_json()))
    except BaseException:
        _remove_if_empty(created)
        raise
    timing["total_s"] = time.perf_counter() - started
    timing_path = config.out_folder / "build_timing.json"
    timing_replaced = write_json_atomic(timing_path, timing)
    written = ((doe_path, replaced[0]), (coefficients_path, replaced[1]), (timing_path, timing_replaced))
    return BuildResult(config, tuple(results), document, paper_rows, coefficients, tuple(problems), timing, written)
