"""The benchmark (the library of ``python -m verify.bench``).

On the same ``--n`` random obstacles (L, W) (uniform in the coefficients' fitted range, seeded),
in one run on this machine, it times side by side:

* **(a)** the regression generator alone (:func:`pipeline.online.generator.generate`), one query at a
  time, and **(a')** batched (:func:`pipeline.online.generator.generate_parameters` over all obstacles,
  time divided by their number);
* **(a*)** the generator with the range certificate (``generate(..., region_map=...)``: the same
  parameters, plus the certified clearance and endpoint bounds of the map's cell), one query at a
  time and batched (:func:`pipeline.online.batch.generate_batch` with the map, per obstacle); the
  map is the one beside the coefficients, ``--region-map``'s, or certified in-process
  (:mod:`verify.benchmark.range_map`);
* **(n*)** the generator with the near time-optimal timing built and certified per query
  (``generate_certified(..., timing=NearOptimal(from_map=False), region_map=m)``), and **TOPP-RA**
  (the ``toppra`` library) on its paths and limits, per query; with the ratio T'/T_TOPP-RA and each
  method's largest sampled excess over a limit (:mod:`verify.benchmark.near_optimal`);
* **(n*g)**, **(n*m)**, **(n*m')** the near-optimal timing from the map's near-optimal cells:
  ``g.near_optimal(L, W)`` per query (timed side by side with (a) and (a*)), ``generate_certified(...,
  timing=NEAR_OPTIMAL)`` per query, and ``execution_batch(..., NEAR_OPTIMAL)`` batched, with the
  ratio of (n*m)'s T' to TOPP-RA's on the same paths;
* **(b)** the generator with certification (:func:`pipeline.online.repair.generate_certified`:
  certify, repair if needed, or refuse);
* **(c)** re-running the PSO online for that (L, W) (:func:`pipeline.offline.experiment.solve_experiment`,
  what the regression replaces; seconds per obstacle, so only on the first ``--pso-cases``);
* **(d)** a general-purpose planner: OMPL's RRT-Connect from the start to the goal configuration
  (analytic IK of P1 and P5) with a Coal validity checker on the same geometry
  (:mod:`verify.benchmark.ompl_planner`), alone and **(d+)** followed by our certificate of its
  piecewise-linear path;
* **(a*) over (L, W, x)**: with coefficients that also vary the obstacle's centre x and their map,
  ``generate(..., x=x)`` per query on random (L, W, x), and (d), (d+) on the same moved obstacles
  (:mod:`verify.benchmark.over_x`).

It reports per method the median time per query, its ratio to (a) and to (b), the ratios of (d) to
(a), (a*) and (b), the fraction of
queries answered and the fraction of the answers that are **certified collision-free** by our
certificates (a rigorous lower bound on the clearance over the whole continuous motion > 0) or
keep the margin. It also reports the build's time and Coal query count (``results/build_timing.json``
written by ``python -m pipeline.build``, or a reduced build it runs itself with ``--run-build``)
and the sweep rate of :func:`verify.acceptance.run.run_cases` with and without the certificate.

The figures are ratios measured in one run on one machine, never absolute claims: times use
``time.perf_counter``, every method is warmed up first, and the cheap methods are repeated many
times so their medians are stable; the per-query rows (a), (a*), (n*g) and (a*) over (L, W, x) in
interleaved passes, so that they sample the same stretches of a shared machine's time.
"""

from __future__ import annotations

import math
import os
import platform
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from pipeline import load_coefficients
from pipeline.exceptions import PipelineError
from pipeline.geometry.sinusoid_certificate import certify_trajectory
from pipeline.io.progress import ProgressCallback
from pipeline.io.provenance import PACKAGES, package_versions
from pipeline.model.arm import PlanarArm
from pipeline.motion.near_optimal import NEAR_OPTIMAL
from pipeline.motion.rest_to_rest import REST_TO_REST
from pipeline.motion.trajectory import JointTrajectory
from pipeline.offline.coefficients import Coefficients
from pipeline.offline.experiment import SolverConfig
from pipeline.offline.fitness import FitnessConfig
from pipeline.offline.pso import PsoConfig
from pipeline.online.loading import BESIDE
from pipeline.online.repair import endpoint_tolerance_of
from verify.acceptance.cases import SweepRange, sample_cases
from verify.acceptance.metrics import check_arm_matches
from verify.acceptance.run import arm_for_sweep

from . import near_optimal as near
from . import ompl_planner as planner
from . import over_x, toppra_peer
from .methods import (
    batch_range_counts,
    bench_batched,
    bench_certified,
    bench_ompl,
    bench_pso,
    bench_range_batched,
    bench_rest_to_rest,
    bench_rest_to_rest_batched,
    bench_sweep,
    certificate_counts,
    range_counts,
    read_build_timing,
    run_reduced_build,
)
from .per_query import PerQueryRow, time_side_by_side
from .range_map import BenchRegionMap, bench_region_map
from .results import BenchReport, BenchSettings, MethodResult

# --------------------------------------------------------------------------------------------
# Helpers


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
        "versions": package_versions((*PACKAGES, "ompl")),
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
            fitness = FitnessConfig.from_json(provenance.get("fitness", {}))
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


# --------------------------------------------------------------------------------------------
# The run


@dataclass(frozen=True)
class _Context:
    """What every method of one benchmark run shares."""

    source: str
    coefficients: Coefficients
    arm: PlanarArm
    cases: np.ndarray
    margin_m: float
    settings: BenchSettings
    log: Callable[[str], None]


def _sweep_and_generator(ctx: _Context, timed: PerQueryRow) -> tuple[list[MethodResult], dict[str, Any], list[Any]]:
    """(a) from its ``timed`` row, (a') and the sweep rate (whose certified pass also certifies
    (a)'s answers); and (a)'s answers."""
    cases, margin, settings = ctx.cases, ctx.margin_m, ctx.settings
    times_a, answers = timed.times_s, timed.answers
    ctx.log("timing the sweep with and without the certificate (and certifying (a)'s answers) ...")
    sweep_info, certified_cases = bench_sweep(ctx.source, ctx.coefficients, ctx.arm, cases)
    clearances_a = [c.certified_clearance_m for c in certified_cases if c.certified_clearance_m is not None]
    certified_a, keeps_a = certificate_counts(clearances_a, margin)
    answered_a = sum(a is not None for a in answers)
    method_a = MethodResult(
        key="a",
        label="(a)  regression generator, per query",
        obstacles=len(cases),
        times_s=tuple(times_a),
        queries=len(cases),
        answered=answered_a,
        certified=certified_a,
        keeps_margin=keeps_a,
        note=f"generate(coefficients, L, W), each call timed; passes over the obstacles: {settings.repeats}, "
        "interleaved with the other per-query rows'",
    )
    ctx.log("timing (a') the regression generator, batched ...")
    batch_cases = _batch_cases(cases, settings.batch_size)
    times_batch, parameters = bench_batched(ctx.coefficients, batch_cases, settings.batch_repeats)
    parameters = parameters[: len(cases)]
    same = _same_parameters(list(parameters), answers)
    if same:
        certified_batch, keeps_batch = certified_a, keeps_a
    else:
        certified_batch, keeps_batch = _certify_batch(ctx, parameters, answers)
    method_batch = MethodResult(
        key="a_batch",
        label=f"(a') regression generator, batched ({len(batch_cases)} per call)",
        obstacles=len(cases),
        times_s=tuple(times_batch),
        queries=len(cases),
        answered=answered_a,
        certified=certified_batch,
        keeps_margin=keeps_batch,
        note=f"generate_parameters(coefficients, L[:], W[:]) / {len(batch_cases)} (the {len(cases)} obstacles "
        "cycled); parameters only (no path object)" + ("; same parameters as (a)" if same else ""),
        extra={"same_parameters_as_a": same},
    )
    return [method_a, method_batch], sweep_info, answers


def _time_per_query(
    ctx: _Context, bench_map: BenchRegionMap, coefficients_x: Coefficients | None
) -> dict[str, PerQueryRow]:
    """Time the per-query rows side by side (:mod:`verify.benchmark.per_query`): (a), (a*) and, with
    ``coefficients_x``, (a*) over (L, W, x) on their random obstacles; the rows by key."""
    settings = ctx.settings
    rows = {
        "a": PerQueryRow(ctx.coefficients, ctx.cases),
        "a_range": PerQueryRow(ctx.coefficients, ctx.cases, bench_map.region_map),
    }
    names = "(a), (a*)"
    attached = ctx.coefficients.region_map
    if attached is not None and attached.near_optimal_cells is not None:
        rows[NEAR_LOOKUP_KEY] = PerQueryRow(ctx.coefficients, ctx.cases, near_optimal=True)
        names += ", (n*g)"
    if coefficients_x is not None:
        cases_x = over_x.sample_cases_x(coefficients_x, settings.n, settings.seed)
        rows[over_x.KEY] = PerQueryRow(coefficients_x, cases_x, coefficients_x.region_map)
        names += f" and {over_x.row_name(coefficients_x)}"
    ctx.log(f"timing {names} one query at a time, side by side ({settings.repeats} interleaved passes) ...")
    time_side_by_side(list(rows.values()), settings.repeats)
    return rows


def _batch_cases(cases: np.ndarray, batch_size: int) -> np.ndarray:
    """The bench's obstacles cycled to ``batch_size`` rows (at least all of them), for the batched rows."""
    return np.resize(cases, (max(len(cases), batch_size), 2))


def _certify_batch(ctx: _Context, parameters: np.ndarray, answers: list[Any]) -> tuple[int, int]:
    """Certified and margin-keeping counts of the batched parameters, where they differ from (a)'s."""
    clearances = []
    for row, answer in zip(parameters, answers, strict=True):
        if answer is not None:
            trajectory = JointTrajectory(tuple(row), answer.duration_s)
            clearances.append(certify_trajectory(trajectory, ctx.arm, answer.obstacle).certified_clearance_m)
    return certificate_counts(clearances, ctx.margin_m)


def _same_parameters(rows: Any, answers_a: list[Any]) -> bool:
    """True if every row of parameters equals (a)'s answer for that obstacle to 1e-12 (both answered)."""
    return all(
        row is not None and answer is not None and np.allclose(row, answer.trajectory.array, rtol=1e-12, atol=1e-12)
        for row, answer in zip(rows, answers_a, strict=True)
    )


def _range_methods(
    ctx: _Context, bench_map: BenchRegionMap, answers_a: list[Any], timed: PerQueryRow
) -> list[MethodResult]:
    """(a*) per query (from its ``timed`` row) and batched: the generator with the range certificate's bounds."""
    cases, margin, settings, region_map = ctx.cases, ctx.margin_m, ctx.settings, bench_map.region_map
    times, answers = timed.times_s, timed.answers
    counts = range_counts(answers, margin)
    same = _same_parameters([None if a is None else a.trajectory.array for a in answers], answers_a)
    common = {"obstacles": len(cases), "queries": len(cases), "answered": sum(a is not None for a in answers)}
    per_query = MethodResult(
        key="a_range",
        label="(a*) generator with range certificate",
        times_s=tuple(times),
        certified=counts.certified,
        keeps_margin=counts.keeps_margin,
        note=f"generate(coefficients, L, W, region_map=m), each call timed; passes: {settings.repeats}, interleaved "
        "with the other per-query rows'; "
        f"{counts.certified} of {counts.in_range} in-range queries answered with a certified clearance > 0, "
        f"{counts.keeps_margin} >= the margin; parameters " + ("equal (a)'s" if same else "DIFFER from (a)'s"),
        extra={
            "in_range_queries": counts.in_range,
            "same_parameters_as_a": same,
            "certified_clearance_min_m": counts.clearance_min_m,
        },
        **common,
    )
    ctx.log("timing (a*') the generator with the range certificate, batched ...")
    batch_cases = _batch_cases(cases, settings.batch_size)
    times_batch, batch = bench_range_batched(ctx.coefficients, batch_cases, region_map, settings.batch_repeats)
    counts_batch = batch_range_counts(batch, margin, len(cases))
    same_batch = _same_parameters(list(batch.parameters[: len(cases)]), answers_a)
    batched = MethodResult(
        key="a_range_batch",
        label=f"(a*') range-certified, batched ({len(batch_cases)} per call)",
        times_s=tuple(times_batch),
        certified=counts_batch.certified,
        keeps_margin=counts_batch.keeps_margin,
        note=f"generate_batch(coefficients, L[:], W[:], region_map=m) / {len(batch_cases)} (the {len(cases)} "
        "obstacles cycled): parameters, T and the map's bounds per obstacle"
        + ("; same parameters as (a)" if same_batch else "; parameters DIFFER from (a)'s"),
        extra={"in_range_queries": counts_batch.in_range, "same_parameters_as_a": same_batch},
        **common,
    )
    return [per_query, batched]


#: The row of ``g.near_optimal(L, W)``, timed side by side with (a) and (a*).
NEAR_LOOKUP_KEY = "n_opt_lookup"


def _near_lookup_method(ctx: _Context, timed: PerQueryRow) -> MethodResult:
    """(n*g): the certified near-optimal answer read off the map (clearance, endpoints, T' and the
    cell's bounds), per query, from its ``timed`` row."""
    answered = [a for a in timed.answers if a is not None]
    return MethodResult(
        key=NEAR_LOOKUP_KEY,
        label="(n*g) near-optimal certified, map lookup",
        obstacles=len(ctx.cases),
        times_s=tuple(timed.times_s),
        queries=len(timed.answers),
        answered=len(answered),
        certified=len(answered),
        keeps_margin=len(answered),
        note="g.near_optimal(L, W) (pipeline.online.map_timing.near_optimal_from_map): the regression's answer "
        "with the map's clearance and endpoint bounds and the near-optimal cell's T' and bounds (the motion built "
        f"on first use); passes: {ctx.settings.repeats}, interleaved with (a)'s and (a*)'s; refused where the map "
        f"does not decide: {len(timed.answers) - len(answered)} of {len(timed.answers)}",
    )


def _per_query_from_map(ctx: _Context, region_map, timing) -> tuple[list[float], list[Any], list[Any], int]:
    """``generate_certified(..., timing=timing)`` per query with the map: (times [s], answers with
    None for a refusal, the answered ones, how many took their limit bounds from the map)."""
    times, answers = bench_rest_to_rest(
        ctx.coefficients, ctx.cases, ctx.arm, region_map, ctx.settings.slow_repeats, timing
    )
    answered = [a for a in answers if a is not None]
    return times, answers, answered, sum(a.execution_source == "range" for a in answered)


def _batched_from_map(ctx: _Context, region_map, timing) -> tuple[list[float], int, np.ndarray, np.ndarray]:
    """``generate_batch`` + ``execution_batch(..., timing)``: (times per obstacle [s], the batch
    size, per bench obstacle whether its bounds keep the limits, and whether it is certified in
    full: the limits, the margin and the endpoint tolerance, all from the map)."""
    batch_cases = _batch_cases(ctx.cases, ctx.settings.batch_size)
    times, batch, result = bench_rest_to_rest_batched(
        ctx.coefficients, batch_cases, region_map, ctx.settings.batch_repeats, timing
    )
    n = len(ctx.cases)
    within = result.within_limits[:n]
    tolerance = endpoint_tolerance_of(ctx.coefficients)
    full = within & (batch.certified_clearance_m[:n] >= ctx.margin_m) & (batch.endpoint_error_bound_m[:n] <= tolerance)
    return times, len(batch_cases), within, full


def _rest_to_rest_methods(ctx: _Context, bench_map: BenchRegionMap) -> list[MethodResult]:
    """(r*) per query and (r*') batched: certified to execute with the rest-to-rest timing, from the map."""
    region_map, settings, cases = bench_map.region_map, ctx.settings, ctx.cases
    if region_map.execution is None:
        return []
    ctx.log("timing (r*) certified rest-to-rest answers from the map, one query at a time ...")
    times, answers, answered, from_map = _per_query_from_map(ctx, region_map, REST_TO_REST)
    per_query = MethodResult(
        key="r_range",
        label="(r*) certified rest-to-rest, from the map",
        obstacles=len(cases),
        times_s=tuple(times),
        queries=len(answers),
        answered=len(answered),
        certified=sum(a.certified_clearance_m > 0.0 for a in answered),
        keeps_margin=sum(a.certified_clearance_m >= ctx.margin_m for a in answered),
        note="generate_certified(coefficients, L, W, timing=REST_TO_REST, region_map=m): clearance, endpoints, "
        f"angles, |dq|, |ddq|, |tau| over [0, T']; limit bounds from the map's leaf for {from_map} of "
        f"{len(answered)} answers (per query for the rest); passes: {settings.slow_repeats}",
        extra={"execution_from_map": from_map},
    )
    ctx.log("timing (r*') certified rest-to-rest from the map, batched ...")
    times_batch, size, within, full = _batched_from_map(ctx, region_map, REST_TO_REST)
    n = len(cases)
    batched = MethodResult(
        key="r_range_batch",
        label=f"(r*') certified rest-to-rest, batched ({size} per call)",
        obstacles=n,
        times_s=tuple(times_batch),
        queries=n,
        answered=int(np.sum(full)),
        certified=int(np.sum(full)),
        keeps_margin=int(np.sum(full)),
        note=f"generate_batch + execution_batch(coefficients, batch, REST_TO_REST) / {size}: T', the "
        f"rest-to-rest timing and its bounds from the map's leaf; {int(np.sum(within))} of {n} obstacles within "
        f"the arm's limits, {int(np.sum(full))} also with the margin and the endpoint tolerance from the map "
        "(answered: these, certified in full without a per-query certificate)",
        extra={"within_limits": int(np.sum(within)), "certified_in_full": int(np.sum(full))},
    )
    return [per_query, batched]


def _certified_method(ctx: _Context) -> MethodResult:
    """(b): the generator with certification (certify-or-repair)."""
    ctx.log("timing (b) the generator with certification (certify-or-repair) ...")
    times_b, clearances_b, repairs = bench_certified(ctx.coefficients, ctx.cases, ctx.arm, ctx.settings.slow_repeats)
    answered = [c for c in clearances_b if c is not None]
    certified_b, keeps_b = certificate_counts(answered, ctx.margin_m)
    refusals = len(clearances_b) - len(answered)
    return MethodResult(
        key="b",
        label="(b)  generator + certificate (or repair)",
        obstacles=len(ctx.cases),
        times_s=tuple(times_b),
        queries=len(clearances_b),
        answered=len(answered),
        certified=certified_b,
        keeps_margin=keeps_b,
        note=f"generate_certified(...) (Coal certificate to the {ctx.margin_m} m margin, repair if needed, "
        "endpoints and the arm's limits with the paper timing, else refuse); "
        f"passes: {ctx.settings.slow_repeats}; repairs: {repairs}, refusals: "
        f"{refusals} of {len(clearances_b)} queries",
        extra={"repairs": repairs, "refusals": refusals},
    )


def _near_optimal_methods(
    ctx: _Context, bench_map: BenchRegionMap, skipped: dict[str, str]
) -> tuple[list[MethodResult], dict[str, Any] | None]:
    """(n*) and TOPP-RA on its paths (:mod:`verify.benchmark.near_optimal`), and their summary;
    TOPP-RA is skipped (reason in ``skipped``) if toppra is not installed."""
    settings, cases = ctx.settings, ctx.cases
    if not settings.run_near_optimal:
        skipped[near.KEY] = "--no-near-optimal"
        return [], None
    with_toppra = toppra_peer.toppra_available()
    if not with_toppra:
        skipped[near.TOPPRA_KEY] = "toppra is not installed (pip install toppra, or the project's 'bench' extra)"
    grid = settings.toppra_gridpoints
    ctx.log(
        f"timing (n*) near-optimal certified per query{f' and toppra ({grid} grid points)' if with_toppra else ''}, "
        f"interleaved ({settings.slow_repeats} passes) ..."
    )
    rows = near.bench_near_optimal(
        ctx.coefficients, cases, ctx.arm, bench_map.region_map, settings.slow_repeats, grid, with_toppra=with_toppra
    )
    answered = [a for a in rows.answers if a is not None]
    clearances = [a.certified_clearance_m for a in answered]
    certified, keeps = certificate_counts(clearances, ctx.margin_m)
    summary = rows.summary()
    ours = summary["ours_excess_max"]
    methods = [
        MethodResult(
            key=near.KEY,
            label="(n*) near-optimal certified per query",
            obstacles=len(cases),
            times_s=rows.near_times_s,
            queries=len(rows.answers),
            answered=len(answered),
            certified=certified,
            keeps_margin=keeps,
            note="generate_certified(coefficients, L, W, timing=NearOptimal(from_map=False), region_map=m): "
            "clearance (map or per query), endpoints, and the near time-optimal timing built and certified per "
            "query over [0, T'] against the limits "
            f"with the servo defaults; passes: {settings.slow_repeats}, interleaved with TOPP-RA's; refusals "
            f"(last pass): {sum(rows.refusals.values())} {rows.refusals or ''}".rstrip(),
            extra={
                "refusals": rows.refusals,
                "sampled_excess_max": ours,
                "duration_s_median": float(np.median([a.duration_s for a in answered])) if answered else None,
            },
        )
    ]
    if with_toppra:
        timed = [r for r in rows.toppra if r is not None]
        paired = [a for a, r in zip(rows.answers, rows.toppra, strict=True) if a is not None and r is not None]
        certified_t, keeps_t = certificate_counts([a.certified_clearance_m for a in paired], ctx.margin_m)
        methods.append(
            MethodResult(
                key=near.TOPPRA_KEY,
                label=f"(tp) toppra ({grid} grid points) per query",
                obstacles=len(cases),
                times_s=rows.toppra_times_s or (math.nan,),
                queries=len(answered),
                answered=len(timed),
                certified=certified_t,
                keeps_margin=keeps_t,
                note=f"toppra_timing(answer.trajectory, answer.execution.limits, dynamics, {grid} gridpoints) on "
                "(n*)'s paths and limits (speed, acceleration, closed-form torque; no jerk), the toppra call "
                "timed (constraints, set-up, compute_parameterization); the path's clearance is (n*)'s, which "
                f"holds for any timing; its limits are not certified; passes: {settings.slow_repeats}; failures "
                f"(last pass): {len(rows.toppra_failures)}",
                extra={
                    "gridpoints": grid,
                    "failures": list(rows.toppra_failures),
                    "sampled_excess_max": summary["toppra_excess_max"],
                    "duration_s_median": float(np.median([r.duration_s for r in timed])) if timed else None,
                },
            )
        )
    map_methods, map_ratios = _near_optimal_map_methods(ctx, bench_map, rows)
    methods.extend(map_methods)
    summary.update(map_ratios)
    return methods, summary


def _near_optimal_map_methods(
    ctx: _Context, bench_map: BenchRegionMap, rows: near.NearOptimalRows
) -> tuple[list[MethodResult], dict[str, Any]]:
    """(n*m) per query and (n*m') batched: the near-optimal timing read off the map's near-optimal
    cells; and T'/T_TOPP-RA of (n*m)'s answers on (tp)'s paths (the same obstacles)."""
    region_map, settings, cases = bench_map.region_map, ctx.settings, ctx.cases
    if region_map.near_optimal_cells is None:
        return [], {}
    ctx.log("timing (n*m) near-optimal from the map's cells, one query at a time ...")
    times, answers, answered, from_map = _per_query_from_map(ctx, region_map, NEAR_OPTIMAL)
    per_query = MethodResult(
        key="n_opt_map",
        label="(n*m) near-optimal certified, from the map",
        obstacles=len(cases),
        times_s=tuple(times),
        queries=len(answers),
        answered=len(answered),
        certified=sum(a.certified_clearance_m > 0.0 for a in answered),
        keeps_margin=sum(a.certified_clearance_m >= ctx.margin_m for a in answered),
        note="generate_certified(coefficients, L, W, timing=NEAR_OPTIMAL, region_map=m): clearance, endpoints, "
        f"and the near-optimal timing with its bounds (jerk included) from the map's cell for {from_map} of "
        f"{len(answered)} answers (per query for the rest); passes: {settings.slow_repeats}",
        extra={"execution_from_map": from_map},
    )
    ctx.log("timing (n*m') near-optimal from the map's cells, batched ...")
    times_batch, size, within, full = _batched_from_map(ctx, region_map, NEAR_OPTIMAL)
    n = len(cases)
    batched = MethodResult(
        key="n_opt_map_batch",
        label=f"(n*m') near-optimal certified, batched ({size} per call)",
        obstacles=n,
        times_s=tuple(times_batch),
        queries=n,
        answered=int(np.sum(full)),
        certified=int(np.sum(full)),
        keeps_margin=int(np.sum(full)),
        note=f"generate_batch + execution_batch(coefficients, batch, NEAR_OPTIMAL) / {size}: T' and the bounds of "
        f"each obstacle's near-optimal cell; {int(np.sum(within))} of {n} obstacles within the limits, "
        f"{int(np.sum(full))} also with the margin and the endpoint tolerance from the map",
        extra={"within_limits": int(np.sum(within)), "certified_in_full": int(np.sum(full))},
    )
    ratios = [
        a.duration_s / r.duration_s
        for a, r in zip(answers, rows.toppra, strict=True)
        if a is not None and r is not None and a.execution_source == "range"
    ]
    summary = {"map_over_toppra": [float(np.median(ratios)), float(np.max(ratios))] if ratios else None}
    return [per_query, batched], summary


def _pso_method(ctx: _Context, config: SolverConfig, pso_source: str) -> MethodResult:
    """(c): the PSO re-run online on the first ``pso_cases`` obstacles."""
    n = ctx.settings.pso_cases
    ctx.log(f"timing (c) re-running the PSO online on {n} obstacle(s) ({pso_source}) ...")
    times_c, clearances_c, details = bench_pso(
        ctx.coefficients, ctx.cases[:n], ctx.arm, config, ctx.settings.seed, ctx.log
    )
    certified_c, keeps_c = certificate_counts(clearances_c, ctx.margin_m)
    return MethodResult(
        key="c",
        label="(c)  PSO online (solve_experiment)",
        obstacles=n,
        times_s=tuple(times_c),
        queries=n,
        answered=n,
        certified=certified_c,
        keeps_margin=keeps_c,
        note=f"solve_experiment on the first {n} obstacle(s), one run each, no warm-up; "
        f"PSO swarm {config.pso.swarm_size}, iterations {config.pso.iterations}, restarts "
        f"{config.pso.restarts}, polish {config.polish} ({pso_source}); optimum then certified (not timed)",
        extra={"cases": details, "pso": asdict(config.pso), "polish": config.polish, "source": pso_source},
    )


def _ompl_methods(ctx: _Context, skipped: dict[str, str]) -> list[MethodResult]:
    """(d) and (d+) if OMPL is wanted and installed; else the reason goes into ``skipped``."""
    settings = ctx.settings
    if not settings.run_ompl:
        skipped["d"] = "--no-ompl"
        return []
    if not planner.ompl_available():
        skipped["d"] = "ompl is not installed (pip install ompl, or the project's 'bench' extra)"
        return []
    ctx.log(f"timing (d) OMPL RRT-Connect ({settings.ompl_time_s} s budget per query) ...")
    try:
        ompl_margin = ctx.margin_m if settings.ompl_margin_m is None else settings.ompl_margin_m
        return list(bench_ompl(ctx.coefficients, ctx.cases, ctx.arm, settings, ompl_margin, ctx.margin_m))
    except ImportError as exc:
        skipped["d"] = f"ompl could not be imported ({exc})"
        return []


def _build_info(ctx: _Context, timing: dict[str, Any] | None, config: SolverConfig) -> dict[str, Any] | None:
    """The build timing file's summary and, with ``run_build_levels``, a reduced build run here."""
    settings = ctx.settings
    if settings.run_build_levels is not None:
        levels = settings.run_build_levels
        ctx.log(f"running a reduced build ({levels} x {levels} levels) ...")
        reduced = run_reduced_build(levels, config, settings.seed, ctx.arm.urdf_path, ctx.coefficients)
        return {"file": timing, "reduced": reduced}
    if timing is not None:
        return {"file": timing, "reduced": None}
    if settings.build_timing is not None:
        return {
            "file": None,
            "reduced": None,
            "missing": f"{settings.build_timing} not found (written by python -m pipeline.build)",
        }
    return None


def run_bench(
    source: str,
    settings: BenchSettings,
    *,
    command: str = "",
    log: Callable[[str], None] = lambda _: None,
    coefficients: Coefficients | None = None,
    arm: PlanarArm | None = None,
    progress: ProgressCallback | None = None,
    coefficients_x: Coefficients | None = None,
) -> BenchReport:
    """Run every method on the same random obstacles and collect the report.

    Args:
        source: Coefficients file or the paper's name.
        settings: What to run.
        command: The command line, recorded in the report.
        log: Progress messages.
        coefficients: ``source`` already loaded (optional; with the region map beside it, as
            :func:`pipeline.load_coefficients` loads it, unless ``settings.region_map`` names one).
        arm: The arm already loaded (optional; default ``settings.urdf``'s, else the one recorded
            with the coefficients; checked against them).
        progress: Progress of long stages (the in-process range certificate, if one is needed).
        coefficients_x: Coefficients over (L, W, x) with their region map attached, for the rows
            over (L, W, x) (optional; default: loaded from ``settings.coefficients_x``, else
            ``results-x/coefficients.json`` if it exists, else those rows are left out and
            ``skipped`` says how to make them; not loaded with ``settings.run_x`` False).

    Raises:
        DataFileError: missing or malformed coefficients / build timing file / region map, or a
            ``settings.region_map`` that certifies other coefficients; coefficients over (L, W, x)
            that do not vary (L, W, x) or have no map beside them.
        InvalidParameterError: coefficients fitted for another arm, or bad settings.
    """
    started = time.perf_counter()
    machine = machine_info()  # load average at the start
    ready = _prepared(source, settings, log, (coefficients, arm, coefficients_x), progress)
    ctx, config, pso_source = ready.ctx, ready.config, ready.pso_source
    measured = _measured_methods(ctx, ready.bench_map, config, pso_source, ready.coefficients_x)
    build_info = _build_info(ctx, ready.build_timing, config)
    settings_json = {key: (str(value) if isinstance(value, Path) else value) for key, value in asdict(settings).items()}
    settings_json.update(pso_resolved=asdict(config.pso), polish=config.polish, pso_settings_source=pso_source)
    coefficients = ctx.coefficients
    return BenchReport(
        coefficients={
            "source": source,
            "family": coefficients.family.name,
            "sha256": coefficients.source_sha256,
            "fitted_range_m": {k: list(v) for k, v in coefficients.fitted_range_m.items()},
        },
        settings=settings_json,
        cases_m=ctx.cases,
        margin_m=ctx.margin_m,
        methods=tuple(measured.methods),
        skipped=measured.skipped,
        sweep=measured.sweep,
        build=build_info,
        range_map=ready.bench_map.to_json(),
        machine=machine,
        command=command,
        elapsed_s=time.perf_counter() - started,
        over_x=measured.over_x,
        near_optimal=measured.near_optimal,
    )


@dataclass(frozen=True)
class _Prepared:
    """What :func:`run_bench` reads and checks before minutes of work.

    Attributes:
        ctx: What every method shares (coefficients, arm, cases, margin, settings, log).
        build_timing: The build timing file's contents (None if none is named).
        config: The PSO and fitness settings of (c) and a build; ``pso_source`` where they came from.
        bench_map: The region map of the coefficients (read, or certified in-process).
        coefficients_x: Coefficients over (L, W, x) for their rows (None: those rows are left out).
    """

    ctx: _Context
    build_timing: dict[str, Any] | None
    config: SolverConfig
    pso_source: str
    bench_map: BenchRegionMap
    coefficients_x: Coefficients | None


def _prepared(
    source: str,
    settings: BenchSettings,
    log: Callable[[str], None],
    loaded: tuple[Coefficients | None, PlanarArm | None, Coefficients | None],
    progress: ProgressCallback | None,
) -> _Prepared:
    """The benchmark's inputs, every file read and checked in the order that reports a bad one
    before minutes of work: the coefficients, the arm, the cases, the build timing, a named region
    map, the coefficients over (L, W, x); last the map beside the coefficients, or certified.

    Args:
        loaded: The coefficients, arm and coefficients over (L, W, x) already loaded (each optional),
            as :func:`run_bench` takes them.
    """
    coefficients, arm, coefficients_x = loaded
    if coefficients is None:
        coefficients = load_coefficients(source, region_map=None if settings.region_map is not None else BESIDE)
    if arm is None:
        arm = arm_for_sweep(coefficients, settings.urdf)
    else:
        check_arm_matches(coefficients, arm)
    cases = sample_cases(SweepRange.from_fitted(coefficients.fitted_range_m), settings.n, settings.seed)
    ctx = _Context(source, coefficients, arm, cases, coefficients.scene.margin_m, settings, log)
    # Build timing first (a missing or malformed file is reported before minutes of work).
    timing = read_build_timing(settings.build_timing) if settings.build_timing is not None else None
    config, pso_source = solver_config(coefficients, settings)
    bench_map = None
    if settings.region_map is not None:  # a named map costs one read: checked before everything else
        bench_map = bench_region_map(coefficients, settings.region_map, log=log, progress=progress, arm=arm)
    if settings.run_x and coefficients_x is None:  # before minutes of work: a bad file is reported first
        path_x = over_x.coefficients_x_path(settings)
        coefficients_x = None if path_x is None else over_x.timed_load(path_x, arm, log)
    if bench_map is None:  # the map beside the coefficients, or certified in-process (minutes)
        bench_map = bench_region_map(coefficients, None, log=log, progress=progress, arm=arm)
    return _Prepared(ctx, timing, config, pso_source, bench_map, coefficients_x if settings.run_x else None)


@dataclass(frozen=True)
class _Measured:
    """The methods :func:`run_bench` timed, with what the report says beside them.

    Attributes:
        methods: Every method's result, in the order they ran.
        skipped: Method key -> why it was skipped.
        sweep: Sweep rates.
        near_optimal: (n*) against TOPP-RA (None if (n*) did not run).
        over_x: The rows over (L, W, x) (None if they did not run).
    """

    methods: list[MethodResult]
    skipped: dict[str, str]
    sweep: dict[str, Any] | None
    near_optimal: dict[str, Any] | None
    over_x: dict[str, Any] | None


def _measured_methods(
    ctx: _Context,
    bench_map: BenchRegionMap,
    config: SolverConfig,
    pso_source: str,
    coefficients_x: Coefficients | None,
) -> _Measured:
    """Every method on the same obstacles, in turn: the per-query rows, the sweep and the generator,
    the range certificate's rows, rest-to-rest, (b), (n*) and TOPP-RA, (c) the PSO, (d) OMPL, and
    the rows over (L, W, x) if ``coefficients_x`` is given."""
    settings = ctx.settings
    rows = _time_per_query(ctx, bench_map, coefficients_x)
    methods, sweep_info, answers_a = _sweep_and_generator(ctx, rows["a"])
    methods.extend(_range_methods(ctx, bench_map, answers_a, rows["a_range"]))
    methods.extend(_rest_to_rest_methods(ctx, bench_map))
    if NEAR_LOOKUP_KEY in rows:
        methods.append(_near_lookup_method(ctx, rows[NEAR_LOOKUP_KEY]))
    methods.append(_certified_method(ctx))
    skipped: dict[str, str] = {}
    near_methods, near_summary = _near_optimal_methods(ctx, bench_map, skipped)
    methods.extend(near_methods)
    if settings.pso_cases > 0:
        methods.append(_pso_method(ctx, config, pso_source))
    else:
        skipped["c"] = "--pso-cases 0"
    methods.extend(_ompl_methods(ctx, skipped))
    info_x = None
    if coefficients_x is not None:
        methods_x, info_x = over_x.x_methods(
            rows[over_x.KEY], ctx.arm, settings, log=ctx.log, skipped=skipped, ompl_margin_m=settings.ompl_margin_m
        )
        methods.extend(methods_x)
    else:
        skipped[over_x.KEY] = over_x.missing_reason(settings)
    return _Measured(methods, skipped, sweep_info, near_summary, info_x)
