"""``python -m pipeline.regress DOE.json -o coefficients.json``: the regression step alone.

Works on any DOE file: ours (``results/doe.json``) or the paper's Table 2
(``paper`` names the copy shipped with the package). By default the fit is the paper's,
least squares per parameter (``python -m pipeline.regress paper`` reproduces Eq. 9);
``--endpoint-tolerance M`` fits subject to the paper family's endpoint errors <= M over the
fitted range (:mod:`pipeline.offline.endpoint_regression`), as ``python -m pipeline.build`` does by
default with M = 0.002.

Overwrite rule (the same for ``python -m pipeline.build``): an existing output file is replaced
atomically (the old file until the new one is complete); the path is checked before any work.
A fit that misses its endpoint tolerance, or a DOE file marked ``"converged": false`` by a build
run with ``--allow-unconverged``, exits 1 and writes nothing unless ``--allow-unconverged``.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import warnings
from pathlib import Path

from pipeline.cli import EXIT_FAILED, EXIT_OK, Parser, run_cli
from pipeline.exceptions import EndpointConstraintWarning, InvalidParameterError
from pipeline.io.output_paths import check_output_file
from pipeline.motion.families import PAPER, PAPER_SOURCE, TrajectoryFamily
from pipeline.offline import report
from pipeline.offline.coefficients import (
    CONVERGED_KEY,
    UNCONVERGED_REASONS_KEY,
    fit_coefficients,
    paper_data_path,
    save_coefficients,
)
from pipeline.offline.convergence import regression_problems
from pipeline.offline.doe import load_doe
from pipeline.offline.endpoint_regression import EndpointConstraint
from pipeline.online.loading import load_coefficients

PROG = "python -m pipeline.regress"
#: The overwrite rule of the offline CLIs, stated in their --help.
OVERWRITE_RULE = (
    "Existing output files are replaced atomically (never half-written); paths are checked before any work."
)


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
        InvalidParameterError: a non-positive or NaN tolerance (naming --endpoint-tolerance).
    """
    if getattr(args, "plain", False) or args.endpoint_tolerance is None:
        return None
    try:
        constraint = EndpointConstraint(tolerance_m=args.endpoint_tolerance)
    except InvalidParameterError as exc:
        raise InvalidParameterError("--endpoint-tolerance", exc.value, exc.expected) from None
    return None if family.pins_endpoints else constraint


def parser() -> Parser:
    p = Parser(
        prog=PROG,
        description="Fit p(L, W) = b0 + b1 L + b2 W + b3 L^2 + b4 L W + b5 W^2 per parameter on a DOE file "
        "(the full quadratic in its variables for a DOE over more than L and W, e.g. (L, W, x)).",
        epilog=f"{OVERWRITE_RULE} Exit status: 0 written, 1 not converged (nothing written), 2 bad input.",
    )
    p.add_argument("doe", help="DOE file (JSON), or 'paper' for the paper's Table 2")
    p.add_argument("-o", "--output", type=Path, required=True, help="coefficients file to write (JSON)")
    p.add_argument("--force", action="store_true", help=argparse.SUPPRESS)  # old scripts: replacing is the rule
    add_regression_arguments(p, default_tolerance_m=None)
    p.add_argument(
        "--allow-unconverged",
        action="store_true",
        help='write even if the fit misses --endpoint-tolerance or the DOE is marked "converged": false '
        "(the file is then marked too; loading it warns)",
    )
    p.add_argument("--quiet", action="store_true", help="do not print the coefficient table")
    return p


def regress(args: argparse.Namespace) -> int:
    """Fit and write for parsed options; returns the exit status (0 written, 1 not converged).

    Raises:
        PipelineError: bad input (``main`` prints it as one line).
    """
    output = check_output_file(args.output, "-o")
    path = paper_data_path("paper_table2_doe.json") if args.doe == PAPER_SOURCE else Path(args.doe)
    doe = load_doe(path)
    constraint = endpoint_constraint(args, doe.family)
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EndpointConstraintWarning)  # reported below as a problem
        coefficients, _ = fit_coefficients(
            doe, {"provenance": {"doe": str(args.doe), "doe_sha256": digest}}, constraint
        )
    problems = []
    if doe.document.get(CONVERGED_KEY, True) is False:
        problems += [f"DOE {args.doe}: {reason}" for reason in doe.document.get(UNCONVERGED_REASONS_KEY, [])]
        problems = problems or [f"DOE {args.doe} is marked as not converged"]
    problems += [str(problem) for problem in regression_problems(coefficients.extra["fit"])]
    if problems and not args.allow_unconverged:
        print(
            f"{PROG}: error: not converged, nothing written (--allow-unconverged writes it, marked):"
            + "".join(f"\n  {problem}" for problem in problems),
            file=sys.stderr,
        )
        return EXIT_FAILED
    if problems:
        coefficients = coefficients.marked_unconverged(problems)
    replaced = save_coefficients(coefficients, output)
    if not args.quiet:
        paper = load_coefficients(PAPER_SOURCE).parameters if doe.family == PAPER else None
        if not coefficients.variables.is_size_only:
            paper = None  # another basis than the paper's
        fit = coefficients.extra["fit"]
        print(report.equation9(coefficients.parameters, paper, fit, coefficients.variables.basis))
        print(report.regression_method(coefficients.extra["fit"]))
    print(f"{'replaced' if replaced else 'wrote'} {output}")
    return EXIT_OK


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (2 on bad input, with one line on stderr)."""
    return run_cli(parser(), regress, argv)


if __name__ == "__main__":
    sys.exit(main())
