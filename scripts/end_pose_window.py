"""How much room the end poses leave where a region map misses the margin: a sampled look at the
cells the infeasibility certificate could not settle.

    python scripts/end_pose_window.py [--map results/region_map.json] [--points 3] [--json OUT]

For every leaf of the map below the margin (``collision_free`` or ``undecided``) and every
proven-``infeasible`` leaf, it samples ``points`` x ``points`` obstacle sizes (L, W) over the
cell (corners included) and, at each, the largest clearance of a pose on the elbow branch whose
tip lies within the map's endpoint tolerance of P5 (the goal; P1 is never the limit in the
default scene): 60 radii x 240 angles over the disc, inverse kinematics, analytic link distance
(equal to Coal's where positive, ``tests/geometry``). The cell's value is the largest of its
samples: below the margin means no sampled size of the cell can end within the tolerance and
keep the margin. Prints the area fraction of the fitted range per status and class of that value.

A sampling, not a proof (the proofs are the map's); not part of the test suite.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict

import numpy as np

#: Upper edges of the classes of the sampled end-pose clearance, above the margin [m].
CLASSES_M = (0.0, 1e-4, 3e-4, 1e-3)


def _disc(tolerance_m: float) -> np.ndarray:
    radii = np.sqrt(np.linspace(0.0, 1.0, 60)) * tolerance_m
    angles = np.linspace(0.0, 2 * np.pi, 240, endpoint=False)
    r, a = np.meshgrid(radii, angles)
    return np.stack([r * np.cos(a), r * np.sin(a)], -1).reshape(-1, 2)


def best_end_pose_clearance_m(length_m: float, width_m: float, disc: np.ndarray, arm, scene, elbow: int) -> float:
    """Largest sampled clearance [m] of a pose on the ``elbow`` branch with its tip in ``disc`` around P5."""
    from pipeline.geometry.clearance import analytic_link_clearance
    from pipeline.model.kinematics import inverse_kinematics_batch
    from pipeline.model.obstacle import Obstacle

    tips = np.array([-(length_m / 2 + scene.start_dx_m), scene.y1_m]) + disc
    q = inverse_kinematics_batch(tips, arm.link_lengths_m, elbow)
    return float(analytic_link_clearance(q, arm, Obstacle.in_scene(length_m, width_m, scene)).min(axis=1).max())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--map", default="results/region_map.json", help="region map (default: %(default)s)")
    parser.add_argument("--points", type=int, default=3, help="samples per side of a cell [count] (default: 3)")
    parser.add_argument("--json", default=None, help="also write the table as JSON to this file")
    args = parser.parse_args(argv)
    from pipeline import load_coefficients
    from pipeline.certify.map_files import load_region_map
    from pipeline.certify.region_map import STATUSES
    from pipeline.exceptions import PipelineError
    from pipeline.model.arm import load_planar_arm

    try:
        region_map = load_region_map(args.map)
        coefficients = load_coefficients(region_map.coefficients_source)
    except PipelineError as exc:
        print(f"end_pose_window: {exc}", file=sys.stderr)
        return 2
    arm, scene = load_planar_arm(), coefficients.scene
    disc = _disc(region_map.endpoint_tolerance_m)
    margin = region_map.margin_m
    grid = np.linspace(0.0, 1.0, max(args.points, 2))
    table: dict[str, float] = defaultdict(float)
    for leaf in np.flatnonzero(region_map.status != STATUSES.index("margin")):
        cell = region_map.cell(int(leaf))
        (l_lo, l_hi), (w_lo, w_hi) = cell.range_of("L"), cell.range_of("W")
        value = max(
            best_end_pose_clearance_m(
                l_lo + u * (l_hi - l_lo), w_lo + v * (w_hi - w_lo), disc, arm, scene, coefficients.elbow
            )
            for u in grid
            for v in grid
        )
        above = value - margin
        label = next((f"< margin + {1e3 * c:g} mm" for c in CLASSES_M if above < c), "larger")
        table[f"{cell.status}: {label}"] += float(region_map.area[leaf])
    for key in sorted(table):
        print(f"{key:45s} {100 * table[key]:7.3f} % of the fitted range")
    if args.json:
        with open(args.json, "w") as handle:
            json.dump(dict(table), handle, indent=2)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
