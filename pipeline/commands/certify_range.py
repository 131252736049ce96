"""``python -m pipeline.certify_range COEFFICIENTS``: the range certificate of a coefficients file.

Certifies, for every (L, W) of the fitted range and every t in [0, T(L, W)], a lower bound on the
clearance of both links, an upper bound on the endpoint errors, and where the margin cannot be
kept by the family at the endpoint tolerance, and the execution bounds of each leaf for the arm
recorded with the coefficients (its URDF limits and the build's acceleration limits); writes the
region map (``pipeline.certify``) and prints the area fraction of each status and the time it
took. While it works, a progress bar per stage on stderr (when it is a terminal; ``--no-progress`` turns them off).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from types import MappingProxyType

import numpy as np

from pipeline.certify.map_files import load_region_map, save_region_map, table_name
from pipeline.certify.map_for_coefficients import default_config, summary_lines, with_execution_bounds
from pipeline.certify.range_certificate import (
    DEFAULT_BOUNDARY_CELL,
    DEFAULT_CELLS,
    DEFAULT_CLEARANCE_CUTS,
    DEFAULT_ENDPOINT_TOLERANCE_M,
    DEFAULT_INFEASIBILITY_CUTS,
    DEFAULT_MERGE_SPREAD_M,
    DEFAULT_MIN_CELL,
    DEFAULT_STRIP_SPLITS,
    DEFAULT_TILT_CUTS,
    certify_range,
)
from pipeline.certify.reachability import witness_lines, witnesses_for_map
from pipeline.certify.region_map import DEFAULT_MAP_NAME
from pipeline.cli import (
    EXIT_OK,
    Parser,
    add_progress_argument,
    add_scheduler_arguments,
    arm_for_cli,
    check_output_file,
    count_argument,
    describe_coefficients,
    jobs_count,
    run_cli,
)
from pipeline.exceptions import InvalidParameterError
from pipeline.io.executor import DaskScheduler, check_executor, check_scheduler_address
from pipeline.io.jsonio import write_json_atomic
from pipeline.io.progress import ProgressBars
from pipeline.model.dynamics import identify_dynamics
from pipeline.model.limits import ArmLimits
from pipeline.motion.families import PAPER_SOURCE
from pipeline.online.loading import load_coefficients, map_path_beside


def _fraction(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not 2.0**-20 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"{value} must be a fraction of the range's side in [2^-20, 1]")
    return value


def _metres(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of metres") from None
    if not value >= 0.0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"{value} must be a finite length >= 0 [m]")
    return value


#: ``--bound-form`` -> ``RangeCertificateConfig.second_order``.
BOUND_FORMS = MappingProxyType({"mean-value": False, "second-order": True})


def _add_cell_options(p: argparse.ArgumentParser) -> None:
    """The options that shape the map's cells: their smallest size, extra depth, merging and the
    boundary's cell."""
    p.add_argument(
        "--min-cell",
        type=_fraction,
        default=None,
        help="smallest cell, as a fraction of the fitted range's side on every axis [-] (default: "
        f"{DEFAULT_MIN_CELL} over (L, W), {DEFAULT_CELLS[3][0]} over (L, W, x))",
    )
    p.add_argument(
        "--extra-depth",
        type=count_argument,
        default=None,
        metavar="E",
        help="halvings beyond the smallest cell a cell may take along the axes that dominate its gap, at the "
        f"smallest cell's volume, 0..6 [count] (default: {DEFAULT_CELLS[2][2]} over (L, W), {DEFAULT_CELLS[3][2]} "
        "over (L, W, x))",
    )
    p.add_argument(
        "--merge-spread",
        type=_metres,
        default=None,
        metavar="M",
        help="store two sibling leaves of one status as their parent where their clearance bounds, and their "
        f"endpoint bounds, differ by at most M [m] (0: none; default: {DEFAULT_MERGE_SPREAD_M[2]} over (L, W), "
        f"{DEFAULT_MERGE_SPREAD_M[3]} over more axes)",
    )
    p.add_argument(
        "--bound-form",
        choices=tuple(BOUND_FORMS),
        default=None,
        help="how the clearance and the endpoint errors are bounded over a box: the mean-value form alone, or "
        "intersected with the second-order Taylor form (default: mean-value over (L, W), second-order over more axes)",
    )
    p.add_argument(
        "--boundary-cell",
        type=_fraction,
        default=None,
        help="cell size to which regions that miss the margin are resolved, fraction of the side [-] "
        f"(default: {DEFAULT_BOUNDARY_CELL})",
    )


def _add_cut_options(p: argparse.ArgumentParser) -> None:
    """The options that cut the smallest cells further where the map misses the margin: strips along
    W, cuts at the infeasibility contour and across its tilt, cuts for the clearance."""
    p.add_argument(
        "--strip-split",
        type=count_argument,
        default=None,
        metavar="E",
        help="cut the smallest cells that miss the margin without being proven infeasible into 2^E strips along W, "
        "each bounded on its own (pipeline.certify.strip_split), 0..6 [count] (default: "
        f"{DEFAULT_STRIP_SPLITS[2]} over (L, W), {DEFAULT_STRIP_SPLITS[3]} over (L, W, x), {DEFAULT_STRIP_SPLITS[4]} "
        "over (L, W, x, d))",
    )
    p.add_argument(
        "--infeasibility-cuts",
        type=count_argument,
        default=None,
        metavar="E",
        help="cut a leaf below the margin and not proven infeasible along W at the lowest of 2^E levels above which "
        "the part is proven infeasible (pipeline.certify.infeasibility_cuts), 0..8 [count] (default: "
        f"{DEFAULT_INFEASIBILITY_CUTS[2]} over (L, W), {DEFAULT_INFEASIBILITY_CUTS[3]} over (L, W, x), "
        f"{DEFAULT_INFEASIBILITY_CUTS[4]} over (L, W, x, d))",
    )
    p.add_argument(
        "--tilt-cuts",
        type=count_argument,
        default=None,
        metavar="T",
        help="with --infeasibility-cuts: first halve a leaf the infeasibility contour crosses up to T times along the "
        "axis that tilts the contour across it, 0..6 [count] (default: "
        f"{DEFAULT_TILT_CUTS[2]} over (L, W), {DEFAULT_TILT_CUTS[3]} over (L, W, x), {DEFAULT_TILT_CUTS[4]} over "
        "(L, W, x, d))",
    )
    p.add_argument(
        "--clearance-cuts",
        type=count_argument,
        default=None,
        metavar="R",
        help="halve the leaves that miss the margin where the clearance at their boxes' centres keeps it along their "
        "steepest axis, R rounds, each half bounded on its own (pipeline.certify.clearance_cuts), 0..8 [count] "
        f"(default: {DEFAULT_CLEARANCE_CUTS[2]} over (L, W), {DEFAULT_CLEARANCE_CUTS[3]} over (L, W, x), "
        f"{DEFAULT_CLEARANCE_CUTS[4]} over (L, W, x, d))",
    )


def parser() -> argparse.ArgumentParser:
    p = Parser(
        prog="python -m pipeline.certify_range",
        description="Certify a coefficients file over its whole fitted (L, W) range and all of [0, T]: "
        "clearance lower bounds, endpoint-error upper bounds and infeasibility, as a region map.",
    )
    p.add_argument("coefficients", nargs="?", help=f"coefficients file, or {PAPER_SOURCE!r} for the paper's Eq. 9")
    p.add_argument(
        "--convert",
        type=Path,
        metavar="MAP",
        default=None,
        help="instead of certifying: rewrite the region map MAP of an earlier format (the leaves as JSON, or a "
        "table of a 2^k-tree's nodes) as a JSON header and a .npy table of its subpaving, every number kept "
        "(to --output, default: in place)",
    )
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        default=None,
        help=f"region map to write (default: {DEFAULT_MAP_NAME} beside the coefficients file; "
        f"none for {PAPER_SOURCE!r})",
    )
    p.add_argument("--json", type=Path, default=None, help="also write the summary (area fractions, bounds, seconds)")
    p.add_argument(
        "--margin", type=_metres, default=None, help="clearance margin [m] (default: the coefficients' scene margin)"
    )
    p.add_argument(
        "--endpoint-tolerance",
        type=_metres,
        default=None,
        help=f"endpoint tolerance of the infeasibility certificate [m] (default: {DEFAULT_ENDPOINT_TOLERANCE_M}, "
        "0 for a family that pins the endpoints)",
    )
    p.add_argument("--jobs", type=jobs_count, default=1, help="worker processes [count], 0 = every CPU")
    add_scheduler_arguments(p)
    p.add_argument(
        "--witnesses",
        type=count_argument,
        default=0,
        metavar="N",
        help="paper family: at N cells that keep neither the margin nor are proven infeasible (spread over them), "
        "search the family for the largest clearance with the endpoint tolerance and certify it (a witness of "
        "what is reachable; pipeline.certify.reachability) [count] (default: 0)",
    )
    p.add_argument(
        "--witness-restarts",
        type=count_argument,
        default=0,
        metavar="K",
        help="random restarts of each witness search besides the start at the coefficients' trajectory [count] "
        "(default: 0)",
    )
    p.add_argument(
        "--seed",
        type=count_argument,
        default=0,
        help="seed of the witness searches' restarts (numpy.random.default_rng) [integer >= 0] (default: 0)",
    )
    _add_cell_options(p)
    _add_cut_options(p)
    add_progress_argument(p)
    return p


def _convert(source: Path, output: Path | None) -> int:
    """Rewrite the map ``source`` in the current format at ``output`` (default: in place)."""
    region_map = load_region_map(source)
    output = source if output is None else output
    digest = save_region_map(region_map, output)
    print(
        f"wrote {output} and {table_name(output.name)} ({region_map.size} leaves; sha256 {digest[:12]}, "
        f"for coefficients sha256 {region_map.coefficients_sha256[:12]})"
    )
    return EXIT_OK


def _work(args: argparse.Namespace) -> int:
    output = check_output_file(args.output, "--output")
    if args.convert is None and args.coefficients is None:
        raise InvalidParameterError("coefficients", None, "a coefficients file, or --convert MAP")
    if args.convert is not None and args.coefficients is not None:
        raise InvalidParameterError(
            "--convert", str(args.convert), f"no coefficients file with it (got {args.coefficients!r})"
        )
    if args.convert is not None:
        return _convert(args.convert, output)
    summary_path = check_output_file(args.json, "--json")
    # Without the map beside them: it is the one this command replaces (an older build's, or a
    # broken file, must neither warn nor stop it).
    coefficients = load_coefficients(args.coefficients, region_map=None)
    executor = None
    if args.scheduler is not None:
        executor = DaskScheduler(
            check_scheduler_address("--scheduler", args.scheduler), worker_timeout_s=args.worker_timeout
        )
        check_executor(executor)  # before any work
    if output is None:
        output = map_path_beside(coefficients)  # None for the paper's Eq. 9
    config = default_config(
        coefficients,
        margin_m=args.margin,
        endpoint_tolerance_m=args.endpoint_tolerance,
        min_cell=args.min_cell,
        boundary_cell=args.boundary_cell,
        extra_depth=args.extra_depth,
        merge_spread_m=args.merge_spread,
        second_order=None if args.bound_form is None else BOUND_FORMS[args.bound_form],
        strip_split=args.strip_split,
        infeasibility_cuts=args.infeasibility_cuts,
        tilt_cuts=args.tilt_cuts,
        clearance_cuts=args.clearance_cuts,
        jobs=args.jobs,
        executor=executor,
    )
    print(describe_coefficients(coefficients))
    arm = arm_for_cli(coefficients, None)
    with ProgressBars(enabled=not args.no_progress) as progress:
        region_map = certify_range(coefficients, config, progress)
    limits = ArmLimits.recorded(arm, coefficients.provenance)
    region_map = with_execution_bounds(region_map, coefficients, identify_dynamics(arm), limits, config.run_on)
    digest = save_region_map(region_map, output) if output is not None else None
    print("\n".join(summary_lines(region_map)))
    summary = region_map.summary()
    if args.witnesses > 0:
        witnesses = witnesses_for_map(
            coefficients,
            region_map,
            arm,
            args.witnesses,
            args.witness_restarts,
            np.random.default_rng(args.seed),
        )
        print("\n".join(witness_lines(witnesses)))
        summary["witnesses"] = [w.to_json() for w in witnesses]
    if output is not None:
        print(f"wrote {output} (sha256 {digest[:12]}, for coefficients sha256 {coefficients.source_sha256[:12]})")
    if summary_path is not None:
        write_json_atomic(summary_path, summary)
        print(f"wrote {summary_path}")
    return EXIT_OK


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit status (0 done, 2 bad input, 130 interrupted)."""
    return run_cli(parser(), _work, argv)


if __name__ == "__main__":
    raise SystemExit(main())
