"""``python -m pipeline.regress DOE.json -o coefficients.json``: the regression step alone.

Works on any DOE file: ours (``results/doe.json``) or the paper's Table 2
(``paper`` names the copy shipped with the package).
"""

from __future__ import annotations

import argparse
import hashlib
import sys
from pathlib import Path

from . import report
from .coefficients import fit_coefficients, load_coefficients, paper_data_path, save_coefficients
from .doe import load_doe
from .exceptions import PipelineError


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m pipeline.regress",
        description="Fit p(L, W) = b0 + b1 L + b2 W + b3 L^2 + b4 L W + b5 W^2 per parameter on a DOE file.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("doe", help="DOE file (JSON), or 'paper' for the paper's Table 2")
    p.add_argument("-o", "--output", type=Path, required=True, help="coefficients file to write (JSON)")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    p.add_argument("--quiet", action="store_true", help="do not print the coefficient table")
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (2 on bad input, with one line on stderr)."""
    args = parser().parse_args(argv)
    try:
        path = paper_data_path("paper_table2_doe.json") if args.doe == "paper" else Path(args.doe)
        doe = load_doe(path)
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
        coefficients, _ = fit_coefficients(doe, {"provenance": {"doe": str(args.doe), "doe_sha256": digest}})
        save_coefficients(coefficients, args.output, overwrite=args.force)
    except PipelineError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if not args.quiet:
        paper = load_coefficients("paper").parameters if doe.family == "paper" else None
        print(report.equation9(coefficients.parameters, paper, coefficients.extra["fit"]))
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
