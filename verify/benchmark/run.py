"""The benchmark: ``python -m verify.bench``.

On the same ``--n`` random obstacles (L, W) (uniform in the coefficients' fitted range, seeded),
in one run on this machine, it times side by side:

* **(a)** the regression generator alone (:func:`pipeline.online.generator.generate`), one query at a
  time, and **(a')** batched (:func:`pipeline.online.generator.generate_parameters` over all obstacles,
  time divided by their number);
* **(b)** the generator with certification (:func:`pipeline.online.repair.generate_certified`:
  certify, repair if needed, or refuse);
* **(c)** re-running the PSO online for that (L, W) (:func:`pipeline.offline.experiment.solve_experiment`,
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
import os
import platform
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

import numpy as np
from verify.cli import DEFAULT_COEFFICIENTS, HelpFormatter, Parser, load_coefficients_for_cli

from pipeline.exceptions import PipelineError
from pipeline.geometry.sinusoid_certificate import certify_trajectory
from pipeline.io.jsonio import write_json_atomic
from pipeline.io.provenance import PACKAGES, package_versions
from pipeline.model.arm import load_planar_arm
from pipeline.motion.trajectory import JointTrajectory
from pipeline.offline.experiment import SolverConfig
from pipeline.offline.fitness import FitnessConfig
from pipeline.offline.pso import PsoConfig

from . import planner
from .bench_methods import (
    bench_batched,
    bench_certified,
    bench_generator,
    bench_ompl,
    bench_pso,
    bench_sweep,
    certificate_counts,
    read_build_timing,
    run_reduced_build,
)
from .bench_report import format_report
from .bench_results import (
    DEFAULT_BUILD_TIMING,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_USAGE,
    PROG,
    BenchReport,
    BenchSettings,
    MethodResult,
)
from .metrics import check_arm_matches
from .sweep import SweepRange, sample_cases

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
    coefficients = load_coefficients_for_cli(source)
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
    certified_a, keeps_a = certificate_counts(clearances_a, margin)
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
        certified_batch, keeps_batch = certificate_counts(clearances_batch, margin)
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
    certified_b, keeps_b = certificate_counts(answered_clearances, margin)
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
        certified_c, keeps_c = certificate_counts(clearances_c, margin)
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
            "family": coefficients.family.name,
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
