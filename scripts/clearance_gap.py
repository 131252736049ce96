"""How the range certificate's clearance bound tightens with the box, in the mean-value and the
second-order form.

    python scripts/clearance_gap.py [COEFFICIENTS] [--n 40] [--seed 0]

For boxes of 1/16, 1/32, 1/64 and 1/128 of the fitted box's side on every axis (and a quarter of
that in s = t / T), at ``--n`` random centres (``numpy.random.default_rng(seed)``), it bounds the
clearance over each box with ``pipeline.certify.clearance_bound.box_clearance_bounds`` in both
forms, samples the clearance on a grid of 3 points per axis (5 over (L, W)) inside the box
(analytic route, from the online generator, the obstacle moved by x and d where the coefficients
vary them), and prints the median gap between the sampled minimum and each bound, their ratio
and the second form's time against the first's. COEFFICIENTS defaults to the paper's Eq. 9.

A sampling, not a proof (each bound is checked to lie below the samples); not part of the test suite.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

#: Box sides, as fractions of the fitted range's side on every axis (a quarter of it in s).
BOX_SIDES = (1 / 16, 1 / 32, 1 / 64, 1 / 128)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python scripts/clearance_gap.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("coefficients", nargs="?", default="paper", help="coefficients file (default: paper)")
    parser.add_argument("--n", type=int, default=40, help="boxes per size [count] (default: 40)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the centres [integer >= 0] (default: 0)")
    args = parser.parse_args(argv)
    if args.n < 1 or args.seed < 0:
        parser.error(f"--n {args.n}, --seed {args.seed}: expected >= 1, >= 0")

    from pipeline import PipelineError, load_coefficients
    from pipeline.certify.clearance_bound import box_clearance_bounds
    from pipeline.certify.range_model import RangeModel
    from pipeline.geometry.clearance import analytic_link_clearance
    from pipeline.model.arm import load_planar_arm
    from pipeline.online.generator import generate

    try:
        coefficients = load_coefficients(args.coefficients, region_map=None)
    except PipelineError as exc:
        print(f"python scripts/clearance_gap.py: error: {exc}", file=sys.stderr)
        return 2
    model, arm = RangeModel.from_coefficients(coefficients), load_planar_arm()
    names = coefficients.variables.names

    def clearance(point: np.ndarray) -> float:
        moves = {name: float(point[names.index(name)]) for name in ("x", "d") if name in names}
        answer = generate(coefficients, float(point[0]), float(point[1]), **moves, out_of_range="ignore")
        q = answer.q(float(point[-1]) * answer.duration_s)
        return float(analytic_link_clearance(q, arm, answer.obstacle).min())

    rng = np.random.default_rng(args.seed)
    k = model.k
    per_axis = 5 if k == 2 else 3
    for side in BOX_SIDES:
        half = np.append(model.range_size * side, side / 4) / 2
        lo, hi = np.append(model.range_lo, 0.0) + half, np.append(model.range_lo + model.range_size, 1.0) - half
        center = lo + (hi - lo) * rng.uniform(size=(args.n, k + 1))
        radius = np.tile(half, (args.n, 1))
        started = time.perf_counter()
        first = box_clearance_bounds(model, center, radius).lower_m
        middle = time.perf_counter()
        second = box_clearance_bounds(model, center, radius, second_order=True).lower_m
        cost = (time.perf_counter() - middle) / (middle - started)
        offsets = np.array(np.meshgrid(*[np.linspace(-1.0, 1.0, per_axis)] * (k + 1), indexing="ij"))
        offsets = offsets.reshape(k + 1, -1).T
        lowest = np.array([min(clearance(c + u * radius[0]) for u in offsets) for c in center])
        if np.any(lowest < first - 1e-12) or np.any(lowest < second - 1e-12):
            print(f"boxes of 1/{1 / side:.0f}: a bound above a sampled clearance", file=sys.stderr)
            return 1
        gap1, gap2 = np.median(lowest - first), np.median(lowest - second)
        print(
            f"boxes of 1/{1 / side:.0f}: gap mean-value {gap1 * 1e3:.3f} mm, second-order {gap2 * 1e3:.3f} mm "
            f"({gap1 / gap2:.1f}x tighter), time {cost:.1f}x"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
