"""``python -m pipeline.regress DOE.json -o coefficients.json``: the regression step alone.

Works on any DOE file: ours (``results/doe.json``) or the paper's Table 2
(``paper`` names the copy shipped with the package). By default the fit is the paper's,
least squares per parameter (``python -m pipeline.regress paper`` reproduces Eq. 9);
``--endpoint-tolerance M`` fits subject to the paper family's endpoint errors <= M over the
fitted range (:mod:`pipeline.offline.endpoint_regression`), as ``python -m pipeline.build`` does by
default with M = 0.002.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
from pathlib import Path

from pipeline.exceptions import PipelineError
from pipeline.motion.families import PAPER, PAPER_SOURCE, TrajectoryFamily
from pipeline.offline import report
from pipeline.offline.coefficients import fit_coefficients, load_coefficients, paper_data_path, save_coefficients
from pipeline.offline.doe import load_doe
from pipeline.offline.endpoint_regression import EndpointConstraint


def add_regression_arguments(p: argparse.ArgumentParser, default_tolerance_m: float | None) -> None:
    """The regression options of this CLI (default: plain, the paper's method) and of
    ``python -m pipeline.build`` (default: the endpoint constraint, which ``--plain`` turns off)."""
    if default_tolerance_m is None:
        p.add_argument(
            "--endpoint-tolerance",
            type=float,
            default=None,
            metavar="M",
            help="paper family: fit subject to endpoint errors <= M over the fitted range [m], as the build does"
            f" (its default: {EndpointConstraint.tolerance_m}); omitted: plain least squares per parameter (Eq. 9)",
        )
        return
    p.add_argument(
        "--endpoint-tolerance",
        type=float,
        default=default_tolerance_m,
        metavar="M",
        help="paper family: hold the regressed trajectory's endpoint errors within this over the fitted range [m]",
    )
    p.add_argument(
        "--plain",
        action="store_true",
        help="plain least squares per parameter, as the paper's Eq. 9 (no endpoint constraint)",
    )


def endpoint_constraint(args: argparse.Namespace, family: TrajectoryFamily) -> EndpointConstraint | None:
    """The endpoint constraint the parsed options ask for, or None (plain fit, or a family
    that is exact by construction).

    Raises:
        InvalidParameterError: a non-positive or NaN tolerance.
    """
    if getattr(args, "plain", False) or args.endpoint_tolerance is None or family.pins_endpoints:
        return None
    return EndpointConstraint(tolerance_m=args.endpoint_tolerance)


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m pipeline.regress",
        description="Fit p(L, W) = b0 + b1 L + b2 W + b3 L^2 + b4 L W + b5 W^2 per parameter on a DOE file.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("doe", help="DOE file (JSON), or 'paper' for the paper's Table 2")
    p.add_argument("-o", "--output", type=Path, required=True, help="coefficients file to write (JSON)")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    add_regression_arguments(p, default_tolerance_m=None)
    p.add_argument("--quiet", action="store_true", help="do not print the coefficient table")
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (2 on bad input, with one line on stderr)."""
    args = parser().parse_args(argv)
    try:
        path = paper_data_path("paper_table2_doe.json") if args.doe == PAPER_SOURCE else Path(args.doe)
        doe = load_doe(path)
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
        coefficients, _ = fit_coefficients(
            doe, {"provenance": {"doe": str(args.doe), "doe_sha256": digest}}, endpoint_constraint(args, doe.family)
        )
        save_coefficients(coefficients, args.output, overwrite=args.force)
    except PipelineError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if not args.quiet:
        paper = load_coefficients(PAPER_SOURCE).parameters if doe.family == PAPER else None
        print(report.equation9(coefficients.parameters, paper, coefficients.extra["fit"]))
        print(report.regression_method(coefficients.extra["fit"]))
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
