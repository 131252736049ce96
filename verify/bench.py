"""The benchmark: ``python -m verify.bench``.

On the same ``--n`` random obstacles it times side by side the regression generator (per query
and batched), the generator with the range certificate (per query and batched), the generator
with certification, the generator with the near time-optimal timing certified and TOPP-RA on its
paths, the PSO re-run online and OMPL's RRT-Connect (:mod:`verify.benchmark`), and
prints the medians, their ratios and how many answers are certified collision-free. With
coefficients over (L, W, x) (``--coefficients-x``, or ``results-x/coefficients.json``), it also times
the generator with their map on random (L, W, x) and OMPL on the same moved obstacles.

Exit status: 0 on success, 2 on bad input (one line on stderr), 130 if interrupted.

This module only parses the command line and calls :func:`verify.benchmark.run.run_bench`.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from pipeline.cli import (
    DEFAULT_COEFFICIENTS,
    EXIT_OK,
    Parser,
    add_progress_argument,
    describe_coefficients,
    run_cli,
)
from pipeline.exceptions import PipelineError
from pipeline.io.jsonio import write_json_atomic
from pipeline.io.output_paths import check_output_file
from pipeline.io.progress import ProgressBars
from pipeline.motion.families import PAPER_SOURCE
from verify.benchmark.report import format_report
from verify.benchmark.results import (
    DEFAULT_BUILD_TIMING,
    DEFAULT_COEFFICIENTS_X,
    MAKE_COEFFICIENTS_X,
    BenchSettings,
)
from verify.benchmark.run import run_bench
from verify.cli_support import arm_for_verify, load_coefficients_for_verify

PROG = "python -m verify.bench"


def _add_method_options(parser: argparse.ArgumentParser, defaults: BenchSettings) -> None:
    parser.add_argument(
        "--coefficients",
        metavar="FILE",
        default=DEFAULT_COEFFICIENTS,
        help=f"coefficients file, or '{PAPER_SOURCE}' for the paper's Eq. 9",
    )
    parser.add_argument("--n", type=int, default=defaults.n, help="random obstacles (L, W) [cases] (>= 1)")
    parser.add_argument(
        "--seed", type=int, default=defaults.seed, help="seed of the obstacles, PSO and OMPL (>= 0) (default: 0)"
    )
    parser.add_argument(
        "--batch-size",
        type=int,
        default=defaults.batch_size,
        help="obstacles per call of the batched rows (a') and (a*'): the --n obstacles cycled to this many "
        "[obstacles] (values below --n count as --n)",
    )
    parser.add_argument(
        "--repeats",
        type=int,
        default=defaults.repeats,
        help="timed passes over the obstacles of the per-query rows (a), (a*) and (a*) over (L, W, x), interleaved: "
        "one pass of each in turn, so that they sample the same stretches of the machine's time [passes]",
    )
    parser.add_argument(
        "--batch-repeats",
        type=int,
        default=defaults.batch_repeats,
        help="timed passes of the batched rows (a'), (a*') and (r*') [passes]",
    )
    parser.add_argument(
        "--region-map",
        type=Path,
        metavar="FILE",
        default=None,
        help="region map (range certificate) of the coefficients for (a*) (default: region_map.json beside the "
        "coefficients, if it certifies them; if there is none, e.g. for 'paper', the coefficients are certified "
        "first, with the build's settings in one process, not timed but reported: that takes minutes, about 1 min "
        "for the default build and 4.5 min for 'paper'); a map of other coefficients is refused",
    )
    parser.add_argument(
        "--coefficients-x",
        type=Path,
        metavar="FILE",
        default=None,
        help="coefficients over (L, W, x), with their region map beside them, for the row (a*) over (L, W, x) "
        "(generate(..., x=x) with the map, on random (L, W, x) in their box) and OMPL on the same moved obstacles "
        f"(default: {DEFAULT_COEFFICIENTS_X} if it exists, else the row is left out; {MAKE_COEFFICIENTS_X} "
        "makes it)",
    )
    parser.add_argument(
        "--no-x", action="store_true", help="leave out the rows over (L, W, x) even if their coefficients exist"
    )
    parser.add_argument(
        "--slow-repeats",
        type=int,
        default=defaults.slow_repeats,
        help="timed passes over the obstacles for (r*), (b), (n*), (tp) and (d) [passes]",
    )
    parser.add_argument(
        "--toppra-gridpoints",
        type=int,
        default=defaults.toppra_gridpoints,
        help="TOPP-RA's gridpoints in (tp), on (n*)'s paths and limits; its output is checked at 100x as many "
        "instants [gridpoints]",
    )
    parser.add_argument(
        "--no-near-optimal",
        action="store_true",
        help="skip (n*) the near-optimal certified timing and (tp) TOPP-RA on its paths (default: run them)",
    )


def _add_pso_options(parser: argparse.ArgumentParser, defaults: BenchSettings) -> None:
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


def _add_ompl_options(parser: argparse.ArgumentParser, defaults: BenchSettings) -> None:
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


def _add_output_options(parser: argparse.ArgumentParser) -> None:
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
    parser.add_argument(
        "--urdf",
        type=Path,
        metavar="FILE",
        default=None,
        help="URDF of the arm (default: the one recorded with the coefficients; given, it must match them)",
    )
    parser.add_argument("--json", type=Path, metavar="FILE", default=None, help="write the report as JSON")
    parser.add_argument("--quiet", action="store_true", help="no progress lines or bars on stderr (default: show them)")
    add_progress_argument(parser)


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface of ``python -m verify.bench``."""
    defaults = BenchSettings()
    parser = Parser(
        prog=PROG,
        description=(
            "Time, on the same random obstacles in one run: (a) the regression generator per query and "
            "batched, (a*) the same with the range certificate's bounds (region map), (b) the generator "
            "with certification, (n*) the generator with the near time-optimal timing certified and (tp) TOPP-RA "
            "on its paths and limits (with T'/T_TOPP-RA and each one's sampled excess over a limit), (c) re-running "
            "the PSO online, (d) OMPL "
            "RRT-Connect with a Coal validity checker, then our certificate of its path; with coefficients over "
            "(L, W, x), (a*) over (L, W, x) and (d) on the same moved obstacles. Prints median "
            "time per query, ratios to (a) and (b), the fraction of answers certified collision-free, the "
            "build time and the sweep rate. Ratios measured in one run on this machine, not absolute claims."
        ),
    )
    _add_method_options(parser, defaults)
    _add_pso_options(parser, defaults)
    _add_ompl_options(parser, defaults)
    _add_output_options(parser)
    return parser


def settings_from_args(args: argparse.Namespace) -> BenchSettings:
    """BenchSettings from parsed arguments (raises InvalidParameterError, named after the option, on bad values)."""
    return BenchSettings(
        n=args.n,
        seed=args.seed,
        repeats=args.repeats,
        batch_repeats=args.batch_repeats,
        batch_size=args.batch_size,
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
        region_map=args.region_map,
        coefficients_x=args.coefficients_x,
        run_x=not args.no_x,
        run_near_optimal=not args.no_near_optimal,
        toppra_gridpoints=args.toppra_gridpoints,
    )


def _work(args: argparse.Namespace, argv: Sequence[str]) -> int:
    settings = settings_from_args(args)
    check_output_file(args.json, "--json")
    # With --region-map, the map beside the coefficients is not read (the named one replaces it).
    coefficients = load_coefficients_for_verify(PROG, args.coefficients, beside=args.region_map is None)
    arm = arm_for_verify(coefficients, args.urdf)
    print(describe_coefficients(coefficients), flush=True)
    try:
        with ProgressBars(enabled=not (args.quiet or args.no_progress)) as bars:

            def log(message: str) -> None:
                if not args.quiet:
                    bars.close()  # a finished stage's bar stays above the line
                    print(message, file=sys.stderr, flush=True)

            report = run_bench(
                args.coefficients,
                settings,
                command=" ".join([PROG, *argv]),
                log=log,
                coefficients=coefficients,
                arm=arm,
                progress=bars,
            )
        print(format_report(report))
        if args.json is not None:
            write_json_atomic(args.json, report.to_json())
            print(f"wrote {args.json}")
    except OSError as exc:  # a file that could not be read or written despite the checks
        raise PipelineError(f"{exc.filename or ''}: {exc.strerror or exc}") from None
    return EXIT_OK


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark; returns the exit status (0 done, 2 bad input, 130 interrupted)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    return run_cli(build_parser(), lambda args: _work(args, argv), argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
