"""How much of the range a map with exact cells would still leave between the margin and
infeasibility: the band where the end poses can keep the margin and the regression does not.

    python scripts/regression_band.py [--coefficients results/coefficients.json] [--json OUT]

Per L (400 values over the fitted range), by bisection in W over [``--from``, W_hi]: W_reg,
where the regression's smallest sampled clearance (s on [0, 1] and densely near 1) falls to the
margin, and W_room, where the sampled room of the end poses within the endpoint tolerance
(``pipeline.certify.end_pose_room``) does; the band is W_room - W_reg where positive, as an
area fraction of the fitted range. It measures the regression alone, at a resolution no map
has: the certifiable regression's settings (``REFIT_ENDPOINT_HEADROOM`` and the feasible slack
in ``pipeline/certify/certifiable_regression.py``) were chosen by it, since the refit's own maps
(cells 39 um or more of W, the band some 20-50 um) could not show their effect. The room is
assumed to fall with W (it does: the obstacle grows with W and P1, P5 do not move) and the
regression's clearance to cross the margin once in [``--from``, W_hi] (checked: the script
says where it does not). A sampling, not a proof (the proofs are the map's); not part of the
test suite.
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np


def crossing(function, lengths: np.ndarray, lo: float, hi: float, margin: float) -> np.ndarray:
    """Per L, the W in [lo, hi] where ``function(L, W)`` falls to ``margin`` (bisection, 30
    halvings); hi where it stays above, lo where it is below all over."""
    w_lo, w_hi = np.full(lengths.size, lo), np.full(lengths.size, hi)
    above_top = function(lengths, w_hi) >= margin
    below_bottom = function(lengths, w_lo) < margin
    for _ in range(30):
        mid = (w_lo + w_hi) / 2
        above = function(lengths, mid) >= margin
        w_lo, w_hi = np.where(above, mid, w_lo), np.where(above, w_hi, mid)
    out = (w_lo + w_hi) / 2
    return np.where(above_top, hi, np.where(below_bottom, lo, out))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--coefficients", default="results/coefficients.json", help="(default: %(default)s)")
    parser.add_argument(
        "--from", dest="w_from", type=float, default=0.115, help="lowest W searched [m] (default: 0.115)"
    )
    parser.add_argument(
        "--tolerance", type=float, default=0.002, help="endpoint tolerance of the room [m] (default: 0.002)"
    )
    parser.add_argument("--json", default=None, help="also write the figures as JSON to this file")
    args = parser.parse_args(argv)
    from pipeline.certify.certifiable_regression import clearance_at, clearance_grid
    from pipeline.certify.end_pose_room import end_pose_room_m
    from pipeline.exceptions import PipelineError
    from pipeline.io.jsonio import write_text_atomic
    from pipeline.motion.trajectory import PARAMETER_NAMES
    from pipeline.offline.coefficients import load_coefficients

    try:
        coefficients = load_coefficients(args.coefficients)
    except PipelineError as error:
        print(f"regression_band: {error}", file=sys.stderr)
        return 2
    (l_lo, l_hi), (w_lo, w_hi) = coefficients.fitted_range_m["L"], coefficients.fitted_range_m["W"]
    if not w_lo <= args.w_from < w_hi:
        print(
            f"regression_band: --from {args.w_from} m is outside the fitted W range [{w_lo}, {w_hi}) m", file=sys.stderr
        )
        return 2
    margin = coefficients.scene.margin_m
    lengths = l_lo + (np.arange(400) + 0.5) * (l_hi - l_lo) / 400
    s = np.unique(np.concatenate([np.linspace(0.0, 1.0, 101), np.linspace(0.9, 1.0, 401)]))
    b = np.stack([coefficients.parameters[name] for name in PARAMETER_NAMES], -1).ravel()

    def regression(L: np.ndarray, W: np.ndarray) -> np.ndarray:
        values = clearance_at(b, clearance_grid(coefficients, np.column_stack([L, W]), s), coefficients)
        return values.reshape(L.size, s.size).min(axis=1)

    def room(L: np.ndarray, W: np.ndarray) -> np.ndarray:
        return end_pose_room_m(coefficients, L, W, args.tolerance)

    w_reg = crossing(regression, lengths, args.w_from, w_hi, margin)
    w_room = crossing(room, lengths, args.w_from, w_hi, margin)
    band = np.maximum(w_room - w_reg, 0.0)
    area = float(band.mean() / (w_hi - w_lo))
    infeasible = float((w_hi - w_room).mean() / (w_hi - w_lo))
    unresolved = int(np.count_nonzero(w_reg <= args.w_from))
    print(f"band where the end poses keep the margin and the regression does not: {100 * area:.3f} % of the range")
    print(f"end poses below the margin (sampled infeasible): {100 * infeasible:.3f} % of the range")
    print(f"largest band: {1e6 * band.max():.1f} um of W at L = {lengths[int(np.argmax(band))]:.4f} m")
    if unresolved:
        print(f"at {unresolved} of 400 L the regression misses the margin already at W = {args.w_from} m: lower --from")
    if args.json:
        document = {"band_area_fraction": area, "infeasible_area_fraction": infeasible, "unresolved": unresolved}
        write_text_atomic(args.json, json.dumps(document, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
