"""The methods the benchmark times beside the per-query rows (:mod:`verify.benchmark.per_query`): (a')
the generator batched, (a*') the generator with the range certificate batched, (r*) rest-to-rest,
(b) certify-or-repair, (c) PSO online, (d) OMPL RRT-Connect (also on moved obstacles), and the
sweep rate and build time."""

from __future__ import annotations

import contextlib
import math
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from pipeline.build import (
    BuildConfig,
    DesignSettings,
    ExecutionSettings,
    OptimiserSettings,
    RangeMapSettings,
    RegressionSettings,
    run_build,
)
from pipeline.certify.region_map import RegionMap
from pipeline.exceptions import DataFileError, ExecutionRefusedError, NoCertifiedTrajectoryError, PipelineError
from pipeline.geometry.polyline_certificate import certify_path
from pipeline.geometry.sinusoid_certificate import certify_trajectory
from pipeline.io.jsonio import read_json
from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.motion.rest_to_rest import REST_TO_REST
from pipeline.motion.trajectory import PARAMETER_NAMES, JointTrajectory
from pipeline.offline.experiment import SolverConfig, solve_experiment
from pipeline.online.batch import GeneratedBatch, generate_batch
from pipeline.online.batch_execution import ExecutionBatch, execution_batch
from pipeline.online.generator import RANGE_SOURCE, generate_parameters
from pipeline.online.repair import generate_certified
from verify.acceptance.metrics import MeasureSettings
from verify.acceptance.run import run_cases

from . import ompl_planner as planner
from .results import WARMUP_CALLS, BenchSettings, MethodResult


def certificate_counts(clearances: Sequence[float], margin_m: float) -> tuple[int, int]:
    """How many certified clearances [m] are > 0 (collision-free) and >= ``margin_m`` (keep the margin)."""
    certified = sum(1 for c in clearances if c > 0.0)
    keeps = sum(1 for c in clearances if c >= margin_m)
    return certified, keeps


def _timed(function: Callable[[], Any]) -> tuple[float, Any]:
    started = time.perf_counter()
    value = function()
    return time.perf_counter() - started, value


def bench_batched(coefficients: Any, cases: np.ndarray, repeats: int) -> tuple[list[float], np.ndarray]:
    """(a'): time ``generate_parameters`` over all cases at once; returns time per query [s] of each pass."""
    lengths, widths = np.ascontiguousarray(cases[:, 0]), np.ascontiguousarray(cases[:, 1])
    for _ in range(max(2, WARMUP_CALLS // 4)):
        generate_parameters(coefficients, lengths, widths)
    times = []
    parameters = np.empty((0, 8))
    for _ in range(repeats):
        elapsed, parameters = _timed(lambda: generate_parameters(coefficients, lengths, widths))
        times.append(elapsed / len(cases))
    return times, np.asarray(parameters)


def bench_range_batched(
    coefficients: Any, cases: np.ndarray, region_map: RegionMap, repeats: int
) -> tuple[list[float], GeneratedBatch]:
    """(a*) batched: time ``generate_batch(..., region_map=...)`` over all cases at once (parameters, T and
    the range certificate's bounds per obstacle); returns (time per obstacle [s] of each pass, the last batch)."""
    lengths, widths = np.ascontiguousarray(cases[:, 0]), np.ascontiguousarray(cases[:, 1])
    for _ in range(max(2, WARMUP_CALLS // 4)):
        generate_batch(coefficients, lengths, widths, region_map=region_map)
    times = []
    batch = None
    for _ in range(repeats):
        elapsed, batch = _timed(lambda: generate_batch(coefficients, lengths, widths, region_map=region_map))
        times.append(elapsed / len(cases))
    return times, batch


def bench_rest_to_rest(
    coefficients: Any,
    cases: np.ndarray,
    arm: PlanarArm,
    region_map: RegionMap,
    repeats: int,
    timing: Any = REST_TO_REST,
) -> tuple[list[float], list[Any]]:
    """(r*): time ``generate_certified(..., timing=REST_TO_REST, region_map=m)`` per query: the
    regression's answer certified in full (clearance, endpoints, and the shortest rest-to-rest
    timing's angles, speeds, accelerations and torques), from the map's leaf where it decides,
    per query elsewhere; (n*m) likewise with ``timing=NEAR_OPTIMAL`` (the map's near-optimal cells).
    Returns (times [s], the last pass's answers, None where it refused)."""

    def one(length: float, width: float) -> Any:
        try:
            return generate_certified(
                coefficients, length, width, arm, region_map=region_map, timing=timing, out_of_range="ignore"
            )
        except (NoCertifiedTrajectoryError, ExecutionRefusedError):
            return None

    for length, width in cases[: min(len(cases), WARMUP_CALLS)]:
        one(float(length), float(width))
    times: list[float] = []
    answers: list[Any] = []
    for _ in range(repeats):
        answers = []
        for length, width in cases:
            started = time.perf_counter()
            answer = one(float(length), float(width))
            times.append(time.perf_counter() - started)
            answers.append(answer)
    return times, answers


def bench_rest_to_rest_batched(
    coefficients: Any, cases: np.ndarray, region_map: RegionMap, repeats: int, timing: Any = REST_TO_REST
) -> tuple[list[float], GeneratedBatch, ExecutionBatch]:
    """(r*'): time ``generate_batch`` and ``execution_batch(..., REST_TO_REST)`` over all cases
    at once (the map's bounds, no per-query certificate); (n*m') likewise with ``NEAR_OPTIMAL``;
    returns (time per obstacle [s] of each pass, the last pass's batch and its execution batch)."""
    lengths, widths = np.ascontiguousarray(cases[:, 0]), np.ascontiguousarray(cases[:, 1])

    def run() -> tuple[GeneratedBatch, ExecutionBatch]:
        batch = generate_batch(coefficients, lengths, widths, region_map=region_map)
        return batch, execution_batch(coefficients, batch, timing, region_map=region_map)

    for _ in range(max(2, WARMUP_CALLS // 4)):
        run()
    times = []
    batch, result = run()
    for _ in range(repeats):
        elapsed, (batch, result) = _timed(run)
        times.append(elapsed / len(cases))
    return times, batch, result


@dataclass(frozen=True)
class RangeCounts:
    """What the range certificate answered for the in-range queries of (a*).

    Attributes:
        in_range: Queries inside the fitted range (where the map answers) [queries].
        certified: Of those, answered with ``certificate_source == "range"`` and a certified
            clearance > 0 [queries].
        keeps_margin: Of those, certified clearance >= the margin [queries].
        clearance_min_m: Smallest certified clearance among them [m] (None if none).
    """

    in_range: int
    certified: int
    keeps_margin: int
    clearance_min_m: float | None


def range_counts(answers: Sequence[Any], margin_m: float) -> RangeCounts:
    """Count (a*)'s answers (a :class:`verify.benchmark.per_query.PerQueryRow`'s with a region map;
    None where it raised) by their range certificate: in range, certified collision-free, keeping ``margin_m`` [m]."""
    in_range = [a for a in answers if a is not None and not a.extrapolated]
    clearances = [
        a.certified_clearance_m
        for a in in_range
        if a.certificate_source == RANGE_SOURCE and a.certified_clearance_m is not None
    ]
    certified, keeps = certificate_counts(clearances, margin_m)
    return RangeCounts(len(in_range), certified, keeps, min(clearances) if clearances else None)


def batch_range_counts(batch: GeneratedBatch, margin_m: float, first: int | None = None) -> RangeCounts:
    """:func:`range_counts` of a :class:`GeneratedBatch` carrying the map's bounds (NaN where it has none),
    over its ``first`` obstacles (all if None)."""
    count = len(batch.error) if first is None else first
    answered = np.array([e is None for e in batch.error[:count]], dtype=bool)
    in_range = answered & ~batch.extrapolated[:count]
    bounds = None if batch.certified_clearance_m is None else batch.certified_clearance_m[:count]
    clearances = [] if bounds is None else [float(c) for c in bounds[in_range] if math.isfinite(c)]
    certified, keeps = certificate_counts(clearances, margin_m)
    return RangeCounts(int(np.count_nonzero(in_range)), certified, keeps, min(clearances) if clearances else None)


def bench_certified(
    coefficients: Any, cases: np.ndarray, arm: PlanarArm, repeats: int
) -> tuple[list[float], list[float | None], int]:
    """(b): time ``generate_certified`` per query, with the per-query certificate every time (no
    region map, even one attached to the coefficients: that is (a*)): the clearance, and the
    endpoints and the arm's limits with the paper timing (decide mode).

    Returns:
        (times [s], certified clearance of each answer or None where it refused, repairs made).
    """
    with contextlib.suppress(PipelineError):
        generate_certified(coefficients, float(cases[0, 0]), float(cases[0, 1]), arm, region_map=None)
    times: list[float] = []
    clearances: list[float | None] = []
    repairs = 0
    for _ in range(repeats):
        for length, width in cases:
            started = time.perf_counter()
            try:
                answer = generate_certified(coefficients, float(length), float(width), arm, region_map=None)
            except (NoCertifiedTrajectoryError, ExecutionRefusedError):
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


@dataclass
class _OmplTally:
    """What the (d) queries gave, gathered over every pass."""

    plan_times: list[float] = field(default_factory=list)
    total_times: list[float] = field(default_factory=list)
    clearances: list[float] = field(default_factory=list)
    answered_times: list[float] = field(default_factory=list)
    waypoints: list[int] = field(default_factory=list)
    checks: list[int] = field(default_factory=list)
    coal_queries: list[int] = field(default_factory=list)
    failures: dict[str, int] = field(default_factory=lambda: {"start_invalid": 0, "goal_invalid": 0, "not_solved": 0})
    obstacles: list[Obstacle] = field(default_factory=list)  # the planner's obstacles of the first pass


def _ompl_queries(
    coefficients: Any,
    cases: np.ndarray,
    arm: PlanarArm,
    settings: BenchSettings,
    config: planner.PlannerConfig,
    scenes: Sequence[Scene] | None = None,
) -> _OmplTally:
    """Every (d) query, ``settings.slow_repeats`` passes, each followed by our certificate of its path.

    ``cases`` holds (L, W) in its first two columns; ``scenes`` (one per case, default the
    coefficients' scene for all) places each obstacle, e.g. an answer's moved scene (its obstacle
    at the answer's centre x); the planner gets ``Obstacle.in_scene(L, W, scene)`` and the IK of
    that scene's P1 and P5."""
    scenes = [coefficients.scene] * len(cases) if scenes is None else list(scenes)

    def query(length: float, width: float, scene: Scene) -> tuple[Obstacle, planner.PlanResult]:
        obstacle = Obstacle.in_scene(length, width, scene)
        start, goal = planner.start_goal_configurations(obstacle, scene, arm.link_lengths_m, coefficients.elbow)
        return obstacle, planner.plan_rrt_connect(arm, obstacle, start, goal, config)

    query(float(cases[0, 0]), float(cases[0, 1]), scenes[0])  # warm-up
    tally = _OmplTally()
    for _ in range(settings.slow_repeats):
        for (length, width), scene in zip(cases[:, :2], scenes, strict=True):
            plan_s, (obstacle, result) = _timed(
                lambda length=length, width=width, scene=scene: query(float(length), float(width), scene)
            )
            if len(tally.obstacles) < len(cases):
                tally.obstacles.append(obstacle)
            certify_s = 0.0
            if result.solved and result.path is not None:
                certify_s, certificate = _timed(lambda r=result, o=obstacle: certify_path(r.path, arm, o))
                tally.clearances.append(certificate.certified_clearance_m)
                tally.waypoints.append(int(result.waypoints_rad.shape[0]))
                tally.answered_times.append(plan_s)
            elif not result.start_valid:
                tally.failures["start_invalid"] += 1
            elif not result.goal_valid:
                tally.failures["goal_invalid"] += 1
            else:
                tally.failures["not_solved"] += 1
            tally.checks.append(result.validity_checks)
            tally.coal_queries.append(result.coal_queries)
            tally.plan_times.append(plan_s)
            tally.total_times.append(plan_s + certify_s)
    return tally


def bench_ompl(
    coefficients: Any,
    cases: np.ndarray,
    arm: PlanarArm,
    settings: BenchSettings,
    validity_margin_m: float,
    margin_m: float,
    *,
    scenes: Sequence[Scene] | None = None,
    rows: tuple[tuple[str, str], tuple[str, str]] | None = None,
) -> tuple[MethodResult, MethodResult]:
    """(d) and (d+): RRT-Connect per query (setup, IK of P1 / P5, solve, simplify), then our certificate.

    Args:
        validity_margin_m: A state is valid iff both links' Coal clearance is >= this [m].
        margin_m: The scene's margin, for the "keeps margin" count [m].
        scenes: The scene of each obstacle (default: the coefficients' for all); with them, the
            rows' extra records every obstacle's centre x the planner got (``obstacle_centre_x_m``).
        rows: (key, label) of the two rows (default: "d" and "d_cert", as the table names them).
    """
    planner.seed_ompl(settings.seed)
    config = planner.PlannerConfig(
        time_limit_s=settings.ompl_time_s,
        margin_m=validity_margin_m,
        simplify=settings.ompl_simplify,
        resolution=settings.ompl_resolution,
        log_level="none",  # failures are counted below, with their reasons
    )
    tally = _ompl_queries(coefficients, cases, arm, settings, config, scenes)
    clearances = tally.clearances
    certified, keeps = certificate_counts(clearances, margin_m)
    limits = arm.position_limits_rad
    extent = math.hypot(limits[0][1] - limits[0][0], limits[1][1] - limits[1][0])
    extra = {
        "planner_failures": sum(tally.failures.values()),
        "failure_reasons": tally.failures,
        "median_answered_s": float(np.median(tally.answered_times)) if tally.answered_times else None,
        "time_limit_s": settings.ompl_time_s,
        "simplify": settings.ompl_simplify,
        "validity": f"Coal clearance of both links >= {validity_margin_m} m",
        "validity_margin_m": validity_margin_m,
        "validity_resolution": settings.ompl_resolution,
        "validity_resolution_rad": settings.ompl_resolution * extent,
        "validity_checks_median": float(np.median(tally.checks)),
        "coal_queries_median": float(np.median(tally.coal_queries)),
        "waypoints_median": float(np.median(tally.waypoints)) if tally.waypoints else None,
        "certified_clearance_min_m": min(clearances) if clearances else None,
        "certified_clearance_median_m": float(np.median(clearances)) if clearances else None,
    }
    if scenes is not None:
        extra["obstacle_centre_x_m"] = [float(o.centre_x_m) for o in tally.obstacles]
    common = {
        "obstacles": len(cases),
        "queries": len(tally.plan_times),
        "answered": len(clearances),
        "certified": certified,
        "keeps_margin": keeps,
        "extra": extra,
    }
    simplify = " + simplifySolution" if settings.ompl_simplify else ""
    if rows is None:
        rows = (
            ("d", "(d)  OMPL RRT-Connect" + (" + simplify" if settings.ompl_simplify else "")),
            ("d_cert", "(d+) OMPL path + our certificate"),
        )
    plan = MethodResult(
        key=rows[0][0],
        label=rows[0][1],
        times_s=tuple(tally.plan_times),
        note="per query: Coal checker + SimpleSetup + IK of P1/P5 + solve" + simplify,
        **common,
    )
    total = MethodResult(
        key=rows[1][0],
        label=rows[1][1],
        times_s=tuple(tally.total_times),
        note="(d) + certify_path (piecewise-linear certificate, Coal)",
        **common,
    )
    return plan, total


def bench_sweep(source: str, coefficients: Any, arm: PlanarArm, cases: np.ndarray) -> tuple[dict[str, Any], Any]:
    """Sweep rate of :func:`verify.acceptance.run.run_cases` (one process) with and without the certificate.

    Returns:
        (rates, the certified sweep's case results).
    """
    for certify in (False, True):  # warm-up of both routes (the first call of each compiles and loads)
        run_cases(source, cases[:1], MeasureSettings(certify=certify), jobs=1, coefficients=coefficients, arm=arm)
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


#: The stage times of a build_timing.json written before ``stages_s`` existed: key -> stage.
_OLDER_STAGE_KEYS = MappingProxyType(
    {
        "doe_s": "doe",
        "regression_s": "regression",
        "clearance_refit_s": "clearance_refit",
        "range_certificate_s": "range_certificate",
        "execution_bounds_s": "execution_bounds",
    }
)


def _total_and_stages(data: dict) -> tuple[float, dict[str, float], bool]:
    """The build's wall time [s], its stages [s] and whether the file is of the older kind.

    A file with ``stages_s`` gives both as written. An older file gave ``total_s`` for the DOE and
    regression only and, with a range map, ``total_with_range_certificate_s`` for the whole build
    but the writing: that is its total, and its stages are read from their separate keys."""
    if "stages_s" in data:
        return float(data["total_s"]), {str(k): float(v) for k, v in data["stages_s"].items()}, False
    total = float(data.get("total_with_range_certificate_s", data["total_s"]))
    stages = {stage: float(data[key]) for key, stage in _OLDER_STAGE_KEYS.items() if key in data}
    if stages and total >= sum(stages.values()):
        stages["other"] = total - sum(stages.values())
    return total, stages, True


def read_build_timing(path: Path) -> dict[str, Any] | None:
    """Summary of a build_timing.json (None if the file does not exist): the build's wall time
    (``total_s``) and its stages (``stages_s``), also from a file of the older kind (``older_format``).

    Raises:
        DataFileError: the file exists but is malformed.
    """
    if not path.is_file():
        return None
    data = read_json(path)
    try:
        experiments = [float(e["seconds"]) for e in data.get("experiments", [])]
        total_s, stages_s, older = _total_and_stages(data)
        return {
            "source": str(path),
            "total_s": total_s,
            "stages_s": stages_s,
            "older_format": older,
            "jobs": data.get("jobs"),
            "experiments": len(experiments),
            "experiment_seconds": experiments,
            "experiment_median_s": float(np.median(experiments)) if experiments else None,
            "coal_queries": int(data["coal_queries"]),
            "objective_evaluations": data.get("objective_evaluations"),
        }
    except (AttributeError, KeyError, TypeError, ValueError) as exc:
        raise DataFileError(path, f"not a build timing file ({type(exc).__name__}: {exc})") from None


def run_reduced_build(
    levels: int, config: SolverConfig, seed: int, urdf: Path | None, coefficients: Any
) -> dict[str, Any]:
    """Run the build (:func:`pipeline.build.run_build`) with ``levels`` levels per factor (>= 3)
    into a temporary folder, with the PSO and objective settings of (c) and the coefficients' scene and
    fitted range; its build_timing.json, summarised. The files are written even if the reduced
    build does not converge (a tiny PSO rarely does): it is timed here, not judged.

    Raises:
        PipelineError: the build failed.
    """
    fitness = config.fitness
    with tempfile.TemporaryDirectory(prefix="bench-build-") as folder:
        run_build(
            BuildConfig(
                out_folder=Path(folder),
                seed=seed,
                family=config.family,
                urdf_path=urdf,
                scene=coefficients.scene,
                design=DesignSettings(
                    levels=levels,
                    length_range_m=tuple(coefficients.fitted_range_m["L"]),
                    width_range_m=tuple(coefficients.fitted_range_m["W"]),
                ),
                optimiser=OptimiserSettings(
                    swarm_size=config.pso.swarm_size,
                    iterations=config.pso.iterations,
                    restarts=config.pso.restarts,
                    polish=config.polish,
                    n_points=fitness.n_points,
                    endpoint_weight=fitness.endpoint_weight,
                    penalty_weight=fitness.penalty_weight,
                    margin_buffer_m=fitness.margin_buffer_m,
                ),
                regression=RegressionSettings(allow_unconverged=True),
                range_map=RangeMapSettings(enabled=False),  # the DOE and regression are timed here, not the map
                execution=ExecutionSettings(jobs=1),  # the DOE's cost in one process, as the per-query methods
            )
        )
        summary = read_build_timing(Path(folder) / "build_timing.json")
    if summary is None:
        raise DataFileError(Path(folder) / "build_timing.json", "the build run by the benchmark wrote no timing file")
    pso = config.pso
    summary["source"] = (
        f"build run by the benchmark: {levels} x {levels} levels, PSO swarm {pso.swarm_size}, iterations "
        f"{pso.iterations}, restarts {pso.restarts}, polish {config.polish}"
    )
    return summary
