"""How the range certificate's endpoint bound tightens with the cell size, per axis.

    python scripts/endpoint_gap.py results-x/coefficients.json [--n 2000] [--seed 0]

For cubes of 1/16, 1/32 and 1/64 of the fitted box's side, at ``--n`` random centres
(``numpy.random.default_rng(seed)``), it prints the error at the centre, each axis's share of the
mean-value form's gap (its term along the axis), and for the mean-value form and the
second-order form (``pipeline.certify.endpoints.endpoint_error_bounds``) the endpoint bound over
the cell, the share of cells whose bound is within the endpoint tolerance and the gap between
the bound and the error at the centre. A gap that falls by about 4 per halving is second order
in the cell's size: the gradient's interval over the cell, not the gradient at its centre, makes
it, and the cells the certificate needs to prove the tolerance follow from it.

A sampling of the bound's terms, not a proof; not part of the test suite.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

#: Cell sides, as fractions of the fitted range's side on every axis.
CELL_SIDES = (1 / 16, 1 / 32, 1 / 64)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python scripts/endpoint_gap.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("coefficients", help="coefficients file")
    parser.add_argument("--n", type=int, default=2000, help="cells per size [count] (default: 2000)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the centres [integer >= 0] (default: 0)")
    parser.add_argument("--tolerance", type=float, default=0.002, help="endpoint tolerance [m] (default: 0.002)")
    args = parser.parse_args(argv)
    if args.n < 1 or args.seed < 0 or not args.tolerance > 0:
        parser.error(f"--n {args.n}, --seed {args.seed}, --tolerance {args.tolerance}: expected >= 1, >= 0, > 0")

    from pipeline import load_coefficients
    from pipeline.certify.endpoints import endpoint_bounds_and_shares, endpoint_error_bounds
    from pipeline.certify.range_model import RangeModel
    from pipeline.exceptions import PipelineError

    try:
        coefficients = load_coefficients(args.coefficients, region_map=None)
        model = RangeModel.from_coefficients(coefficients)
    except PipelineError as exc:
        print(f"python scripts/endpoint_gap.py: error: {exc}", file=sys.stderr)
        return 2
    names = coefficients.variables.names
    lo, hi = (np.array([coefficients.fitted_range_m[name][i] for name in names]) for i in (0, 1))
    rng = np.random.default_rng(args.seed)
    print(f"axes {', '.join(names)}; medians over {args.n} cells per size; shares per axis in mm")
    for side in CELL_SIDES:
        half = (hi - lo) * side / 2
        centres = lo + half + rng.uniform(0.0, 1.0, (args.n, len(names))) * (hi - lo - 2 * half)
        radii = np.tile(half, (args.n, 1))
        centre = endpoint_error_bounds(model, centres, np.zeros_like(centres)).max(axis=1)
        _, shares = endpoint_bounds_and_shares(model, centres, radii)
        per_axis = ", ".join(f"{name} {1e3 * v:.3f}" for name, v in zip(names, np.median(shares, 0), strict=True))
        print(f"cells of 1/{round(1 / side)}: error at the centre {1e3 * np.median(centre):.2f} mm; shares {per_axis}")
        for form, second_order in (("mean-value", False), ("second-order", True)):
            bound = endpoint_error_bounds(model, centres, radii, second_order).max(axis=1)
            print(
                f"  {form:>12}: bound {1e3 * np.median(bound):.2f} mm (90th percentile "
                f"{1e3 * np.percentile(bound, 90):.2f}), within {1e3 * args.tolerance:g} mm on "
                f"{100 * np.mean(bound <= args.tolerance):.1f} %, gap {1e3 * np.median(bound - centre):.2f} mm"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
