"""``python -m pipeline.certify_range COEFFICIENTS``: the range certificate of a coefficients file.

Certifies, for every (L, W) of the fitted range and every t in [0, T(L, W)], a lower bound on the
clearance of both links, an upper bound on the endpoint errors, and where the margin cannot be
kept by the family at the endpoint tolerance; writes the region map (``pipeline.certify``) and
prints the area fraction of each status and the time it took.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from pipeline.certify.range_certificate import (
    DEFAULT_BOUNDARY_CELL,
    DEFAULT_ENDPOINT_TOLERANCE_M,
    DEFAULT_MIN_CELL,
    RangeCertificateConfig,
    certify_range,
)
from pipeline.certify.region_map import STATUSES, save_region_map
from pipeline.cli import (
    EXIT_OK,
    Parser,
    check_output_file,
    describe_coefficients,
    jobs_count,
    load_coefficients_for_cli,
    run_cli,
)
from pipeline.io.jsonio import write_json_atomic
from pipeline.motion.families import PAPER_SOURCE

#: File name of the map written beside a coefficients file when -o is not given.
DEFAULT_MAP_NAME = "region_map.json"


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


def parser() -> argparse.ArgumentParser:
    p = Parser(
        prog="python -m pipeline.certify_range",
        description="Certify a coefficients file over its whole fitted (L, W) range and all of [0, T]: "
        "clearance lower bounds, endpoint-error upper bounds and infeasibility, as a region map.",
    )
    p.add_argument("coefficients", help=f"coefficients file, or {PAPER_SOURCE!r} for the paper's Eq. 9")
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
    p.add_argument(
        "--min-cell",
        type=_fraction,
        default=DEFAULT_MIN_CELL,
        help="smallest (L, W) cell, as a fraction of the fitted range's side [-]",
    )
    p.add_argument(
        "--boundary-cell",
        type=_fraction,
        default=DEFAULT_BOUNDARY_CELL,
        help="cell size to which regions that miss the margin are resolved, fraction of the side [-]",
    )
    return p


def _work(args: argparse.Namespace) -> int:
    output = check_output_file(args.output, "--output")
    summary_path = check_output_file(args.json, "--json")
    coefficients = load_coefficients_for_cli(args.coefficients)
    if output is None and args.coefficients != PAPER_SOURCE:
        output = Path(args.coefficients).with_name(DEFAULT_MAP_NAME)
    tolerance = args.endpoint_tolerance
    if tolerance is None:
        tolerance = 0.0 if coefficients.family.pins_endpoints else DEFAULT_ENDPOINT_TOLERANCE_M
    config = RangeCertificateConfig(
        margin_m=args.margin,
        endpoint_tolerance_m=tolerance,
        min_cell=args.min_cell,
        boundary_cell=min(args.boundary_cell, 1.0),
        jobs=args.jobs,
    )
    print(describe_coefficients(coefficients))
    region_map = certify_range(coefficients, config)
    summary = region_map.summary()
    fractions = summary["area_fraction"]
    print(
        "range certificate: "
        + ", ".join(f"{name} {100 * fractions[name]:.2f} %" for name in STATUSES)
        + f" of the area (margin {1e3 * region_map.margin_m:.2f} mm, endpoint tolerance "
        f"{1e3 * region_map.endpoint_tolerance_m:.2f} mm)"
    )
    print(
        f"certified collision-free {100 * summary['certified_collision_free_fraction']:.2f} %; clearance bound min "
        f"{1e3 * summary['clearance_bound_min_m']:.3f} mm; endpoint bound max "
        f"{1e3 * summary['endpoint_bound_max_m']:.3f} mm, <= tolerance on "
        f"{100 * summary['endpoint_within_tolerance_fraction']:.2f} %; "
        f"{summary['cells']} cells in {region_map.seconds:.1f} s"
    )
    if output is not None:
        digest = save_region_map(region_map, output)
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
