"""``python -m pipeline.regress DOE.json -o coefficients.json``: the regression step alone.

Works on any DOE file: ours (``results/doe.json``) or the paper's Table 2
(``paper`` names the copy shipped with the package). ``--plain`` is the paper's own fit
(``python -m pipeline.regress paper --plain`` reproduces Eq. 9); the default holds the
paper family's endpoint errors within ``--endpoint-tolerance`` (see
:mod:`pipeline.endpoint_regression`), as the build does.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
from pathlib import Path

from . import report
from .coefficients import fit_coefficients, load_coefficients, paper_data_path, save_coefficients
from .doe import load_doe
from .endpoint_regression import EndpointConstraint
from .exceptions import PipelineError


def add_regression_arguments(p: argparse.ArgumentParser) -> None:
    """The regression options shared by this CLI and ``python -m pipeline.build``."""
    p.add_argument(
        "--endpoint-tolerance",
        type=float,
        default=EndpointConstraint.tolerance_m,
        metavar="M",
        help="paper family: hold the regressed trajectory's endpoint errors within this over the fitted range [m]",
    )
    p.add_argument(
        "--plain",
        action="store_true",
        help="plain least squares per parameter, as the paper's Eq. 9 (no endpoint constraint)",
    )


def endpoint_constraint(args: argparse.Namespace, family: str) -> EndpointConstraint | None:
    """The endpoint constraint the parsed options ask for, or None (plain fit, or a family
    that is exact by construction).

    Raises:
        InvalidParameterError: a non-positive or NaN tolerance.
    """
    if args.plain or family != "paper":
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
    add_regression_arguments(p)
    p.add_argument("--quiet", action="store_true", help="do not print the coefficient table")
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (2 on bad input, with one line on stderr)."""
    args = parser().parse_args(argv)
    try:
        path = paper_data_path("paper_table2_doe.json") if args.doe == "paper" else Path(args.doe)
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
        paper = load_coefficients("paper").parameters if doe.family == "paper" else None
        print(report.equation9(coefficients.parameters, paper, coefficients.extra["fit"]))
        print(report.regression_method(coefficients.extra["fit"]))
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
