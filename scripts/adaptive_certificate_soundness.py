"""The adaptive certificate against the dense one and a 100x denser Coal sampling, on many sweep cases.

    python scripts/adaptive_certificate_soundness.py [--coefficients F] [--n 10000] [--jobs 2] [--json OUT]

Per case (L, W uniform in the coefficients' fitted range, seeded): the regression's trajectory is
certified by the adaptive route in tolerance mode and in decide mode (margin), by the dense
route (``initial="dense"``), and sampled by Coal at 100x the adaptive route's initial samples. It counts
the cases where a bound lies above the denser sampling's minimum (unsound; must be 0), where the
adaptive bound is more than 0.05 mm from the dense one, and where the decide-mode verdict differs
from the dense bound's outside a 0.05 mm band around the margin. Not part of the test suite (minutes);
``tests/geometry/test_adaptive_certificate.py`` runs the same checks on a few hundred cases.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

CLOSE_M = 5e-5


def _chunk(job: tuple[str, list[tuple[float, float]]]) -> list[dict]:
    from pipeline import load_coefficients
    from pipeline.geometry.clearance import CoalClearance
    from pipeline.geometry.sinusoid_certificate import certify_trajectory
    from pipeline.model.arm import load_planar_arm
    from pipeline.online.generator import generate

    source, cases = job
    coefficients = load_coefficients(source)
    arm = load_planar_arm()
    margin = coefficients.scene.margin_m
    rows = []
    for L, W in cases:
        answer = generate(coefficients, L, W, out_of_range="ignore")
        trajectory, obstacle = answer.trajectory, answer.obstacle
        started = time.perf_counter()
        adaptive = certify_trajectory(trajectory, arm, obstacle)
        adaptive_s = time.perf_counter() - started
        started = time.perf_counter()
        decided = certify_trajectory(trajectory, arm, obstacle, decide_above_m=margin)
        decided_s = time.perf_counter() - started
        started = time.perf_counter()
        dense = certify_trajectory(trajectory, arm, obstacle, initial="dense")
        dense_s = time.perf_counter() - started
        t = np.linspace(0.0, trajectory.duration_s, 100 * adaptive.initial_samples)
        denser = float(np.min(CoalClearance(arm, obstacle).link_clearance(trajectory.q(t))))
        rows.append(
            {
                "L": L,
                "W": W,
                "adaptive": adaptive.certified_clearance_m,
                "decided": decided.certified_clearance_m,
                "dense": dense.certified_clearance_m,
                "denser_min": denser,
                "evaluations": [adaptive.evaluations, decided.evaluations, dense.evaluations],
                "seconds": [adaptive_s, decided_s, dense_s],
            }
        )
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--coefficients", default="results/coefficients.json")
    parser.add_argument("--n", type=int, default=10_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)

    from pipeline import load_coefficients

    coefficients = load_coefficients(args.coefficients)
    margin = coefficients.scene.margin_m
    (l_lo, l_hi), (w_lo, w_hi) = coefficients.fitted_range_m["L"], coefficients.fitted_range_m["W"]
    rng = np.random.default_rng(args.seed)
    cases = list(zip(rng.uniform(l_lo, l_hi, args.n).tolist(), rng.uniform(w_lo, w_hi, args.n).tolist(), strict=True))
    chunks = [(args.coefficients, cases[i : i + 250]) for i in range(0, len(cases), 250)]
    started = time.perf_counter()
    with ProcessPoolExecutor(args.jobs) as pool:
        rows = [row for part in pool.map(_chunk, chunks) for row in part]
    elapsed = time.perf_counter() - started

    adaptive = np.array([r["adaptive"] for r in rows])
    decided = np.array([r["decided"] for r in rows])
    dense = np.array([r["dense"] for r in rows])
    denser = np.array([r["denser_min"] for r in rows])
    evaluations = np.array([r["evaluations"] for r in rows])
    seconds = np.array([r["seconds"] for r in rows])
    outside_band = np.abs(dense - margin) > CLOSE_M
    summary = {
        "coefficients": args.coefficients,
        "cases": len(rows),
        "adaptive_above_denser_min": int(np.sum(adaptive > denser)),
        "decided_above_denser_min": int(np.sum(decided > denser)),
        "dense_above_denser_min": int(np.sum(dense > denser)),
        "adaptive_minus_dense_max_abs_m": float(np.max(np.abs(adaptive - dense))),
        "adaptive_farther_than_0.05mm_from_dense": int(np.sum(np.abs(adaptive - dense) > CLOSE_M)),
        "decide_verdict_differs_outside_0.05mm_band": int(
            np.sum(((decided > margin) != (dense > margin)) & outside_band)
        ),
        "cases_below_margin_by_dense": int(np.sum(dense < margin)),
        "evaluations_median_adaptive_decided_dense": np.median(evaluations, axis=0).tolist(),
        "seconds_median_adaptive_decided_dense": np.median(seconds, axis=0).tolist(),
        "wall_seconds": elapsed,
    }
    print(json.dumps(summary, indent=2))
    if args.json:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump({"summary": summary, "cases": rows}, handle)
    unsound = summary["adaptive_above_denser_min"] + summary["decided_above_denser_min"]
    return 1 if unsound or summary["adaptive_farther_than_0.05mm_from_dense"] else 0


if __name__ == "__main__":
    sys.exit(main())
