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
Of the leaves of the first class it samples the 3^k grid of corners, edge and face midpoints
too: the share the margin's contour crosses (a grid point below the margin: no proof of the
whole leaf exists, only of a part), and how far the leaf's clearance bound lies below the grid's
lowest sampled clearance (the bound's gap, where the contour does not decide).

``--uniform N`` needs no map: it samples N points uniformly in the coefficients' fitted box
(the same seed) and prints the same classes as shares of the box, with the regression's own cap
(the box where its sampled clearance keeps the margin, over the box where the end poses leave
it: what a map of these coefficients could reach with every cell decided at its centre), and the
largest sampled endpoint error; a quick comparison of two fits before their maps are built.

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
    parser.add_argument(
        "--uniform",
        type=int,
        default=0,
        metavar="N",
        help="no map: N points uniform in the fitted box instead of leaves [count] (default: 0, the map's leaves)",
    )
    args = parser.parse_args(argv)
    if args.n < 1 or args.seed < 0 or args.uniform < 0:
        parser.error(
            f"--n {args.n}, --seed {args.seed}, --uniform {args.uniform}: "
            "expected --n >= 1, --seed >= 0, --uniform >= 0"
        )

    from pipeline import load_coefficients
    from pipeline.certify.map_files import load_region_map
    from pipeline.exceptions import PipelineError

    try:
        coefficients = load_coefficients(args.coefficients, region_map=None)
        if args.uniform:
            return _uniform(coefficients, args.uniform, args.seed)
        region_map = load_region_map(args.map) if args.map else load_coefficients(args.coefficients).region_map
    except PipelineError as exc:
        print(f"python scripts/margin_band.py: error: {exc}", file=sys.stderr)
        return 2
    if region_map is None or not region_map.belongs_to(coefficients):
        print("python scripts/margin_band.py: error: no region map of these coefficients", file=sys.stderr)
        return 2
    return _leaves(coefficients, region_map, args.n, args.seed, args.weight)


def _lowest(coefficients, points: np.ndarray) -> np.ndarray:
    """The regression's lowest sampled clearance along [0, T] [m] per row of ``points`` (n, k: the
    coefficients' variables [m])."""
    from pipeline.certify.certifiable_regression import clearance_at, clearance_grid
    from pipeline.motion.trajectory import PARAMETER_NAMES

    b = np.stack([coefficients.parameters[name] for name in PARAMETER_NAMES], -1).ravel()
    s = np.linspace(0.0, 1.0, SAMPLES_S)
    chunks = np.array_split(points, max(1, len(points) // 2000))  # memory: 401 samples per point
    return np.concatenate(
        [clearance_at(b, clearance_grid(coefficients, c, s), coefficients).reshape(len(c), -1).min(1) for c in chunks]
    )


def _lowest_and_room(coefficients, points: np.ndarray, tolerance_m: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_lowest` and the end poses' sampled room at ``tolerance_m`` [m], per row of ``points``."""
    from pipeline.certify.end_pose_room import end_pose_room_m

    lowest = _lowest(coefficients, points)
    names = coefficients.variables.names
    x = points[:, names.index("x")] if "x" in names else None
    d = points[:, names.index("d")] if "d" in names else None
    room = end_pose_room_m(coefficients, points[:, 0], points[:, 1], tolerance_m, x, top_y_m=d)
    return lowest, room


def _classes(lowest: np.ndarray, room: np.ndarray, margin_m: float) -> dict[str, np.ndarray]:
    """The four classes of the module docstring, as masks."""
    return {
        "the regression keeps the margin at the centre (the bound's share)": lowest >= margin_m,
        "the end poses leave less than the margin (infeasible, not proven)": (lowest < margin_m) & (room < margin_m),
        "the end poses leave >= margin + 0.1 mm, the regression less than the margin (the regression's share)": (
            (lowest < margin_m) & (room >= margin_m + ROOM_SLACK_M)
        ),
        "the end poses leave the margin to within 0.1 mm, the regression less": (
            (lowest < margin_m) & (room >= margin_m) & (room < margin_m + ROOM_SLACK_M)
        ),
    }


def _leaves(coefficients, region_map, n: int, seed: int, weight: str) -> int:
    """The classes over ``n`` leaves below the margin drawn from ``region_map`` (module docstring)."""
    from pipeline.certify.region_map import STATUSES

    volume = region_map.area / region_map.area.sum()
    below = np.flatnonzero(region_map.status == STATUSES.index("collision_free"))
    if below.size == 0:
        print("no leaf below the margin that is not proven infeasible")
        return 0
    rng = np.random.default_rng(seed)
    if weight == "volume":
        drawn = np.sort(rng.choice(below, n, replace=True, p=volume[below] / volume[below].sum()))
    else:
        drawn = np.sort(rng.choice(below, min(n, below.size), replace=False))
    centres = region_map.leaf_centres_m()[drawn]
    lowest, room = _lowest_and_room(coefficients, centres, region_map.endpoint_tolerance_m)
    total = float(volume[below].sum())
    print(
        f"{below.size} leaves below the margin, not proven infeasible: {100 * total:.2f} % of the box "
        f"(axes {', '.join(region_map.axes)}); {drawn.size} drawn (seed {seed})"
    )
    for label, mask in _classes(lowest, room, region_map.margin_m).items():
        share = float(np.mean(mask))
        print(f"  {100 * share:5.1f} % of the drawn ({100 * share * total:.2f} % of the box): {label}")
    print(
        f"  W of the drawn leaves' centres: {centres[:, 1].min():.5f} .. {centres[:, 1].max():.5f} m; "
        f"sampled clearance {1e3 * lowest.min():.3f} .. {1e3 * lowest.max():.3f} mm"
    )
    kept = lowest >= region_map.margin_m
    if np.any(kept):
        _crossed(coefficients, region_map, drawn[kept], centres[kept])
    return 0


def _crossed(coefficients, region_map, leaves: np.ndarray, centres: np.ndarray) -> None:
    """Of ``leaves`` whose centre keeps the margin: the share the margin's contour crosses (a point
    of the 3^k grid of corners, edge and face midpoints below it), and how far the bound lies below
    the grid's lowest sampled clearance."""
    import itertools

    k = centres.shape[1]
    half = region_map.leaf_sizes_m()[leaves] / 2
    grid = np.array(list(itertools.product((-1.0, 0.0, 1.0), repeat=k)))
    points = (centres[:, None, :] + grid[None] * half[:, None, :]).reshape(-1, k)
    lowest = _lowest(coefficients, points).reshape(len(leaves), -1)
    crossed = lowest.min(axis=1) < region_map.margin_m
    gap_mm = 1e3 * (lowest.min(axis=1) - region_map.clearance_bound_m[leaves])
    print(
        f"  of the drawn leaves whose centre keeps the margin, {100 * np.mean(crossed):.1f} % are crossed by the "
        f"margin's contour (a point of their 3^{k} grid below it); the grid's lowest sampled clearance lies "
        f"{np.median(gap_mm):.3f} mm (median; {gap_mm.min():.3f} .. {gap_mm.max():.3f}) above the leaf's bound"
    )


def _uniform(coefficients, n: int, seed: int) -> int:
    """The classes over ``n`` points uniform in the fitted box, the regression's own cap and the
    largest sampled endpoint error (module docstring), at the build's endpoint tolerance."""
    from pipeline.offline.endpoint_regression import EndpointConstraint, endpoint_errors_m, targets_at

    variables = coefficients.variables
    box = np.array([coefficients.fitted_range_m[name] for name in variables.names])
    points = box[:, 0] + np.random.default_rng(seed).random((n, variables.k)) * (box[:, 1] - box[:, 0])
    tolerance_m = EndpointConstraint().tolerance_m
    margin_m = coefficients.scene.margin_m
    lowest, room = _lowest_and_room(coefficients, points, tolerance_m)
    print(f"{n} points uniform in the box (axes {', '.join(variables.names)}; seed {seed}):")
    print(f"  {100 * np.mean(lowest >= margin_m):5.2f} % of the box: the regression keeps the margin")
    for label, mask in list(_classes(lowest, room, margin_m).items())[1:]:
        label = label.replace(" (infeasible, not proven)", " (sampled)")
        print(f"  {100 * np.mean(mask):5.2f} % of the box: {label}")
    feasible = 1.0 - float(np.mean((lowest < margin_m) & (room < margin_m)))
    cap = 100 * np.mean(lowest >= margin_m) / feasible
    print(f"  the regression's own cap: the margin on {cap:.2f} % of the feasible volume")
    if not variables.is_size_only:
        targets = targets_at(points, variables, coefficients.scene, coefficients.link_lengths_m)
        parameters = variables.design(points) @ np.stack(
            [coefficients.parameters[name] for name in coefficients.family.free_parameter_names], -1
        )
        errors = endpoint_errors_m(parameters, targets)
        print(f"  sampled endpoint error at most {1e3 * errors.max():.3f} mm (tolerance {1e3 * tolerance_m:.1f} mm)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
