"""The benchmark: ``python -m verify.bench``.

On the same ``--n`` random obstacles (L, W) (uniform in the coefficients' fitted range, seeded),
in one run on this machine, it times side by side:

* **(a)** the regression generator alone (:func:`pipeline.generator.generate`), one query at a
  time, and **(a')** batched (:func:`pipeline.generator.generate_parameters` over all obstacles,
  time divided by their number);
* **(b)** the generator with certification (:func:`pipeline.online.generate_certified`:
  certify, repair if needed, or refuse);
* **(c)** re-running the PSO online for that (L, W) (:func:`pipeline.experiment.solve_experiment`,
  what the regression replaces; seconds per obstacle, so only on the first ``--pso-cases``);
* **(d)** a general-purpose planner: OMPL's RRT-Connect from the start to the goal configuration
  (analytic IK of P1 and P5) with a Coal validity checker on the same geometry
  (:mod:`verify.planner`), alone and **(d+)** followed by our certificate of its
  piecewise-linear path.

It reports per method the median time per query, its ratio to (a) and to (b), the fraction of
queries answered and the fraction of the answers that are **certified collision-free** by our
certificates (a rigorous lower bound on the clearance over the whole continuous motion > 0) or
keep the margin. It also reports the build's time and Coal query count (``results/build_timing.json``
written by ``python -m pipeline.build``, or a reduced build it runs itself with ``--run-build``)
and the sweep rate of :func:`verify.sweep.run_cases` with and without the certificate.

The figures are ratios measured in one run on one machine, never absolute claims: times use
``time.perf_counter``, every method is warmed up first, and the cheap methods are repeated many
times so their medians are stable.

Exit status: 0 on success, 2 on bad input (one line on stderr), 130 if interrupted.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import os
import platform
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from pipeline.certificate import certify_trajectory
from pipeline.exceptions import DataFileError, InvalidParameterError, NoCertifiedTrajectoryError, PipelineError
from pipeline.experiment import SolverConfig, solve_experiment
from pipeline.fitness import FitnessConfig
from pipeline.generator import generate, generate_parameters
from pipeline.jsonio import read_json, write_json_atomic
from pipeline.obstacle import Obstacle
from pipeline.online import generate_certified
from pipeline.pso import PsoConfig
from pipeline.robot import PlanarArm, load_planar_arm
from pipeline.trajectory import PARAMETER_NAMES, JointTrajectory
from pipeline.validation import check_non_negative, check_positive, check_positive_int
from verify.cli import HelpFormatter, Parser

from . import planner
from .bench_report import format_report
from .metrics import MeasureSettings, check_arm_matches
from .sweep import SweepRange, run_cases, sample_cases

FORMAT = "twolink-bench/1"
PROG = "python -m verify.bench"
DEFAULT_COEFFICIENTS = "results/coefficients.json"
DEFAULT_BUILD_TIMING = "results/build_timing.json"
DEFAULT_N = 50
DEFAULT_SEED = 0
DEFAULT_REPEATS = 200
DEFAULT_SLOW_REPEATS = 3
DEFAULT_PSO_CASES = 3
DEFAULT_OMPL_TIME_S = 1.0
EXIT_OK, EXIT_USAGE, EXIT_INTERRUPTED = 0, 2, 130

#: Warm-up calls of the cheap methods before timing.
_WARMUP_CALLS = 20


# --------------------------------------------------------------------------------------------
# Results


@dataclass(frozen=True)
class MethodResult:
    """Timings and answer quality of one method.

    Attributes:
        key: Short key: "a", "a_batch", "b", "c", "d", "d_cert".
        label: Row label of the table.
        obstacles: Distinct obstacles queried.
        times_s: Every timed run, as time per query [s].
        queries: Queries whose answers are counted (obstacles x runs).
        answered: Queries that returned an answer (a trajectory or a path).
        certified: Answers certified collision-free (certified clearance > 0).
        keeps_margin: Answers whose certified clearance is >= the margin.
        note: What exactly was timed.
        extra: Method-specific numbers (repairs, planner failures, Coal queries, ...).
    """

    key: str
    label: str
    obstacles: int
    times_s: tuple[float, ...]
    queries: int
    answered: int
    certified: int
    keeps_margin: int
    note: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def median_s(self) -> float:
        """Median time per query [s]."""
        return float(np.median(self.times_s))

    @property
    def answered_fraction(self) -> float:
        """Fraction of the queries answered."""
        return self.answered / self.queries if self.queries else float("nan")

    @property
    def certified_fraction(self) -> float:
        """Fraction of the answers certified collision-free."""
        return self.certified / self.answered if self.answered else float("nan")

    @property
    def keeps_margin_fraction(self) -> float:
        """Fraction of the answers whose certified clearance keeps the margin."""
        return self.keeps_margin / self.answered if self.answered else float("nan")

    def to_json(self, reference_a_s: float, reference_b_s: float | None) -> dict[str, Any]:
        """Plain-JSON form, with the ratios of the median to (a) and (b)."""
        return {
            "key": self.key,
            "label": self.label,
            "obstacles": self.obstacles,
            "timed_runs": len(self.times_s),
            "median_s": self.median_s,
            "min_s": float(np.min(self.times_s)),
            "max_s": float(np.max(self.times_s)),
            "ratio_to_a": self.median_s / reference_a_s,
            "ratio_to_b": None if reference_b_s is None else self.median_s / reference_b_s,
            "queries": self.queries,
            "answered": self.answered,
            "answered_fraction": self.answered_fraction,
            "certified_collision_free": self.certified,
            "certified_fraction": self.certified_fraction,
            "keeps_margin": self.keeps_margin,
            "keeps_margin_fraction": self.keeps_margin_fraction,
            "note": self.note,
            "extra": self.extra,
        }


@dataclass(frozen=True)
class BenchSettings:
    """What the benchmark runs.

    Attributes:
        n: Random obstacles [cases].
        seed: Seed of the obstacle sampler, the PSO and OMPL.
        repeats: Timed passes over all obstacles for (a) and (a').
        slow_repeats: Timed passes over all obstacles for (b) and (d).
        pso_cases: Obstacles (the first ones) on which (c) re-runs the PSO; 0 skips (c).
        pso_swarm_size, pso_iterations, pso_restarts: PSO settings of (c) and --run-build; None: the
            coefficients' build settings if recorded (provenance), else PsoConfig's defaults.
        polish: least_squares polish in (c); None: as the build did (default True).
        ompl_time_s: RRT-Connect time budget per query [s].
        ompl_margin_m: Validity margin of (d): a state is valid iff both links' clearance is >= this [m];
            None: the coefficients' scene margin (the fair comparison: the margin (b) is held to).
        ompl_simplify: Simplify the RRT-Connect path (timed as part of (d)).
        ompl_resolution: OMPL's validity checking resolution [fraction of the joint-space extent].
        run_ompl: Run (d) if ompl is installed.
        build_timing: build_timing.json to report (None: skip).
        run_build_levels: If set, also run a reduced build with this many levels per factor.
        urdf: URDF of the arm (None: the project's).
    """

    n: int = DEFAULT_N
    seed: int = DEFAULT_SEED
    repeats: int = DEFAULT_REPEATS
    slow_repeats: int = DEFAULT_SLOW_REPEATS
    pso_cases: int = DEFAULT_PSO_CASES
    pso_swarm_size: int | None = None
    pso_iterations: int | None = None
    pso_restarts: int | None = None
    polish: bool | None = None
    ompl_time_s: float = DEFAULT_OMPL_TIME_S
    ompl_margin_m: float | None = None
    ompl_simplify: bool = True
    ompl_resolution: float = planner.OMPL_DEFAULT_RESOLUTION
    run_ompl: bool = True
    build_timing: Path | None = Path(DEFAULT_BUILD_TIMING)
    run_build_levels: int | None = None
    urdf: Path | None = None

    def __post_init__(self) -> None:
        check_positive_int("--n", self.n)
        check_positive_int("--seed", self.seed, minimum=0)
        check_positive_int("--repeats", self.repeats)
        check_positive_int("--slow-repeats", self.slow_repeats)
        check_positive_int("--pso-cases", self.pso_cases, minimum=0)
        if self.pso_cases > self.n:
            raise InvalidParameterError("--pso-cases", self.pso_cases, f"at most --n = {self.n}")
        for name, value, minimum in (
            ("--pso-swarm-size", self.pso_swarm_size, 2),
            ("--pso-iterations", self.pso_iterations, 1),
            ("--pso-restarts", self.pso_restarts, 1),
        ):
            if value is not None:
                check_positive_int(name, value, minimum=minimum)
        check_positive("--ompl-time", self.ompl_time_s)
        if self.ompl_margin_m is not None:
            check_non_negative("--ompl-margin", self.ompl_margin_m)
        check_positive("--ompl-resolution", self.ompl_resolution)
        if self.run_build_levels is not None:
            check_positive_int("--run-build", self.run_build_levels, minimum=3)


@dataclass(frozen=True)
class BenchReport:
    """Everything one benchmark run measured.

    Attributes:
        coefficients: Source, family and hash of the coefficients.
        settings: The settings as plain JSON.
        cases_m: The obstacles (L, W) [m], shape (n, 2).
        margin_m: The scene's safety margin [m].
        methods: One :class:`MethodResult` per method run.
        skipped: Method key -> why it was skipped.
        sweep: Sweep rates (None if not run).
        build: Build timing (None if none was found or run).
        machine: Python, platform, CPU count, package versions.
        command: The command line.
        elapsed_s: Wall time of the whole benchmark [s].
    """

    coefficients: dict[str, Any]
    settings: dict[str, Any]
    cases_m: np.ndarray
    margin_m: float
    methods: tuple[MethodResult, ...]
    skipped: dict[str, str]
    sweep: dict[str, Any] | None
    build: dict[str, Any] | None
    machine: dict[str, Any]
    command: str
    elapsed_s: float

    def method(self, key: str) -> MethodResult | None:
        """The result of method ``key``, or None if it was not run."""
        return next((m for m in self.methods if m.key == key), None)

    def to_json(self) -> dict[str, Any]:
        """The --json document."""
        a = self.method("a")
        b = self.method("b")
        reference_a = a.median_s if a else float("nan")
        reference_b = b.median_s if b else None
        return {
            "format": FORMAT,
            "command": self.command,
            "note": "ratios measured in one run on this machine, not absolute claims",
            "coefficients": self.coefficients,
            "settings": self.settings,
            "margin_m": self.margin_m,
            "cases": [[float(length), float(width)] for length, width in self.cases_m],
            "methods": [m.to_json(reference_a, reference_b) for m in self.methods],
            "skipped": dict(self.skipped),
            "sweep": self.sweep,
            "build": self.build,
            "machine": self.machine,
            "elapsed_s": self.elapsed_s,
        }


# --------------------------------------------------------------------------------------------
# Helpers


def load_coefficients_checked(source: str) -> Any:
    """Load coefficients (a file or "paper") with a clear error when the file is missing."""
    from pipeline.coefficients import load_coefficients

    if source != "paper" and not Path(source).is_file():
        hint = " (run python -m pipeline.build first, or pass --coefficients paper)"
        raise DataFileError(source, "coefficients file not found" + (hint if source == DEFAULT_COEFFICIENTS else ""))
    return load_coefficients(source)


def _versions() -> dict[str, str | None]:
    out: dict[str, str | None] = {"python": platform.python_version()}
    for name in ("twolink-obstacle", "numpy", "scipy", "pin", "coal", "ompl"):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def machine_info() -> dict[str, Any]:
    """Where the benchmark ran: platform, CPUs, load average (other processes compete for the CPUs),
    package versions."""
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        cpus = os.cpu_count()
    try:
        load = [round(v, 2) for v in os.getloadavg()]
    except (AttributeError, OSError):  # pragma: no cover - not Unix
        load = None
    return {
        "platform": platform.platform(),
        "load_average_1_5_15_min": load,
        "machine": platform.machine(),
        "processor": platform.processor() or None,
        "usable_cpus": cpus,
        "versions": _versions(),
    }


def solver_config(coefficients: Any, settings: BenchSettings) -> tuple[SolverConfig, str]:
    """The PSO settings of (c): the build's (from the coefficients' provenance) unless overridden.

    Returns:
        (config, where the settings came from, in words).
    """
    provenance = coefficients.provenance
    source = "PsoConfig defaults (the coefficients record no build settings)"
    pso, fitness, polish = PsoConfig(), FitnessConfig(), True
    if provenance.get("pso") is not None:
        try:
            pso = PsoConfig(**provenance["pso"])
            fitness = FitnessConfig(**provenance.get("fitness", {}))
            polish = bool(provenance.get("polish", True))
            source = "the build's settings (coefficients' provenance)"
        except (TypeError, PipelineError):
            source = "PsoConfig defaults (the coefficients' provenance could not be read)"
    overrides = {
        name: value
        for name, value in (
            ("swarm_size", settings.pso_swarm_size),
            ("iterations", settings.pso_iterations),
            ("restarts", settings.pso_restarts),
        )
        if value is not None
    }
    if overrides:
        pso, source = replace(pso, **overrides), f"{source}, with {', '.join(overrides)} from the command line"
    if settings.polish is not None:
        polish = settings.polish
    return SolverConfig(family=coefficients.family, fitness=fitness, pso=pso, polish=polish), source


def _timed(function: Callable[[], Any]) -> tuple[float, Any]:
    started = time.perf_counter()
    value = function()
    return time.perf_counter() - started, value


def _certificate_counts(clearances: Sequence[float], margin_m: float) -> tuple[int, int]:
    certified = sum(1 for c in clearances if c > 0.0)
    keeps = sum(1 for c in clearances if c >= margin_m)
    return certified, keeps


# --------------------------------------------------------------------------------------------
# The methods


def bench_generator(coefficients: Any, cases: np.ndarray, repeats: int) -> tuple[list[float], list[Any]]:
    """(a): time ``generate`` one query at a time, ``repeats`` passes over the cases.

    Returns:
        (time of every call [s], the generated trajectories of the last pass, None where it raised).
    """
    for _ in range(_WARMUP_CALLS):
        generate(coefficients, float(cases[0, 0]), float(cases[0, 1]))
    times: list[float] = []
    answers: list[Any] = [None] * len(cases)
    clock = time.perf_counter
    for _ in range(repeats):
        for i, (length, width) in enumerate(cases):
            started = clock()
            try:
                answers[i] = generate(coefficients, float(length), float(width))
            except PipelineError:
                answers[i] = None
            times.append(clock() - started)
    return times, answers


def bench_batched(coefficients: Any, cases: np.ndarray, repeats: int) -> tuple[list[float], np.ndarray]:
    """(a'): time ``generate_parameters`` over all cases at once; returns time per query [s] of each pass."""
    lengths, widths = np.ascontiguousarray(cases[:, 0]), np.ascontiguousarray(cases[:, 1])
    for _ in range(max(2, _WARMUP_CALLS // 4)):
        generate_parameters(coefficients, lengths, widths)
    times = []
    parameters = np.empty((0, 8))
    for _ in range(repeats):
        elapsed, parameters = _timed(lambda: generate_parameters(coefficients, lengths, widths))
        times.append(elapsed / len(cases))
    return times, np.asarray(parameters)


def bench_certified(
    coefficients: Any, cases: np.ndarray, arm: PlanarArm, repeats: int
) -> tuple[list[float], list[float | None], int]:
    """(b): time ``generate_certified`` per query.

    Returns:
        (times [s], certified clearance of each answer or None where it refused, repairs made).
    """
    with contextlib.suppress(PipelineError):
        generate_certified(coefficients, float(cases[0, 0]), float(cases[0, 1]), arm)
    times: list[float] = []
    clearances: list[float | None] = []
    repairs = 0
    for _ in range(repeats):
        for length, width in cases:
            started = time.perf_counter()
            try:
                answer = generate_certified(coefficients, float(length), float(width), arm)
            except NoCertifiedTrajectoryError:
                answer = None
            times.append(time.perf_counter() - started)
            clearances.append(None if answer is None else answer.certified_clearance_m)
            repairs += bool(answer is not None and answer.repaired)
    return times, clearances, repairs


def bench_pso(
    coefficients: Any, cases: np.ndarray, arm: PlanarArm, config: SolverConfig, seed: int, log: Callable[[str], None]
) -> tuple[list[float], list[float], list[dict[str, Any]]]:
    """(c): time ``solve_experiment`` once per case and certify each optimum (not timed).

    Returns:
        (times [s], certified clearance of each optimum [m], per-case details).
    """
    rng = np.random.default_rng(seed)
    times, clearances, details = [], [], []
    for length, width in cases:
        started = time.perf_counter()
        result = solve_experiment(arm, float(length), float(width), coefficients.scene, config, rng)
        elapsed = time.perf_counter() - started
        trajectory = JointTrajectory(tuple(result.parameters[name] for name in PARAMETER_NAMES), result.duration_s)
        obstacle = Obstacle.in_scene(float(length), float(width), coefficients.scene)
        certificate = certify_trajectory(trajectory, arm, obstacle)
        times.append(elapsed)
        clearances.append(certificate.certified_clearance_m)
        details.append(
            {
                "L": float(length),
                "W": float(width),
                "seconds": elapsed,
                "fitness": result.fitness,
                "solver": result.solver,
                "objective_evaluations": result.objective_evaluations,
                "coal_queries": result.coal_queries,
                "certified_clearance_m": certificate.certified_clearance_m,
            }
        )
        log(f"  (c) L = {length:.4f} m, W = {width:.4f} m: {elapsed:.2f} s")
    return times, clearances, details


def bench_ompl(
    coefficients: Any,
    cases: np.ndarray,
    arm: PlanarArm,
    settings: BenchSettings,
    validity_margin_m: float,
    margin_m: float,
) -> tuple[MethodResult, MethodResult]:
    """(d) and (d+): RRT-Connect per query (setup, IK of P1 / P5, solve, simplify), then our certificate.

    Args:
        validity_margin_m: A state is valid iff both links' Coal clearance is >= this [m].
        margin_m: The scene's margin, for the "keeps margin" count [m].
    """
    planner.seed_ompl(settings.seed)
    config = planner.PlannerConfig(
        time_limit_s=settings.ompl_time_s,
        margin_m=validity_margin_m,
        simplify=settings.ompl_simplify,
        resolution=settings.ompl_resolution,
        log_level="none",  # failures are counted below, with their reasons
    )
    scene = coefficients.scene

    def query(length: float, width: float) -> tuple[Obstacle, planner.PlanResult]:
        obstacle = Obstacle.in_scene(length, width, scene)
        start, goal = planner.start_goal_configurations(obstacle, scene, arm.link_lengths_m, coefficients.elbow)
        return obstacle, planner.plan_rrt_connect(arm, obstacle, start, goal, config)

    query(float(cases[0, 0]), float(cases[0, 1]))  # warm-up
    plan_times, total_times, clearances = [], [], []
    failures = {"start_invalid": 0, "goal_invalid": 0, "not_solved": 0}
    checks, queries_coal, waypoints, answered_times = [], [], [], []
    for _ in range(settings.slow_repeats):
        for length, width in cases:
            plan_s, (obstacle, result) = _timed(lambda length=length, width=width: query(float(length), float(width)))
            certify_s = 0.0
            if result.solved and result.path is not None:
                certify_s, certificate = _timed(lambda r=result, o=obstacle: planner.certify_path(r.path, arm, o))
                clearances.append(certificate.certified_clearance_m)
                waypoints.append(int(result.waypoints_rad.shape[0]))
                answered_times.append(plan_s)
            elif not result.start_valid:
                failures["start_invalid"] += 1
            elif not result.goal_valid:
                failures["goal_invalid"] += 1
            else:
                failures["not_solved"] += 1
            checks.append(result.validity_checks)
            queries_coal.append(result.coal_queries)
            plan_times.append(plan_s)
            total_times.append(plan_s + certify_s)
    certified, keeps = _certificate_counts(clearances, margin_m)
    n_queries = len(plan_times)
    limits = arm.position_limits_rad
    extent = math.hypot(limits[0][1] - limits[0][0], limits[1][1] - limits[1][0])
    extra = {
        "planner_failures": sum(failures.values()),
        "failure_reasons": failures,
        "median_answered_s": float(np.median(answered_times)) if answered_times else None,
        "time_limit_s": settings.ompl_time_s,
        "simplify": settings.ompl_simplify,
        "validity": f"Coal clearance of both links >= {validity_margin_m} m",
        "validity_margin_m": validity_margin_m,
        "validity_resolution": settings.ompl_resolution,
        "validity_resolution_rad": settings.ompl_resolution * extent,
        "validity_checks_median": float(np.median(checks)),
        "coal_queries_median": float(np.median(queries_coal)),
        "waypoints_median": float(np.median(waypoints)) if waypoints else None,
        "certified_clearance_min_m": min(clearances) if clearances else None,
        "certified_clearance_median_m": float(np.median(clearances)) if clearances else None,
    }
    common = {
        "obstacles": len(cases),
        "queries": n_queries,
        "answered": len(clearances),
        "certified": certified,
        "keeps_margin": keeps,
        "extra": extra,
    }
    plan = MethodResult(
        key="d",
        label="(d)  OMPL RRT-Connect" + (" + simplify" if settings.ompl_simplify else ""),
        times_s=tuple(plan_times),
        note="per query: Coal checker + SimpleSetup + IK of P1/P5 + solve"
        + (" + simplifySolution" if settings.ompl_simplify else ""),
        **common,
    )
    total = MethodResult(
        key="d_cert",
        label="(d+) OMPL path + our certificate",
        times_s=tuple(total_times),
        note="(d) + certify_path (piecewise-linear certificate, Coal)",
        **common,
    )
    return plan, total


def bench_sweep(source: str, coefficients: Any, arm: PlanarArm, cases: np.ndarray) -> tuple[dict[str, Any], Any]:
    """Sweep rate of ``verify.sweep.run_cases`` (one process) with and without the certificate.

    Returns:
        (rates, the certified sweep's case results).
    """
    run_cases(source, cases[:1], MeasureSettings(certify=True), jobs=1, coefficients=coefficients, arm=arm)  # warm-up
    out: dict[str, Any] = {"n_cases": len(cases), "jobs": 1}
    results = None
    for key, certify in (("without_certificate", False), ("with_certificate", True)):
        elapsed, results = _timed(
            lambda certify=certify: run_cases(
                source, cases, MeasureSettings(certify=certify), jobs=1, coefficients=coefficients, arm=arm
            )
        )
        out[key] = {"seconds": elapsed, "cases_per_s": len(cases) / elapsed}
    return out, results


def read_build_timing(path: Path) -> dict[str, Any] | None:
    """Summary of a build_timing.json (None if the file does not exist).

    Raises:
        DataFileError: the file exists but is malformed.
    """
    if not path.is_file():
        return None
    data = read_json(path)
    try:
        experiments = [float(e["seconds"]) for e in data.get("experiments", [])]
        return {
            "source": str(path),
            "total_s": float(data["total_s"]),
            "jobs": data.get("jobs"),
            "experiments": len(experiments),
            "experiment_seconds": experiments,
            "experiment_median_s": float(np.median(experiments)) if experiments else None,
            "coal_queries": int(data["coal_queries"]),
            "objective_evaluations": data.get("objective_evaluations"),
        }
    except (KeyError, TypeError, ValueError) as exc:
        raise DataFileError(path, f"not a build timing file ({type(exc).__name__}: {exc})") from None


def run_reduced_build(levels: int, config: SolverConfig, seed: int, urdf: Path | None) -> dict[str, Any]:
    """Run ``python -m pipeline.build`` with ``levels`` levels per factor (>= 3) into a temporary
    folder, with the PSO settings of (c); its build_timing.json, summarised.

    Raises:
        PipelineError: the build failed.
    """
    from pipeline import build

    with tempfile.TemporaryDirectory(prefix="bench-build-") as folder:
        argv = [
            "--out",
            folder,
            "--quiet",
            "--seed",
            str(seed),
            "--levels",
            str(levels),
            "--family",
            config.family,
            "--swarm-size",
            str(config.pso.swarm_size),
            "--iterations",
            str(config.pso.iterations),
            "--restarts",
            str(config.pso.restarts),
        ]
        if not config.polish:
            argv.append("--no-polish")
        if urdf is not None:
            argv += ["--urdf", str(urdf)]
        build.build(build.parser().parse_args(argv), out=io.StringIO())
        summary = read_build_timing(Path(folder) / "build_timing.json")
    assert summary is not None
    pso = config.pso
    summary["source"] = (
        f"build run by the benchmark: {levels} x {levels} levels, PSO swarm {pso.swarm_size}, iterations "
        f"{pso.iterations}, restarts {pso.restarts}, polish {config.polish}"
    )
    return summary


# --------------------------------------------------------------------------------------------
# The run


def run_bench(
    source: str,
    settings: BenchSettings,
    *,
    command: str = PROG,
    log: Callable[[str], None] = lambda _: None,
) -> BenchReport:
    """Run every method on the same random obstacles and collect the report.

    Raises:
        DataFileError: missing or malformed coefficients / build timing file.
        InvalidParameterError: coefficients fitted for another arm, or bad settings.
    """
    started = time.perf_counter()
    machine = machine_info()  # load average at the start
    coefficients = load_coefficients_checked(source)
    arm = load_planar_arm(settings.urdf)
    check_arm_matches(coefficients, arm)
    margin = coefficients.scene.margin_m
    sweep_range = SweepRange.from_fitted(coefficients.fitted_range_m)
    cases = sample_cases(sweep_range, settings.n, settings.seed)
    methods: list[MethodResult] = []
    skipped: dict[str, str] = {}

    # Build timing first (a missing or malformed file is reported before minutes of work).
    build_info = read_build_timing(settings.build_timing) if settings.build_timing is not None else None
    config, pso_source = solver_config(coefficients, settings)

    # (a) and the sweep rate; the sweep with certificate also certifies (a)'s answers.
    log("timing (a) the regression generator, one query at a time ...")
    times_a, answers = bench_generator(coefficients, cases, settings.repeats)
    log("timing the sweep with and without the certificate (and certifying (a)'s answers) ...")
    sweep_info, certified_cases = bench_sweep(source, coefficients, arm, cases)
    clearances_a = [c.certified_clearance_m for c in certified_cases if c.certified_clearance_m is not None]
    certified_a, keeps_a = _certificate_counts(clearances_a, margin)
    answered_a = sum(a is not None for a in answers)
    methods.append(
        MethodResult(
            key="a",
            label="(a)  regression generator, per query",
            obstacles=len(cases),
            times_s=tuple(times_a),
            queries=len(cases),
            answered=answered_a,
            certified=certified_a,
            keeps_margin=keeps_a,
            note=f"generate(coefficients, L, W), each call timed; passes over the obstacles: {settings.repeats}",
        )
    )

    log("timing (a') the regression generator, batched ...")
    times_batch, parameters = bench_batched(coefficients, cases, settings.repeats)
    same = all(
        answer is not None and np.allclose(row, answer.trajectory.array, rtol=1e-12, atol=1e-12)
        for row, answer in zip(parameters, answers, strict=True)
    )
    if not same:
        clearances_batch = []
        for row, answer in zip(parameters, answers, strict=True):
            if answer is not None:
                trajectory = JointTrajectory(tuple(row), answer.duration_s)
                clearances_batch.append(certify_trajectory(trajectory, arm, answer.obstacle).certified_clearance_m)
        certified_batch, keeps_batch = _certificate_counts(clearances_batch, margin)
    else:
        certified_batch, keeps_batch = certified_a, keeps_a
    methods.append(
        MethodResult(
            key="a_batch",
            label=f"(a') regression generator, batched (n = {len(cases)})",
            obstacles=len(cases),
            times_s=tuple(times_batch),
            queries=len(cases),
            answered=answered_a,
            certified=certified_batch,
            keeps_margin=keeps_batch,
            note="generate_parameters(coefficients, L[:], W[:]) / n; parameters only (no path object)"
            + ("; same parameters as (a)" if same else ""),
            extra={"same_parameters_as_a": same},
        )
    )

    log("timing (b) the generator with certification (certify-or-repair) ...")
    times_b, clearances_b, repairs = bench_certified(coefficients, cases, arm, settings.slow_repeats)
    answered_clearances = [c for c in clearances_b if c is not None]
    certified_b, keeps_b = _certificate_counts(answered_clearances, margin)
    methods.append(
        MethodResult(
            key="b",
            label="(b)  generator + certificate (or repair)",
            obstacles=len(cases),
            times_s=tuple(times_b),
            queries=len(clearances_b),
            answered=len(answered_clearances),
            certified=certified_b,
            keeps_margin=keeps_b,
            note=f"generate_certified(...) (Coal certificate to the {margin} m margin, repair if needed, "
            f"else refuse); passes: {settings.slow_repeats}; repairs: {repairs}, refusals: "
            f"{len(clearances_b) - len(answered_clearances)} of {len(clearances_b)} queries",
            extra={"repairs": repairs, "refusals": len(clearances_b) - len(answered_clearances)},
        )
    )

    if settings.pso_cases > 0:
        log(f"timing (c) re-running the PSO online on {settings.pso_cases} obstacle(s) ({pso_source}) ...")
        times_c, clearances_c, details = bench_pso(
            coefficients, cases[: settings.pso_cases], arm, config, settings.seed, log
        )
        certified_c, keeps_c = _certificate_counts(clearances_c, margin)
        methods.append(
            MethodResult(
                key="c",
                label="(c)  PSO online (solve_experiment)",
                obstacles=settings.pso_cases,
                times_s=tuple(times_c),
                queries=settings.pso_cases,
                answered=settings.pso_cases,
                certified=certified_c,
                keeps_margin=keeps_c,
                note=f"solve_experiment on the first {settings.pso_cases} obstacle(s), one run each, no warm-up; "
                f"PSO swarm {config.pso.swarm_size}, iterations {config.pso.iterations}, restarts "
                f"{config.pso.restarts}, polish {config.polish} ({pso_source}); optimum then certified (not timed)",
                extra={"cases": details, "pso": asdict(config.pso), "polish": config.polish, "source": pso_source},
            )
        )
    else:
        skipped["c"] = "--pso-cases 0"

    if not settings.run_ompl:
        skipped["d"] = "--no-ompl"
    elif not planner.ompl_available():
        skipped["d"] = "ompl is not installed (pip install ompl, or the project's 'bench' extra)"
    else:
        log(f"timing (d) OMPL RRT-Connect ({settings.ompl_time_s} s budget per query) ...")
        try:
            ompl_margin = margin if settings.ompl_margin_m is None else settings.ompl_margin_m
            methods.extend(bench_ompl(coefficients, cases, arm, settings, ompl_margin, margin))
        except ImportError as exc:
            skipped["d"] = f"ompl could not be imported ({exc})"

    if settings.run_build_levels is not None:
        log(f"running a reduced build ({settings.run_build_levels} x {settings.run_build_levels} levels) ...")
        reduced = run_reduced_build(settings.run_build_levels, config, settings.seed, settings.urdf)
        build_info = {"file": build_info, "reduced": reduced}
    elif build_info is not None:
        build_info = {"file": build_info, "reduced": None}
    elif settings.build_timing is not None:
        build_info = {
            "file": None,
            "reduced": None,
            "missing": f"{settings.build_timing} not found (written by python -m pipeline.build)",
        }

    settings_json = {key: (str(value) if isinstance(value, Path) else value) for key, value in asdict(settings).items()}
    settings_json["pso_resolved"] = asdict(config.pso)
    settings_json["polish"] = config.polish
    settings_json["pso_settings_source"] = pso_source
    return BenchReport(
        coefficients={
            "source": source,
            "family": coefficients.family,
            "sha256": coefficients.source_sha256,
            "fitted_range_m": {k: list(v) for k, v in coefficients.fitted_range_m.items()},
        },
        settings=settings_json,
        cases_m=cases,
        margin_m=margin,
        methods=tuple(methods),
        skipped=skipped,
        sweep=sweep_info,
        build=build_info,
        machine=machine,
        command=command,
        elapsed_s=time.perf_counter() - started,
    )


# --------------------------------------------------------------------------------------------
# Command line


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface of ``python -m verify.bench``."""
    defaults = BenchSettings()
    parser = Parser(
        prog=PROG,
        description=(
            "Time, on the same random obstacles in one run: (a) the regression generator per query and "
            "batched, (b) the generator with certification, (c) re-running the PSO online, (d) OMPL "
            "RRT-Connect with a Coal validity checker, then our certificate of its path. Prints median "
            "time per query, ratios to (a) and (b), the fraction of answers certified collision-free, the "
            "build time and the sweep rate. Ratios measured in one run on this machine, not absolute claims."
        ),
        formatter_class=HelpFormatter,
    )
    parser.add_argument(
        "--coefficients",
        metavar="FILE",
        default=DEFAULT_COEFFICIENTS,
        help="coefficients file, or 'paper' for the paper's Eq. 9",
    )
    parser.add_argument("--n", type=int, default=defaults.n, help="random obstacles (L, W) [cases] (>= 1)")
    parser.add_argument("--seed", type=int, default=defaults.seed, help="seed of the obstacles, PSO and OMPL (>= 0)")
    parser.add_argument(
        "--repeats",
        type=int,
        default=defaults.repeats,
        help="timed passes over the obstacles for (a) and (a') [passes]",
    )
    parser.add_argument(
        "--slow-repeats",
        type=int,
        default=defaults.slow_repeats,
        help="timed passes over the obstacles for (b) and (d) [passes]",
    )
    parser.add_argument(
        "--pso-cases",
        type=int,
        default=defaults.pso_cases,
        help="obstacles on which (c) re-runs the PSO, about 5-20 s each with the build's settings [cases] "
        "(0 skips (c))",
    )
    parser.add_argument(
        "--pso-swarm-size",
        type=int,
        default=None,
        help="PSO particles for (c) and --run-build [particles] (default: the build's, from the coefficients' "
        "provenance, else 40)",
    )
    parser.add_argument(
        "--pso-iterations",
        type=int,
        default=None,
        help="PSO iterations per restart for (c) [iterations] (default: the build's, else 200)",
    )
    parser.add_argument(
        "--pso-restarts",
        type=int,
        default=None,
        help="independent PSO swarms for (c) [swarms] (default: the build's, else 4)",
    )
    parser.add_argument(
        "--pso-no-polish",
        action="store_true",
        help="skip the least_squares polish in (c) (default: polish, as the build)",
    )
    parser.add_argument(
        "--ompl-time", type=float, default=defaults.ompl_time_s, help="RRT-Connect time budget per query [s]"
    )
    parser.add_argument(
        "--ompl-margin",
        type=float,
        default=None,
        help="validity margin of (d): a state is valid iff both links' Coal clearance is >= this [m] "
        "(default: the coefficients' scene margin, 0.01 m, the margin (b) is held to)",
    )
    parser.add_argument(
        "--ompl-resolution",
        type=float,
        default=defaults.ompl_resolution,
        help="OMPL state validity checking resolution along motions [fraction of the joint-space extent] "
        "(default: 0.01, OMPL's own)",
    )
    parser.add_argument(
        "--ompl-simplify",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="simplify the RRT-Connect path with OMPL's simplifier, timed as part of (d)",
    )
    parser.add_argument("--no-ompl", action="store_true", help="skip (d) even if ompl is installed (default: run it)")
    parser.add_argument(
        "--build-timing",
        type=Path,
        metavar="FILE",
        default=Path(DEFAULT_BUILD_TIMING),
        help="build timing file written by python -m pipeline.build, reported if it exists",
    )
    parser.add_argument(
        "--run-build",
        type=int,
        metavar="LEVELS",
        default=None,
        help="also run a build of LEVELS x LEVELS experiments (>= 3; with the PSO settings of (c), so reduced "
        "with the --pso-* options) in a temporary folder and report its time [levels per factor] (default: off)",
    )
    parser.add_argument("--urdf", type=Path, default=None, help="URDF of the arm (default: urdf/planar_2link.urdf)")
    parser.add_argument(
        "--json", type=Path, metavar="FILE", default=None, help="write the report as JSON (atomically) (default: none)"
    )
    parser.add_argument("--quiet", action="store_true", help="no progress lines on stderr (default: show them)")
    return parser


def settings_from_args(args: argparse.Namespace) -> BenchSettings:
    """BenchSettings from parsed arguments (raises InvalidParameterError on bad values)."""
    return BenchSettings(
        n=args.n,
        seed=args.seed,
        repeats=args.repeats,
        slow_repeats=args.slow_repeats,
        pso_cases=args.pso_cases,
        pso_swarm_size=args.pso_swarm_size,
        pso_iterations=args.pso_iterations,
        pso_restarts=args.pso_restarts,
        polish=False if args.pso_no_polish else None,
        ompl_time_s=args.ompl_time,
        ompl_margin_m=args.ompl_margin,
        ompl_simplify=args.ompl_simplify,
        ompl_resolution=args.ompl_resolution,
        run_ompl=not args.no_ompl,
        build_timing=args.build_timing,
        run_build_levels=args.run_build,
        urdf=args.urdf,
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark; returns the exit status (0 done, 2 bad input, 130 interrupted)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help (0) or a usage error (2), already printed
        return int(exc.code or 0)

    def log(message: str) -> None:
        if not args.quiet:
            print(message, file=sys.stderr, flush=True)

    try:
        settings = settings_from_args(args)
        report = run_bench(args.coefficients, settings, command=" ".join([PROG, *argv]), log=log)
        print(format_report(report))
        if args.json is not None:
            write_json_atomic(args.json, report.to_json())
            print(f"wrote {args.json}")
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except (PipelineError, OSError) as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    return EXIT_OK


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
