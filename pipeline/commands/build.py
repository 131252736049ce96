"""``python -m pipeline.build``: DOE -> PSO per experiment -> regression -> certifiable
regression -> range map, written as one set of files.

The command parses its options into a :class:`pipeline.build.BuildConfig`, calls
:func:`pipeline.build.run_build` (which does all the work and writes ``DIR/doe.json``,
``DIR/coefficients.json``, ``DIR/region_map.json``, ``DIR/build_timing.json`` and, for an arm
other than the shipped one, ``DIR/arm.urdf``, all at the end; see :mod:`pipeline.build.run`),
shows its progress on stderr, and prints our Table 2 and Eq. 9 beside the paper's, the
certifiable regression's rounds and the range certificate's area fractions.

Exit status: 0 written; 1 the build did not converge (nothing written, the failing experiments
named; ``--allow-unconverged`` writes anyway, marked); 2 bad input (one line, before any work; a
folder another build is writing included); 130 interrupted (Ctrl-C); 143 (SIGTERM) or 129 (SIGHUP)
terminated, the worker processes stopped and the folder as it was.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TextIO

from pipeline.build import BuildConfig, BuildResult, run_build
from pipeline.build.arm_scene import scene_for_arm
from pipeline.build.config import OPTIONS, SCENE_OPTIONS, VARY_NAMES, scene_from_options, vary_name
from pipeline.build.run import stage_summary
from pipeline.certify.certifiable_regression import DEFAULT_CLEARANCE_ROUNDS, clearance_refit_lines
from pipeline.certify.map_for_coefficients import summary_lines
from pipeline.certify.region_map import DEFAULT_MAP_NAME
from pipeline.cli import (
    EXIT_FAILED,
    EXIT_OK,
    Parser,
    add_acceleration_limit_argument,
    add_progress_argument,
    add_scheduler_arguments,
    count_argument,
    jobs_count,
    run_cli,
)
from pipeline.commands.regress import OVERWRITE_RULE, add_regression_arguments
from pipeline.exceptions import BuildNotConvergedError, InvalidParameterError
from pipeline.io.output_paths import check_output_folder
from pipeline.io.progress import ProgressBars
from pipeline.model.arm import DEFAULT_URDF, load_planar_arm
from pipeline.model.scene import SCENE_FIELDS, Scene
from pipeline.motion.families import FAMILY_NAMES, PAPER, PAPER_SOURCE
from pipeline.offline import report
from pipeline.offline.coefficients import read_coefficients
from pipeline.offline.convergence import ConvergenceCriteria
from pipeline.offline.designs import DEFAULT_RANGES_M, DESIGN_KINDS, FullFactorial
from pipeline.offline.endpoint_regression import EndpointConstraint

PROG = "python -m pipeline.build"


def _scene_arguments(p: argparse.ArgumentParser) -> None:
    scene = Scene()
    group = p.add_argument_group(
        "scene",
        "the scene is the defaults below, then the keys of --scene FILE, then these options; it is stored in "
        "coefficients.json and every later step reads it from there",
    )
    group.add_argument(
        "--scene",
        type=Path,
        metavar="FILE",
        help="scene file, TOML (.toml) or JSON (.json), whose keys are the scene's fields as stored in "
        f"coefficients.json ({', '.join(SCENE_FIELDS)}), e.g. top_y_m = 0.54; an unknown key is refused",
    )
    for field_name, text in (
        ("top_y_m", "d, the y of the obstacle's far edge [m]"),
        ("start_y_m", "y1 = y5, the height of the start and goal points [m] (default: d)"),
        ("speed_m_s", "end-effector speed v along the path [m/s]"),
        ("margin_m", "safety margin between links and obstacle [m]"),
        ("corner_radius_m", "obstacle corner radius [m]"),
    ):
        option = SCENE_OPTIONS[field_name]
        default = getattr(scene, field_name)
        if default is not None:
            text += f" (default: {default}, or the scene file's)"
        group.add_argument(
            option, type=float, dest=field_name, metavar="M" if "speed" not in option else "V", help=text
        )


def _convergence_arguments(p: argparse.ArgumentParser) -> None:
    criteria = ConvergenceCriteria()
    group = p.add_argument_group(
        "convergence",
        "the build exits 1 and writes nothing if a DOE optimum's dense Coal clearance is below the margin (for "
        "exact-endpoints: below the margin or its end poses' clearance, whichever is smaller), if a DOE optimum "
        "misses P1 or P5 by more than --max-doe-endpoint-error, or if the endpoint-constrained regression misses "
        "--endpoint-tolerance on its grid",
    )
    group.add_argument(
        "--max-doe-endpoint-error",
        type=float,
        default=criteria.endpoint_error_max_m,
        metavar="M",
        help="largest endpoint error of a DOE optimum [m]; the default build's optima: up to 6.1 mm, with "
        "top_y_m = 0.54: 27 mm, after a 2-iteration PSO: 168 mm (the regression's own limit is --endpoint-tolerance)",
    )
    group.add_argument(
        "--allow-unconverged",
        action="store_true",
        help='write the files anyway, marked "converged": false with the reasons; loading them warns',
    )


def _design_arguments(p: argparse.ArgumentParser, d: BuildConfig) -> None:
    """--out, --seed and the design of experiments: levels, ranges, varied variables, design kind."""
    p.add_argument(
        "--out",
        type=Path,
        default=d.out_folder,
        help="output folder (doe.json, coefficients.json, region_map.json and .npy, build_timing.json; arm.urdf for a "
        "--urdf other than the shipped arm)",
    )
    p.add_argument(
        "--seed",
        type=int,
        default=d.seed,
        help="master random seed [integer >= 0]; the same seed, the same files (default: 0)",
    )
    p.add_argument(
        "--levels",
        type=int,
        default=d.levels,
        help="levels per factor [count] of the full-factorial design (K^k runs: K x K over (L, W)), K >= 3",
    )
    p.add_argument(
        "--L-range", nargs=2, type=float, default=list(d.length_range_m), metavar=("MIN", "MAX"), help="L range [m]"
    )
    p.add_argument(
        "--W-range", nargs=2, type=float, default=list(d.width_range_m), metavar=("MIN", "MAX"), help="W range [m]"
    )
    default_ranges = ", ".join(f"{name}: {lo:g} {hi:g}" for name, (lo, hi) in DEFAULT_RANGES_M.items())
    p.add_argument(
        "--vary",
        nargs="+",
        action="append",
        default=[],
        metavar="NAME [MIN MAX]",
        help=f"vary a scene variable beside L and W over [MIN, MAX] [m] (repeatable): {', '.join(VARY_NAMES)} "
        "(x: the obstacle's centre x, d: its far edge y, default --top-y); a NAME alone takes its default range "
        f"({default_ranges}; |x| < 0.06 m keeps P1..P5 of every corner of the default (L, W) range in reach). "
        "The coefficients then vary these too (python -m pipeline.generate --x); the region map covers them "
        "(d only with y1 = d, i.e. without --start-y; otherwise none is written)",
    )
    p.add_argument(
        "--design",
        choices=tuple(DESIGN_KINDS),
        default=FullFactorial.kind,
        help="the DOE: full-factorial (--levels per factor, the paper's 3 x 3 over (L, W)), box-behnken "
        "(3 or more factors: 2k(k-1)+1 runs) or central-composite (face-centred, 2^k+2k+1 runs); the last two "
        "from pyDOE, with one centre run (default: full-factorial)",
    )


def _optimiser_arguments(p: argparse.ArgumentParser, d: BuildConfig) -> None:
    """The PSO and its objective (Eq. 5 with the clearance penalty)."""
    pso = p.add_argument_group("optimiser")
    pso.add_argument("--swarm-size", type=int, default=d.swarm_size, help="PSO particles per swarm [count]")
    pso.add_argument("--iterations", type=int, default=d.iterations, help="PSO iterations per restart [count]")
    pso.add_argument("--restarts", type=int, default=d.restarts, help="independent PSO swarms [count], each polished")
    pso.add_argument("--no-polish", action="store_true", help="skip the least_squares polish after PSO")
    pso.add_argument("--n-points", type=int, default=d.n_points, help="path points n of Eq. 5 [count], uniform in x")
    pso.add_argument(
        "--endpoint-weight",
        type=float,
        default=d.endpoint_weight,
        help="weight of the first and last 3 path points in Eq. 5 [-]",
    )
    pso.add_argument(
        "--penalty-weight",
        type=float,
        default=d.penalty_weight,
        help="clearance penalty weight [1/m^2 relative to Eq. 5's m^2]",
    )
    pso.add_argument(
        "--margin-buffer",
        type=float,
        default=d.margin_buffer_m,
        metavar="M",
        help="extra clearance the optimiser aims for beyond the margin [m]",
    )


def _map_arguments(p: argparse.ArgumentParser) -> None:
    """The range certificate and the certifiable regression's rounds before it."""
    p.add_argument(
        "--no-range-map",
        action="store_true",
        help=f"do not certify the coefficients over their fitted range (by default {DEFAULT_MAP_NAME} is written "
        "beside them, linked by their sha256; see python -m pipeline.certify_range)",
    )
    p.add_argument(
        "--near-optimal-cells",
        type=count_argument,
        default=None,
        metavar="N",
        help="cells per axis of the map's certified near-optimal timings (one timing per cell, read at lookup "
        "cost); 0: none [count] (default: 64 over (L, W), 16 over three axes, 8 over four)",
    )
    p.add_argument(
        "--clearance-rounds",
        type=count_argument,
        default=DEFAULT_CLEARANCE_ROUNDS,
        metavar="N",
        help="paper family with the endpoint constraint: rounds of the certifiable regression before the map "
        "(certify, constrain the worst point of every cell below the margin that is not proven infeasible, "
        f"refit); 0: none [count] (default: {DEFAULT_CLEARANCE_ROUNDS})",
    )


def parser() -> Parser:
    """The command line's options (every default is :class:`pipeline.build.BuildConfig`'s)."""
    d = BuildConfig()
    p = Parser(
        prog=PROG,
        description="Run the DOE (PSO + exact Coal clearance per obstacle), regress the coefficients and certify "
        "them over their fitted range; the files are written as one set at the end.",
        epilog=f"{OVERWRITE_RULE} Exit status: 0 written, 1 not converged (nothing written), 2 bad input, "
        "130 interrupted, 143 terminated (SIGTERM; SIGHUP: 129).",
    )
    _design_arguments(p, d)
    p.add_argument("--family", choices=FAMILY_NAMES, default=PAPER.name, help="trajectory family")
    p.add_argument(
        "--jobs",
        type=jobs_count,
        default="0",
        help="worker processes [count], 0 = every CPU; the files do not depend on it (default: 0)",
    )
    add_scheduler_arguments(p)
    p.add_argument(
        "--urdf",
        type=Path,
        default=DEFAULT_URDF,
        help="URDF of the arm (default: the paper's arm, shipped with the package); another URDF is copied beside "
        "the coefficients as arm.urdf, and later commands use it from there",
    )
    _scene_arguments(p)
    _optimiser_arguments(p, d)
    add_regression_arguments(p, default_tolerance_m=EndpointConstraint.tolerance_m)
    _convergence_arguments(p)
    _map_arguments(p)
    add_acceleration_limit_argument(
        p,
        "recorded in the coefficients; python -m pipeline.generate and generate_certified hold answers to them "
        "(default: none)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bars or tables")
    add_progress_argument(p)
    return p


def _vary(item: list[str]) -> tuple[str, float, float]:
    """One ``--vary NAME [MIN MAX]`` as (name, min, max); a NAME alone takes its default range.

    Raises:
        InvalidParameterError: not NAME or NAME MIN MAX, a bad name (with the closest valid one),
            no default range for NAME, or a bound that is not a number.
    """
    option = OPTIONS["vary"]
    if len(item) not in (1, 3):
        raise InvalidParameterError(option, " ".join(item), "NAME MIN MAX, or NAME alone for its default range")
    name = vary_name(item[0])
    if len(item) == 1:
        if name not in DEFAULT_RANGES_M:
            raise InvalidParameterError(option, name, f"NAME MIN MAX ({name} has no default range)")
        return (name, *DEFAULT_RANGES_M[name])
    bounds = []
    for text in item[1:]:
        try:
            bounds.append(float(text))
        except ValueError:
            raise InvalidParameterError(f"{option} {name}", text, "a number [m]") from None
    return (name, bounds[0], bounds[1])


def config_from_args(args: argparse.Namespace) -> BuildConfig:
    """The :class:`BuildConfig` of parsed options.

    Raises:
        InvalidParameterError, DataFileError: a bad value or scene file (naming the option or key).
    """
    scene = scene_from_options(args.scene, **{name: getattr(args, name) for name in SCENE_OPTIONS})
    return BuildConfig(
        out_folder=args.out,
        seed=args.seed,
        levels=args.levels,
        length_range_m=tuple(args.L_range),
        width_range_m=tuple(args.W_range),
        vary=tuple(_vary(item) for item in args.vary),
        design_kind=args.design,
        family=args.family,
        jobs=args.jobs,
        scheduler=args.scheduler,
        worker_timeout_s=args.worker_timeout,
        urdf_path=args.urdf,
        scene=scene,
        swarm_size=args.swarm_size,
        iterations=args.iterations,
        restarts=args.restarts,
        polish=not args.no_polish,
        n_points=args.n_points,
        endpoint_weight=args.endpoint_weight,
        penalty_weight=args.penalty_weight,
        margin_buffer_m=args.margin_buffer,
        endpoint_tolerance_m=None if args.plain else args.endpoint_tolerance,
        doe_endpoint_error_max_m=args.max_doe_endpoint_error,
        allow_unconverged=args.allow_unconverged,
        acceleration_limits_rad_s2=args.acceleration_limit,
        range_map=not args.no_range_map,
        clearance_rounds=args.clearance_rounds,
        near_optimal_cells=args.near_optimal_cells,
    )


def _with_scene_for_arm(config: BuildConfig, args: argparse.Namespace) -> BuildConfig:
    """``config`` with the obstacle's far edge d chosen for the arm (:func:`scene_for_arm`) when a
    URDF other than the shipped one is given without --top-y, --scene or a varying d: the build
    says which d it chose and why (on stderr). The L and W ranges are shrunk only when they are
    the defaults. The output folder is checked first, so that a bad --out is refused before the search."""
    if (
        args.top_y_m is not None
        or args.scene is not None
        or Path(args.urdf).resolve() == DEFAULT_URDF.resolve()
        or "d" in config.variables.names
    ):
        return config
    check_output_folder(config.out_folder, OPTIONS["out_folder"], new_parents=False)
    default = BuildConfig()
    shrink = (config.length_range_m, config.width_range_m) == (default.length_range_m, default.width_range_m)
    config, note = scene_for_arm(load_planar_arm(config.urdf_path), config, shrink=shrink)
    print(f"{PROG}: {note}", file=sys.stderr)
    return config


def print_report(result: BuildResult, out: TextIO) -> None:
    """Our Table 2 and Eq. 9 beside the paper's, the regression method and the timing (the total
    wall time and its stages, as in build_timing.json)."""
    coefficients, timing = result.coefficients, result.timing
    print("Table 2 (ours, with the paper's row below where the design matches it):", file=out)
    extra_names = coefficients.variables.extra
    print(report.table2(result.doe_document["experiments"], result.paper_rows, extra_names), file=out)
    same_basis = coefficients.family == PAPER and coefficients.variables.is_size_only
    paper_eq9 = read_coefficients(PAPER_SOURCE).parameters if same_basis else None
    print("\nEq. 9 (ours, paper below):", file=out)
    fit = coefficients.extra["fit"]
    print(report.equation9(coefficients.parameters, paper_eq9, fit, coefficients.variables.basis), file=out)
    print(report.regression_method(coefficients.extra["fit"]), file=out)
    print(
        f"\nTiming: {timing['total_s']:.1f} s wall in all ({stage_summary(timing)}); "
        + ", ".join(f"{r.seconds:.1f}" for r in result.experiments)
        + f" s per experiment; {timing['coal_queries']} Coal distance queries, "
        f"{timing['objective_evaluations']} objective evaluations (analytic route)",
        file=out,
    )


def _problem_lines(problems) -> str:
    return "".join(f"\n  {problem}" for problem in problems)


def run(args: argparse.Namespace, out: TextIO | None = None) -> int:
    """Run the build for parsed options and print what it did; returns the exit status (0
    written, 1 not converged).

    Raises:
        PipelineError: bad input (``main`` prints it as one line).
    """
    out = sys.stdout if out is None else out
    config = _with_scene_for_arm(config_from_args(args), args)
    try:
        with ProgressBars(enabled=not (args.quiet or args.no_progress)) as bars:
            result = run_build(config, progress=bars)
    except BuildNotConvergedError as exc:
        print(
            f"{PROG}: error: the build did not converge, nothing written (--allow-unconverged writes it, marked):"
            + _problem_lines(exc.problems),
            file=sys.stderr,
        )
        return EXIT_FAILED
    if not args.quiet:
        print_report(result, out)
    print(f"solver: {', '.join(sorted({r.solver for r in result.experiments}))}", file=out)
    if result.refit_report is not None:
        print("\n".join(clearance_refit_lines(result.refit_report)), file=out)
    if result.region_map is not None:
        print("\n".join(summary_lines(result.region_map)), file=out)
    elif result.range_map_skipped is not None:
        print(f"range certificate: skipped, {result.range_map_skipped}", file=out)
    if not result.converged:
        print(
            f'{PROG}: warning: the build did not converge; written with "converged": false:'
            + _problem_lines(result.problems),
            file=sys.stderr,
        )
    for written in result.written:
        print(written, file=out)
    print(
        f"build {result.timing['total_s']:.1f} s wall (build_timing.json; sha256 of coefficients.json "
        f"{result.coefficients.source_sha256[:12]})",
        file=out,
    )
    return EXIT_OK


def main(argv: list[str] | None = None) -> int:
    """Entry point: parse ``argv``, run, one line per usage error; returns the exit status."""
    return run_cli(parser(), run, argv)


if __name__ == "__main__":
    sys.exit(main())
