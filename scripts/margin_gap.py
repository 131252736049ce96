"""Where a region map misses the margin without proving infeasibility, whose is the gap: the end
poses', the regression's or the certificate's?

    python scripts/margin_gap.py [--coefficients results/coefficients.json] [--map MAP] [--json OUT]

For every ``collision_free`` leaf of the map (certified collision-free, below the margin) it
samples

* the room the end poses leave at the leaf's centre: the largest clearance of a pose on the
  family's elbow branch whose tip is within the map's endpoint tolerance of P1 and of P5, the
  smaller of the two (``pipeline.certify.end_pose_room.end_pose_room_m``);
* the regression's own clearance over the leaf: its smallest analytic clearance at the
  corners and centre of the cell, at 401 times of s in [0.9, 1] and 401 in [0, 1]

and prints the area fraction of the fitted range per class of the room, split by whether the
regression's sampled clearance over the leaf reaches the margin (where it does, only the
certificate's bound is below it). Then, over the strip W >= ``--strip-from``, the area where the
room at the full tolerance lies within +-delta of the margin on a grid of obstacle sizes (the
band that a map with exact bounds and a regression exact to delta would still leave open), and
how fast the room changes with W there. Last, the band a map with exact cells would still leave
between the margin and infeasibility: per L (400 values), by bisection in W over
[``--strip-from``, W_hi], W_reg where the regression's smallest sampled clearance falls to the
margin and W_room where the sampled room does; the band is W_room - W_reg where positive (the
room falls with W: the obstacle grows with W and P1, P5 do not move). It measures the
regression alone, at a resolution no map has: the certifiable regression's settings
(``REFIT_ENDPOINT_HEADROOM`` and the feasible slack in
``pipeline/certify/certifiable_regression.py``) are chosen by it, since the refit's own maps
(cells 39 um or more of W, the band some 20-50 um) cannot show their effect (docs/results.md).

A sampling, not a proof (the proofs are the map's); not part of the test suite.
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys

import numpy as np

#: Class edges of the end-pose room relative to the margin [m].
ROOM_EDGES_M = (-np.inf, -2e-5, 0.0, 2e-5, 5e-5, 1e-4, np.inf)
#: Half widths of the bands around the margin [m].
BANDS_M = (1e-5, 2e-5, 5e-5, 1e-4)


def _leaf_minimum(coefficients, lengths: np.ndarray, widths: np.ndarray) -> np.ndarray:
    """Smallest sampled clearance [m] of the regression at each (L, W): s on [0, 1] and densely near 1."""
    from pipeline.certify.certifiable_regression import clearance_at, clearance_grid
    from pipeline.motion.trajectory import PARAMETER_NAMES

    s = np.unique(np.concatenate([np.linspace(0.0, 1.0, 401), np.linspace(0.9, 1.0, 401)]))
    b = np.stack([coefficients.parameters[name] for name in PARAMETER_NAMES], -1).ravel()
    values = clearance_at(b, clearance_grid(coefficients, np.column_stack([lengths, widths]), s), coefficients)
    return values.reshape(lengths.size, s.size).min(axis=1)


def _crossing(function, lengths: np.ndarray, lo: float, hi: float, margin: float) -> np.ndarray:
    """Per L, the W in [lo, hi] where ``function(L, W)`` falls to ``margin`` (30 halvings); hi
    where it stays at or above the margin, lo where it is below it all over."""
    w_lo, w_hi = np.full(lengths.size, lo), np.full(lengths.size, hi)
    above_top = function(lengths, w_hi) >= margin
    below_bottom = function(lengths, w_lo) < margin
    for _ in range(30):
        mid = (w_lo + w_hi) / 2
        above = function(lengths, mid) >= margin
        w_lo, w_hi = np.where(above, mid, w_lo), np.where(above, w_hi, mid)
    return np.where(above_top, hi, np.where(below_bottom, lo, (w_lo + w_hi) / 2))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--coefficients", default="results/coefficients.json", help="(default: %(default)s)")
    parser.add_argument("--map", default=None, help="region map (default: region_map.json beside the coefficients)")
    parser.add_argument(
        "--strip-from", type=float, default=0.116, help="W where the band grid starts [m] (default: 0.116)"
    )
    parser.add_argument("--json", default=None, help="also write the tables as JSON to this file")
    args = parser.parse_args(argv)

    from pipeline import load_coefficients
    from pipeline.certify.end_pose_room import end_pose_room_m
    from pipeline.certify.region_map import STATUSES
    from pipeline.exceptions import PipelineError
    from pipeline.io.jsonio import write_text_atomic

    try:  # the map beside the coefficients, or --map; either must certify them
        from pipeline.online.loading import BESIDE

        coefficients = load_coefficients(args.coefficients, region_map=args.map or BESIDE)
    except PipelineError as error:
        print(f"margin_gap: {error}", file=sys.stderr)
        return 2
    region_map = coefficients.region_map
    if region_map is None:
        print("margin_gap: no region map of these coefficients beside them (--map names one)", file=sys.stderr)
        return 2
    margin, tolerance = region_map.margin_m, region_map.endpoint_tolerance_m
    cell = region_map.leaf_sizes_m()
    centre = region_map.leaf_centres_m()
    below = np.flatnonzero(region_map.status == STATUSES.index("collision_free"))
    area = region_map.area[below]
    room = end_pose_room_m(coefficients, centre[below, 0], centre[below, 1], tolerance) - margin
    corners = np.array([[0.0, 0.0], [-0.5, -0.5], [-0.5, 0.5], [0.5, -0.5], [0.5, 0.5]])
    regression = np.min([_leaf_minimum(coefficients, *(centre[below] + k * cell[below]).T) for k in corners], axis=0)
    reached = regression >= margin
    rows = []
    print(f"collision_free leaves: {below.size}, {100 * area.sum():.3f} % of the range")
    for low, high in itertools.pairwise(ROOM_EDGES_M):
        sel = (room >= low) & (room < high)
        row = {
            "room_above_margin_m": [low, high],
            "area_fraction": float(area[sel].sum()),
            "regression_below_margin": float(area[sel & ~reached].sum()),
            "regression_at_margin_bound_below": float(area[sel & reached].sum()),
        }
        rows.append(row)
        print(
            f"room - margin in [{1e3 * low:+.2f}, {1e3 * high:+.2f}) mm: {100 * row['area_fraction']:.3f} %"
            f" (regression's sampled clearance below the margin {100 * row['regression_below_margin']:.3f} %,"
            f" at it, only the bound below {100 * row['regression_at_margin_bound_below']:.3f} %)"
        )
    lengths = np.linspace(*region_map.range_of("L"), 201)
    widths = np.linspace(args.strip_from, region_map.range_of("W")[1], 81)
    grid_l, grid_w = np.meshgrid(lengths, widths, indexing="ij")
    band_room = end_pose_room_m(coefficients, grid_l.ravel(), grid_w.ravel(), tolerance) - margin
    w_lo, w_hi = region_map.range_of("W")
    strip_fraction = (w_hi - args.strip_from) / (w_hi - w_lo)
    bands = {}
    for delta in BANDS_M:
        bands[delta] = float(np.mean(np.abs(band_room) < delta) * strip_fraction)
        print(f"room within +-{1e3 * delta:.2f} mm of the margin: {100 * bands[delta]:.3f} % of the range")
    slope = np.gradient(band_room.reshape(grid_l.shape), widths, axis=1)
    near = np.abs(band_room.reshape(grid_l.shape)) < 3e-4
    median_slope = float(np.median(slope[near]))
    print(f"d room / d W within 0.3 mm of the margin: median {median_slope:.3f} (m per m)")
    infeasible = float(np.mean(band_room < 0.0) * strip_fraction)
    print(f"room below the margin (sampled infeasible): {100 * infeasible:.3f} % of the range")
    l_lo, l_hi = region_map.range_of("L")
    per_l = l_lo + (np.arange(400) + 0.5) * (l_hi - l_lo) / 400
    w_reg = _crossing(lambda L, W: _leaf_minimum(coefficients, L, W), per_l, args.strip_from, w_hi, margin)
    w_room = _crossing(
        lambda L, W: end_pose_room_m(coefficients, L, W, tolerance), per_l, args.strip_from, w_hi, margin
    )
    regression_band = float(np.mean(np.maximum(w_room - w_reg, 0.0)) / (w_hi - w_lo))
    print(
        f"band where the end poses keep the margin and the regression does not: {100 * regression_band:.3f} % "
        f"of the range (per L by bisection in W)"
    )
    unresolved = int(np.count_nonzero(w_reg <= args.strip_from))
    if unresolved:
        print(f"  at {unresolved} of 400 L the regression misses the margin already at W = {args.strip_from} m")
    if args.json:
        document = {
            "classes": rows,
            "bands": bands,
            "sampled_infeasible": infeasible,
            "slope": median_slope,
            "regression_band": regression_band,
        }
        write_text_atomic(args.json, json.dumps(document, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
