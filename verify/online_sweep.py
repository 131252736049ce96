"""``python -m verify.online_sweep``: certify-or-repair over many obstacles.

For each sampled (L, W) the online generator runs with certification on
(:func:`pipeline.online.repair.generate_certified`). Every answer must either carry a certified
clearance of at least the margin or be a refusal that says why; this sweep checks that
invariant on every case and reports how many answers came straight from the regression,
how many were repaired, and how many were refused. ``--beyond 0.2`` widens the fitted range
by 20 % of its width on each side, to exercise extrapolation. Every query runs the per-query
certificate (a region map beside the coefficients is not used), with the arm recorded with the
coefficients (``--urdf`` names one, which must match them).

Exit status: 0 if every answer is certified at least the margin or refused, 1 if an answer
breaks that, 2 on bad input (one line on stderr), 130 if interrupted.

This module only parses the command line and calls :mod:`verify.acceptance.online`.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from pipeline.cli import (
    DEFAULT_COEFFICIENTS,
    EXIT_FAILED,
    EXIT_OK,
    Parser,
    add_progress_argument,
    describe_coefficients,
    jobs_count,
    run_cli,
)
from pipeline.exceptions import InvalidParameterError, PipelineError
from pipeline.geometry.clearance import ROUTES, route_from_name
from pipeline.io.jsonio import write_json_atomic
from pipeline.io.output_paths import check_output_file
from pipeline.model.obstacle import Obstacle
from pipeline.motion.families import PAPER_SOURCE
from pipeline.offline.coefficients import Coefficients
from pipeline.online.repair import RepairConfig
from pipeline.validation import check_positive, check_positive_int
from verify.acceptance.cases import SweepRange, sample_cases
from verify.acceptance.online import format_online_report, run_online_cases, summarize_online
from verify.cli_support import arm_for_verify, load_coefficients_for_verify

PROG = "python -m verify.online_sweep"
#: --beyond must be below this [fraction of the fitted range's width per side].
MAX_BEYOND = 10.0


def parser() -> argparse.ArgumentParser:
    """The command-line interface of ``python -m verify.online_sweep``."""
    defaults = RepairConfig()
    p = Parser(
        prog=PROG,
        description="Certify-or-repair on random obstacles: each answer certified >= margin, or refused. "
        "Exit status 0 if that holds for every answer, 1 if not, 2 on bad input.",
    )
    p.add_argument(
        "--coefficients",
        metavar="FILE",
        default=DEFAULT_COEFFICIENTS,
        help=f"coefficients file, or '{PAPER_SOURCE}' for the paper's Eq. 9",
    )
    p.add_argument("--n", type=int, default=1000, help="number of random obstacles [cases] (>= 1)")
    p.add_argument("--seed", type=int, default=0, help="seed of the obstacle sizes (>= 0) (default: 0)")
    p.add_argument(
        "--beyond",
        type=float,
        default=0.0,
        metavar="FRACTION",
        help="widen the fitted range by this fraction of its width on each side (0 <= FRACTION < 10) "
        "(default: 0, the fitted range)",
    )
    p.add_argument(
        "--jobs", type=jobs_count, default=1, metavar="J", help="worker processes [processes] (0: every CPU)"
    )
    p.add_argument("--route", choices=tuple(ROUTES), default=defaults.route.name, help="certificate's distance route")
    p.add_argument(
        "--max-seconds", type=float, default=defaults.max_seconds, metavar="S", help="repair time budget per query [s]"
    )
    p.add_argument("--no-repair", action="store_true", help="refuse instead of repairing")
    p.add_argument(
        "--urdf",
        type=Path,
        default=None,
        metavar="FILE",
        help="URDF of the arm (default: the one recorded with the coefficients; given, it must match them)",
    )
    p.add_argument("--json", type=Path, metavar="FILE", help="write cases and summary to this JSON file")
    add_progress_argument(p)
    return p


def _check_args(args: argparse.Namespace) -> None:
    """One option per message, before any work."""
    check_positive_int("--n", args.n, minimum=1)
    check_positive_int("--seed", args.seed, minimum=0)
    if not 0.0 <= args.beyond < MAX_BEYOND:
        raise InvalidParameterError("--beyond", args.beyond, f"a fraction in [0, {MAX_BEYOND:g})")
    check_positive("--max-seconds [s]", args.max_seconds)
    check_output_file(args.json, "--json")


def _widened_range(coefficients: Coefficients, beyond: float) -> SweepRange:
    """The fitted range widened by --beyond, refused (naming --beyond) if it holds an impossible obstacle."""
    sweep_range = SweepRange.from_fitted(coefficients.fitted_range_m).widened(beyond)
    try:
        for length, width in ((sweep_range.L_m[0], sweep_range.W_m[0]), (sweep_range.L_m[1], sweep_range.W_m[1])):
            Obstacle.in_scene(length, width, coefficients.scene)
    except PipelineError as exc:
        raise InvalidParameterError(
            "--beyond",
            beyond,
            f"a widening whose obstacles exist: L in [{sweep_range.L_m[0]:.4f}, {sweep_range.L_m[1]:.4f}] m, "
            f"W in [{sweep_range.W_m[0]:.4f}, {sweep_range.W_m[1]:.4f}] m holds one that does not ({exc})",
        ) from None
    return sweep_range


def _work(args: argparse.Namespace) -> int:
    _check_args(args)
    coefficients = load_coefficients_for_verify(PROG, args.coefficients, beside=False)  # per-query certificates
    arm = arm_for_verify(coefficients, args.urdf)
    print(describe_coefficients(coefficients), flush=True)
    sweep_range = _widened_range(coefficients, args.beyond)
    config = RepairConfig(route=route_from_name(args.route), max_seconds=args.max_seconds, repair=not args.no_repair)
    cases = sample_cases(sweep_range, args.n, args.seed)
    results = run_online_cases(
        args.coefficients,
        cases,
        config,
        arm.urdf_path,
        args.jobs,
        not args.no_progress,
        coefficients=coefficients,
        arm=arm,
    )
    summary = summarize_online(results, coefficients.scene.margin_m)
    header = (
        f"certify-or-repair on {args.coefficients} ({coefficients.family.name}), {len(results)} cases, "
        f"L in [{sweep_range.L_m[0]:.4f}, {sweep_range.L_m[1]:.4f}] m, "
        f"W in [{sweep_range.W_m[0]:.4f}, {sweep_range.W_m[1]:.4f}] m"
    )
    print(format_online_report(summary, header))
    if args.json:
        document = {**summary.to_json(), "range": sweep_range.to_dict()}
        write_json_atomic(args.json, {"summary": document, "cases": [case.to_json() for case in results]})
    return EXIT_OK if summary.invariant_holds else EXIT_FAILED


def main(argv: Sequence[str] | None = None) -> int:
    """Exit 0 if every answer is certified >= margin or refused; 1 if any answer breaks that; 2 on bad input;
    130 if interrupted."""
    return run_cli(parser(), _work, argv)


if __name__ == "__main__":
    sys.exit(main())
