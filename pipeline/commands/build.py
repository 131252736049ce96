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
from collections.abc import Callable, Mapping
from pathlib import Path
from types import MappingProxyType
from typing import Any, TextIO

from pipeline.build import BuildConfig, BuildResult, run_build
from pipeline.build.arm_scene import d_range_for_arm, scene_for_arm
from pipeline.build.options import BUILD_OPTIONS, GROUPS, OPTIONS, SETTINGS, Option, vary_name
from pipeline.build.run import stage_summary
from pipeline.certify.certifiable_regression import clearance_refit_lines
from pipeline.certify.map_for_coefficients import summary_lines
from pipeline.cli import (
    EXIT_FAILED,
    EXIT_OK,
    Parser,
    add_progress_argument,
    count_argument,
    finite_positive,
    jobs_count,
    run_cli,
    worker_timeout,
)
from pipeline.commands.regress import OVERWRITE_RULE
from pipeline.exceptions import BuildNotConvergedError
from pipeline.io.output_paths import check_output_folder
from pipeline.io.progress import ProgressBars
from pipeline.model.arm import DEFAULT_URDF, load_planar_arm
from pipeline.motion.families import PAPER, PAPER_SOURCE, TrajectoryFamily
from pipeline.offline import report
from pipeline.offline.coefficients import read_coefficients
from pipeline.offline.designs import ScaledDesign

PROG = "python -m pipeline.build"


#: argparse's type of each kind of option (:attr:`pipeline.build.options.Option.kind`), from the option.
_TYPES: Mapping[str, Callable[[Option], Callable[[str], Any] | None]] = MappingProxyType(
    {
        "text": lambda option: None,
        "int": lambda option: int,
        "float": lambda option: float,
        "path": lambda option: Path,
        "count": lambda option: count_argument,
        "jobs": lambda option: jobs_count,
        "timeout": lambda option: worker_timeout,
        "positive": lambda option: finite_positive(option.flag, option.unit),
    }
)


def _cli_default(option: Option, settings: Mapping[str, Any]) -> Any:
    """The default argparse gets for ``option``: its own, or its setting's default as typed on the
    command line (a list for a tuple, the name of a design kind or a family)."""
    if option.cli_default is not ...:
        return option.cli_default
    value = settings[option.name]
    if isinstance(value, tuple):
        return list(value)
    if isinstance(value, type) and issubclass(value, ScaledDesign):
        return value.kind
    if isinstance(value, TrajectoryFamily):
        return value.name
    return value


def add_option(container: argparse._ActionsContainer, option: Option, settings: Mapping[str, Any]) -> None:
    """Add ``option`` (one of :data:`pipeline.build.options.BUILD_OPTIONS`) to a parser or group;
    ``settings``: the defaults by setting name (:meth:`BuildConfig.settings`)."""
    keywords: dict[str, Any] = {"help": option.help_text()}
    if option.dest:
        keywords["dest"] = option.dest
    if option.action == "store_true":
        container.add_argument(option.flag, action="store_true", **keywords)
        return
    for key in ("action", "nargs", "metavar", "choices"):
        if getattr(option, key) is not None:
            keywords[key] = getattr(option, key)
    parse = _TYPES[option.kind](option)
    if parse is not None:
        keywords["type"] = parse
    container.add_argument(option.flag, default=_cli_default(option, settings), **keywords)


def parser() -> Parser:
    """The command line's options: :data:`pipeline.build.options.BUILD_OPTIONS` (every default is
    :class:`pipeline.build.BuildConfig`'s), --quiet and --no-progress."""
    p = Parser(
        prog=PROG,
        description="Run the DOE (PSO + exact Coal clearance per obstacle), regress the coefficients and certify "
        "them over their fitted range; the files are written as one set at the end.",
        epilog=f"{OVERWRITE_RULE} Exit status: 0 written, 1 not converged (nothing written), 2 bad input, "
        "130 interrupted, 143 terminated (SIGTERM; SIGHUP: 129).",
    )
    settings = BuildConfig().settings()
    groups: dict[str, argparse._ActionsContainer] = {"": p}
    for option in BUILD_OPTIONS:
        if option.help_group not in groups:
            groups[option.help_group] = p.add_argument_group(*GROUPS[option.help_group])
        add_option(groups[option.help_group], option, settings)
    p.add_argument("--quiet", action="store_true", help="no progress bars or tables")
    add_progress_argument(p)
    return p


def config_from_args(args: argparse.Namespace) -> BuildConfig:
    """The :class:`BuildConfig` of parsed options (each setting read as its option declares).

    Raises:
        InvalidParameterError, DataFileError: a bad value or scene file (naming the option or key).
    """
    return BuildConfig.from_settings(**{option.name: option.value(args) for option in SETTINGS.values()})


def _without_bare_d(args: argparse.Namespace) -> tuple[argparse.Namespace, bool]:
    """``args`` without a ``--vary d`` that gives no range, and whether there was one (its range is
    then the arm's window: :func:`_with_d_for_arm`)."""
    items = list(args.vary or [])
    rest = [item for item in items if not (len(item) == 1 and vary_name(item[0]) == "d")]
    if len(rest) == len(items):
        return args, False
    return argparse.Namespace(**{**vars(args), "vary": rest}), True


def _with_d_for_arm(config: BuildConfig) -> BuildConfig:
    """``config`` varying d over the arm's window (:func:`d_range_for_arm`), said on stderr; the
    output folder is checked first, so that a bad --out is refused before the search."""
    check_output_folder(config.out_folder, OPTIONS["out_folder"], new_parents=False)
    config, note = d_range_for_arm(load_planar_arm(config.urdf_path), config)
    print(f"{PROG}: {note}", file=sys.stderr)
    return config


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
    design, default = config.design, BuildConfig().design
    shrink = (design.length_range_m, design.width_range_m) == (default.length_range_m, default.width_range_m)
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
    args, d_from_arm = _without_bare_d(args)
    config = config_from_args(args)
    config = _with_d_for_arm(config) if d_from_arm else _with_scene_for_arm(config, args)
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
