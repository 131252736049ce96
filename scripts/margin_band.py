"""Where a region map over any axes ((L, W), (L, W, x), (L, W, x, d)) misses the margin without proving
infeasibility, whose is the gap: the certificate's, the end poses' or the regression's?

    python scripts/margin_band.py results-x/coefficients.json [--map MAP] [--n 600] [--seed 0] [--weight volume]

It draws ``--n`` of the map's ``collision_free`` leaves (certified collision-free, below the
margin; ``numpy.random.default_rng(seed)``), each draw with a probability in proportion to the
leaf's volume (with replacement, so that every share below is a share of the volume, whatever the
leaves' sizes; ``--weight count``: every leaf alike, without replacement), and samples at
each leaf's centre

* the regression's clearance along [0, T] at 401 times (analytic distance, the certifiable
  regression's ``clearance_at``, against the obstacle moved by x where the map has x);
* the room the end poses leave at the map's endpoint tolerance
  (``pipeline.certify.end_pose_room.end_pose_room_m``, P1 and P5 moved by x and d),

and prints the share of the drawn leaves, and the volume fraction of the box they stand for,
in which: the regression's sampled clearance keeps the margin (finer cells could prove it); the
end poses leave less than the margin (infeasible, not proven at this cell size); the end poses
leave at least the margin + 0.1 mm and the regression's clearance is below the margin (the
regression's share); the rest (room within 0.1 mm above the margin).

A sampling at leaf centres, not a proof (the proofs are the map's); not part of the test suite.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

#: Normalised times of the clearance samples along each leaf's motion.
SAMPLES_S = 401
#: Room above the margin [m] from which a leaf below the margin is counted as the regression's.
ROOM_SLACK_M = 1e-4


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python scripts/margin_band.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("coefficients", help="coefficients file")
    parser.add_argument("--map", default=None, help="region map (default: the one beside the coefficients)")
    parser.add_argument("--n", type=int, default=600, help="leaves drawn [count] (default: 600)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the draw [integer >= 0] (default: 0)")
    parser.add_argument(
        "--weight",
        choices=("volume", "count"),
        default="volume",
        help="draw leaves by their volume (with replacement) or alike (default: volume)",
    )
    args = parser.parse_args(argv)
    if args.n < 1 or args.seed < 0:
        parser.error(f"--n {args.n} and --seed {args.seed}: expected --n >= 1 and --seed >= 0")

    from pipeline import load_coefficients
    from pipeline.certify.certifiable_regression import clearance_at, clearance_grid
    from pipeline.certify.end_pose_room import end_pose_room_m
    from pipeline.certify.map_files import load_region_map
    from pipeline.certify.region_map import STATUSES
    from pipeline.exceptions import PipelineError
    from pipeline.motion.trajectory import PARAMETER_NAMES

    try:
        coefficients = load_coefficients(args.coefficients, region_map=None)
        region_map = load_region_map(args.map) if args.map else load_coefficients(args.coefficients).region_map
    except PipelineError as exc:
        print(f"python scripts/margin_band.py: error: {exc}", file=sys.stderr)
        return 2
    if region_map is None or not region_map.belongs_to(coefficients):
        print("python scripts/margin_band.py: error: no region map of these coefficients", file=sys.stderr)
        return 2
    volume = region_map.area / region_map.area.sum()
    below = np.flatnonzero(region_map.status == STATUSES.index("collision_free"))
    if below.size == 0:
        print("no leaf below the margin that is not proven infeasible")
        return 0
    rng = np.random.default_rng(args.seed)
    if args.weight == "volume":
        drawn = np.sort(rng.choice(below, args.n, replace=True, p=volume[below] / volume[below].sum()))
    else:
        drawn = np.sort(rng.choice(below, min(args.n, below.size), replace=False))
    centres = region_map.leaf_centres_m()[drawn]
    b = np.stack([coefficients.parameters[name] for name in PARAMETER_NAMES], -1).ravel()
    s = np.linspace(0.0, 1.0, SAMPLES_S)
    clearance = clearance_at(b, clearance_grid(coefficients, centres, s), coefficients).reshape(len(drawn), s.size)
    lowest = clearance.min(axis=1)
    names = coefficients.variables.names
    x = centres[:, names.index("x")] if "x" in names else None
    d = centres[:, names.index("d")] if "d" in names else None
    room = end_pose_room_m(coefficients, centres[:, 0], centres[:, 1], region_map.endpoint_tolerance_m, x, top_y_m=d)
    margin = region_map.margin_m
    classes = {
        "the regression keeps the margin at the centre (the bound's share)": lowest >= margin,
        "the end poses leave less than the margin (infeasible, not proven)": (lowest < margin) & (room < margin),
        "the end poses leave >= margin + 0.1 mm, the regression less than the margin (the regression's share)": (
            (lowest < margin) & (room >= margin + ROOM_SLACK_M)
        ),
        "the end poses leave the margin to within 0.1 mm, the regression less": (
            (lowest < margin) & (room >= margin) & (room < margin + ROOM_SLACK_M)
        ),
    }
    total = float(volume[below].sum())
    print(
        f"{below.size} leaves below the margin, not proven infeasible: {100 * total:.2f} % of the box "
        f"(axes {', '.join(region_map.axes)}); {drawn.size} drawn (seed {args.seed})"
    )
    for label, mask in classes.items():
        share = float(np.mean(mask))
        print(f"  {100 * share:5.1f} % of the drawn ({100 * share * total:.2f} % of the box): {label}")
    print(
        f"  W of the drawn leaves' centres: {centres[:, 1].min():.5f} .. {centres[:, 1].max():.5f} m; "
        f"sampled clearance {1e3 * lowest.min():.3f} .. {1e3 * lowest.max():.3f} mm"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
