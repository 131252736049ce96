"""The acceptance verifier: ``python -m verify.sweep``.

For ``n`` cases drawn uniformly (seeded) from the box of the coefficients' variables — the
obstacle size (L, W) and, for coefficients that vary them, the other scene variables such as the
obstacle's centre x [m] — over their fitted range (``--range`` replaces the (L, W) part), the
trajectory is generated from the coefficients exactly as an online user would (with the
obstacle and path moved to the case's x) and measured (:mod:`verify.acceptance`): sampled and
certified clearance (Pinocchio + Coal, continuous-time certificate), endpoint errors, tracking
errors, joint peaks against the URDF.

Exit status: 0 if every case passes (and agrees with the region map), 1 if any case fails (they
are listed with their (L, W) and extra values), 2 on bad input (one line on stderr, no traceback), 130 if interrupted.

``--coefficients paper`` judges the paper's own Eq. 9 with the same verifier; ``--compare A B``
runs both on the same sampled cases and prints them side by side (both must vary the same
variables).

The range certificate (``region_map.json``, written by the build beside the coefficients) is
reported and every sampled case is cross-checked against it, in the leaf holding its whole point
(:mod:`verify.acceptance.range_check`); a case that contradicts it fails the run. One beside the
coefficients that was made for other coefficients is not used (a warning says so). ``--region-map
FILE`` names another map (the only way for ``paper``), reported as not belonging and not checked
if it was made for other coefficients (with ``--compare`` it belongs to one of them at most);
``--no-region-map`` skips the map.

The arm is the one recorded with the coefficients (``--urdf`` names one, which must match them).

This module only parses the command line and calls the library.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from pipeline.certify.map_files import load_region_map
from pipeline.certify.region_map import RegionMap
from pipeline.cli import (
    DEFAULT_COEFFICIENTS,
    EXIT_FAILED,
    EXIT_OK,
    Parser,
    describe_coefficients,
    jobs_count,
    run_cli,
)
from pipeline.exceptions import InvalidParameterError, PipelineError
from pipeline.geometry.motion_certificate import DEFAULT_MAX_EVALUATIONS, DEFAULT_TOLERANCE_M
from pipeline.io.jsonio import write_json_atomic
from pipeline.io.output_paths import check_output_file, check_output_folder
from pipeline.io.progress import progress_enabled
from pipeline.model.arm import PlanarArm
from pipeline.motion.families import PAPER_SOURCE
from pipeline.offline.coefficients import Coefficients
from pipeline.online.loading import map_path_beside
from pipeline.validation import check_finite, check_non_negative, check_positive, check_positive_int
from verify.acceptance.cases import SweepRange, sample_cases
from verify.acceptance.metrics import (
    CERTIFICATE_MODES,
    TRACKING_RESOLUTION_M,
    AcceptanceThresholds,
    MeasureSettings,
)
from verify.acceptance.report import format_comparison, format_summary
from verify.acceptance.run import DEFAULT_CASES, DEFAULT_SEED, SweepRun, run_sweep, source_label
from verify.cli_support import arm_for_verify, load_coefficients_for_verify

PROG = "python -m verify.sweep"


# --------------------------------------------------------------------------------------------
# Options


def _add_source_options(parser: argparse.ArgumentParser) -> None:
    source = parser.add_mutually_exclusive_group()
    source.add_argument(
        "--coefficients",
        metavar="FILE",
        default=DEFAULT_COEFFICIENTS,
        help=f"coefficients file to judge, or '{PAPER_SOURCE}' for the paper's Eq. 9",
    )
    source.add_argument(
        "--compare",
        nargs=2,
        metavar=("A", "B"),
        default=None,
        help=f"judge two coefficients sources (files or '{PAPER_SOURCE}') on the same cases and print them side "
        "by side; the default range is the intersection of their fitted ranges",
    )


def _add_region_map_options(parser: argparse.ArgumentParser) -> None:
    choice = parser.add_mutually_exclusive_group()
    choice.add_argument(
        "--region-map",
        metavar="FILE",
        type=Path,
        default=None,
        help="region map (python -m pipeline.certify_range) to report and cross-check the cases against "
        "(default: region_map.json beside the coefficients file, if it certifies them; none for "
        f"'{PAPER_SOURCE}')",
    )
    choice.add_argument("--no-region-map", action="store_true", help="do not report or cross-check a region map")


def _add_sampling_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--n", type=int, default=DEFAULT_CASES, help="number of sampled cases [cases] (>= 1)")
    parser.add_argument("--seed", type=int, default=DEFAULT_SEED, help="seed of the cases' sampler (>= 0) (default: 0)")
    parser.add_argument(
        "--range",
        nargs=4,
        type=float,
        metavar=("LMIN", "LMAX", "WMIN", "WMAX"),
        default=None,
        help="sample L in [LMIN, LMAX] m and W in [WMIN, WMAX] m instead of the fitted range "
        "(cases outside it are reported as extrapolation; the coefficients' other variables, such as "
        "x, keep their fitted range) (default: the coefficients' fitted range)",
    )
    parser.add_argument(
        "--jobs",
        type=jobs_count,
        default=1,
        metavar="J",
        help="worker processes [processes] (0: every CPU); the results do not depend on it",
    )
    parser.add_argument(
        "--samples",
        type=int,
        default=None,
        help="path samples per case for the tracking error [samples] (>= 2) (default: one per --resolution "
        "of path length); the certificate chooses its own samples",
    )
    parser.add_argument(
        "--resolution",
        type=float,
        default=TRACKING_RESOLUTION_M,
        metavar="M",
        help="spacing of the tracking error's path samples [m]",
    )
    parser.add_argument(
        "--certificate",
        choices=CERTIFICATE_MODES,
        default=CERTIFICATE_MODES[0],
        help="'decide': certify whether each case keeps --margin, tightening the bound only where it does "
        "not (fast); 'tight': every bound within --tolerance of the sampled minimum",
    )
    parser.add_argument(
        "--tolerance",
        type=float,
        default=DEFAULT_TOLERANCE_M,
        metavar="M",
        help="certificate refinement tolerance: bisect until the certified bound is within this of the "
        "sampled minimum [m]",
    )
    parser.add_argument(
        "--max-evaluations",
        type=int,
        default=DEFAULT_MAX_EVALUATIONS,
        metavar="N",
        help="certificate refinement budget per case [clearance evaluations]",
    )


def _add_threshold_options(parser: argparse.ArgumentParser) -> None:
    defaults = AcceptanceThresholds()
    parser.add_argument(
        "--min-clearance",
        type=float,
        default=defaults.min_certified_clearance_m,
        metavar="M",
        help="a case passes only if its certified clearance is > this [m] (default: 0, certified collision-free)",
    )
    parser.add_argument(
        "--max-endpoint-error",
        type=float,
        default=defaults.max_endpoint_error_m,
        metavar="M",
        help="a case passes only if both endpoint errors are <= this [m]",
    )
    parser.add_argument(
        "--margin",
        type=float,
        default=defaults.margin_m,
        metavar="M",
        help="safety margin [m]: the fraction of cases whose certified clearance keeps it is reported",
    )
    parser.add_argument("--require-margin", action="store_true", help="also fail the cases that do not keep --margin")
    parser.add_argument(
        "--max-tracking-error",
        type=float,
        default=None,
        metavar="M",
        help="fail the cases whose max tracking error exceeds this [m] (default: report only)",
    )
    parser.add_argument(
        "--joint-limits",
        action=argparse.BooleanOptionalAction,
        default=defaults.check_joint_limits,
        help="fail the cases whose joint speed or angle leaves the URDF's limits",
    )
    parser.add_argument(
        "--max-acceleration",
        nargs=2,
        type=float,
        default=None,
        metavar=("A1", "A2"),
        help="joint acceleration limits [rad/s^2] (the URDF has none) (default: report only)",
    )


def _add_output_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--urdf",
        metavar="FILE",
        default=None,
        help="URDF of the arm (default: the one recorded with the coefficients; given, it must match them)",
    )
    parser.add_argument(
        "--json", metavar="FILE", type=Path, default=None, help="write cases, summary and provenance as JSON"
    )
    parser.add_argument(
        "--plots",
        metavar="DIR",
        type=Path,
        default=None,
        help="write PNG plots (clearance and endpoint error over (L, W), the four case studies, and the region "
        "map if it belongs to the coefficients; over (L, W, x) the map and the sampled clearance in slices "
        "of x) into DIR",
    )
    parser.add_argument(
        "--meshcat",
        action="store_true",
        help="after the sweep, serve the results in a Meshcat viewer on the loopback interface until Ctrl-C "
        "(with --compare, the first run)",
    )
    parser.add_argument(
        "--html",
        metavar="FILE",
        type=Path,
        default=None,
        help="write a self-contained HTML page (Meshcat) of the results; with --compare one file per run, "
        "suffixed _1 and _2",
    )
    parser.add_argument(
        "--list-failures",
        type=int,
        default=None,
        metavar="K",
        help="list at most K failing cases on stdout (default: all; --json has all)",
    )
    parser.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="progress bar on stderr (drawn only when stderr is a terminal)",
    )


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface of ``python -m verify.sweep``."""
    parser = Parser(
        prog=PROG,
        description=(
            "Acceptance verifier: judge a coefficients file (or the paper's Eq. 9) on random obstacle "
            "sizes (L, W): certified clearance (Pinocchio + Coal, continuous time), endpoint accuracy, "
            "tracking, joint limits. Exit status 0 if every case passes, 1 if any fails, 2 on bad input."
        ),
    )
    _add_source_options(parser)
    _add_region_map_options(parser)
    _add_sampling_options(parser)
    _add_threshold_options(parser)
    _add_output_options(parser)
    return parser


# --------------------------------------------------------------------------------------------
# From options to library calls


def _settings_from_args(args: argparse.Namespace) -> MeasureSettings:
    thresholds = AcceptanceThresholds(
        min_certified_clearance_m=args.min_clearance,
        max_endpoint_error_m=args.max_endpoint_error,
        margin_m=args.margin,
        require_margin=args.require_margin,
        max_tracking_error_m=args.max_tracking_error,
        check_joint_limits=args.joint_limits,
        acceleration_limits_rad_s2=tuple(args.max_acceleration) if args.max_acceleration else None,
    )
    return MeasureSettings(
        resolution_m=args.resolution,
        time_samples=args.samples,
        certificate_mode=args.certificate,
        tolerance_m=args.tolerance,
        max_evaluations=args.max_evaluations,
        thresholds=thresholds,
    )


def _validate_args(args: argparse.Namespace) -> None:
    """Raise InvalidParameterError, named after the option, on bad values before any work starts."""
    check_positive_int("--n", args.n, minimum=1)
    check_positive_int("--seed", args.seed, minimum=0)
    if args.samples is not None:
        check_positive_int("--samples", args.samples, minimum=2)
    check_positive("--resolution [m]", args.resolution)
    check_positive("--tolerance [m]", args.tolerance)
    check_positive_int("--max-evaluations", args.max_evaluations, minimum=0)
    check_non_negative("--max-endpoint-error [m]", args.max_endpoint_error)
    check_non_negative("--margin [m]", args.margin)
    check_finite("--min-clearance [m]", args.min_clearance)
    if args.max_tracking_error is not None:
        check_non_negative("--max-tracking-error [m]", args.max_tracking_error)
    for value in args.max_acceleration or ():
        check_positive("--max-acceleration [rad/s^2]", value)
    if args.list_failures is not None:
        check_positive_int("--list-failures", args.list_failures, minimum=0)
    if args.range is not None:
        _check_range(args.range)
    if args.region_map is not None and not args.region_map.is_file():
        raise InvalidParameterError("--region-map", str(args.region_map), "an existing region map file")
    check_output_file(args.json, "--json")
    check_output_file(args.html, "--html")
    check_output_folder(args.plots, "--plots")


def _check_range(values: Sequence[float]) -> None:
    lmin, lmax, wmin, wmax = values
    for name, value in (("LMIN", lmin), ("LMAX", lmax), ("WMIN", wmin), ("WMAX", wmax)):
        check_positive(f"--range {name} [m]", value)
    if lmin > lmax:
        raise InvalidParameterError("--range", list(values), f"LMIN <= LMAX (got LMIN {lmin} > LMAX {lmax})")
    if wmin > wmax:
        raise InvalidParameterError("--range", list(values), f"WMIN <= WMAX (got WMIN {wmin} > WMAX {wmax})")


def _viewer(args: argparse.Namespace) -> Any:
    """The module verify.viewer.sweep_view if --meshcat or --html was given (imported only then)."""
    if not (args.meshcat or args.html):
        return None
    flag = "--meshcat" if args.meshcat else "--html"
    try:
        module = importlib.import_module("verify.viewer.sweep_view")
    except ImportError as exc:
        raise PipelineError(
            f"{flag} needs the viewer (verify.viewer.sweep_view), which is unavailable: {exc}"
        ) from None
    for wanted, name in ((args.meshcat, "show_sweep"), (args.html, "sweep_html")):
        if wanted and not callable(getattr(module, name, None)):
            raise PipelineError(f"{flag} needs verify.viewer.sweep_view.{name}, which does not exist")
    return module


def _show(
    viewer: Any,
    runs: Sequence[SweepRun],
    coefficients: Sequence[Coefficients],
    arms: Sequence[PlanarArm],
    args: argparse.Namespace,
) -> None:
    """Write the HTML view (one file per run) and/or serve the Meshcat view (first run) of the sweep."""
    from pipeline.online.generator import generate

    for k, (run, coefficient_set, arm) in enumerate(zip(runs, coefficients, arms, strict=True)):
        # The viewer names a case by (L, W); its extra variables (x, ...) are the case's own.
        extra = {(c.L_m, c.W_m): c.extra_values for c in (*run.cases, *run.case_studies)}

        def regenerate(
            length_m: float, width_m: float, chosen: Coefficients = coefficient_set, extra: dict = extra
        ) -> Any:
            return generate(chosen, length_m, width_m, out_of_range="ignore", **extra.get((length_m, width_m), {}))

        cases = run.cases
        region_map = None if run.range_check is None else run.range_check.region_map  # None unless it belongs
        if args.html is not None:
            path = args.html if len(runs) == 1 else args.html.with_name(f"{args.html.stem}_{k + 1}{args.html.suffix}")
            viewer.sweep_html(cases, regenerate, path, arm=arm, region_map=region_map)
            print(f"wrote {path} ({run.label})")
        if args.meshcat and k == 0:
            if len(runs) > 1:
                print(f"Meshcat shows the first run only ({run.label})")
            try:
                viewer.show_sweep(cases, regenerate, arm=arm, region_map=region_map)
            except KeyboardInterrupt:
                pass


def _labels(sources: Sequence[str]) -> list[str]:
    labels = [source_label(s) for s in sources]
    if len(set(labels)) < len(labels):
        labels = [f"{label} ({name})" for label, name in zip(labels, "AB", strict=False)]
    return labels


def _chosen_range(
    args: argparse.Namespace, sources: Sequence[str], coefficients: Sequence[Coefficients]
) -> SweepRange | None:
    """The --range (over (L, W); the other variables over their fitted range), or the fitted
    ranges' intersection with --compare, or None (the fitted range)."""
    names = [c.variables.names for c in coefficients]
    if len(set(names)) > 1:
        raise InvalidParameterError(
            "--compare",
            list(sources),
            "coefficients over the same variables (got " + " and ".join(f"({', '.join(n)})" for n in names) + ")",
        )
    if args.range is not None:
        fitted = SweepRange.from_fitted(coefficients[0].fitted_range_m, names[0])
        return SweepRange((args.range[0], args.range[1]), (args.range[2], args.range[3]), fitted.extra_m)
    if len(coefficients) > 1:
        ranges = [SweepRange.from_fitted(c.fitted_range_m, names[0]) for c in coefficients]
        chosen = ranges[0].intersection(ranges[1])
        if chosen is None:
            raise InvalidParameterError(
                "--compare", list(sources), "coefficients with overlapping fitted ranges, or --range"
            )
        return chosen
    return None


def _write_outputs(args: argparse.Namespace, runs: Sequence[SweepRun]) -> None:
    if args.json is not None:
        data = runs[0].to_json() if len(runs) == 1 else {"runs": [r.to_json() for r in runs]}
        write_json_atomic(args.json, data)
        print(f"wrote {args.json}")
    if args.plots is not None:
        from verify.acceptance.plots import write_plots  # matplotlib only when asked

        for run in runs:
            directory = args.plots if len(runs) == 1 else args.plots / run.label.replace(" ", "_")
            for path in write_plots(run, directory):  # with the run's arm
                print(f"wrote {path}")


def _region_maps(
    args: argparse.Namespace, coefficients: Sequence[Coefficients]
) -> list[tuple[RegionMap | None, str | None]]:
    """Per coefficients set, the map to report and check and its file: ``--region-map``'s (whether
    it belongs or not: the report says), else the one attached to them (beside their file)."""
    if args.no_region_map:
        return [(None, None)] * len(coefficients)
    if args.region_map is not None:
        named = load_region_map(args.region_map)
        return [(named, str(args.region_map))] * len(coefficients)
    return [(None, None) if c.region_map is None else (c.region_map, str(map_path_beside(c))) for c in coefficients]


def _work(args: argparse.Namespace, argv: Sequence[str]) -> int:
    _validate_args(args)
    settings = _settings_from_args(args)
    viewer = _viewer(args)
    sources = list(args.compare) if args.compare else [args.coefficients]
    beside = not (args.no_region_map or args.region_map is not None)
    coefficients = [
        load_coefficients_for_verify(PROG, s, beside=beside, malformed_hint="--no-region-map skips it") for s in sources
    ]
    arms = [arm_for_verify(c, args.urdf) for c in coefficients]
    for coefficient_set in coefficients:
        print(describe_coefficients(coefficient_set), flush=True)
    maps = _region_maps(args, coefficients)
    chosen = _chosen_range(args, sources, coefficients)
    box = chosen or SweepRange.from_fitted(coefficients[0].fitted_range_m, coefficients[0].variables.names)
    cases = sample_cases(box, args.n, args.seed)
    runs = [
        run_sweep(
            source,
            n=args.n,
            seed=args.seed,
            sweep_range=chosen,
            settings=settings,
            jobs=args.jobs,
            progress=progress_enabled(args.progress),
            label=label,
            cases_m=cases,
            argv=["python", "-m", "verify.sweep", *argv],
            coefficients=coefficient_set,
            arm=arm,
            region_map=region_map,
            region_map_path=region_map_path,
        )
        for source, label, coefficient_set, arm, (region_map, region_map_path) in zip(
            sources, _labels(sources), coefficients, arms, maps, strict=True
        )
    ]
    for run in runs:
        print(format_summary(run, args.list_failures))
        print()
    if len(runs) > 1:
        print(format_comparison(runs))
    _write_outputs(args, runs)
    if viewer is not None:
        _show(viewer, runs, coefficients, arms, args)
    return EXIT_OK if all(run.passed for run in runs) else EXIT_FAILED  # a contradicted map fails its run


def _work_or_error(args: argparse.Namespace, argv: Sequence[str]) -> int:
    try:
        return _work(args, argv)
    except OSError as exc:  # a file that could not be read or written despite the checks
        raise PipelineError(f"{exc.filename or ''}: {exc.strerror or exc}") from None


def main(argv: Sequence[str] | None = None) -> int:
    """Run the verifier; returns the exit status (0 all pass, 1 some fail, 2 bad input, 130 interrupted)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    return run_cli(build_parser(), lambda args: _work_or_error(args, argv), argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
