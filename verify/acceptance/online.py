"""``python -m verify.online_sweep``: certify-or-repair over many obstacles.

For each sampled (L, W) the online generator runs with certification on
(:func:`pipeline.online.repair.generate_certified`). Every answer must either carry a certified
clearance of at least the margin or be a refusal that says why; this sweep checks that
invariant on every case and reports how many answers came straight from the regression,
how many were repaired, and how many were refused. ``--beyond 0.2`` widens the fitted range
by 20 % of its width on each side, to exercise extrapolation.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from pipeline.exceptions import NoCertifiedTrajectoryError, PipelineError, UnreachableObstacleError
from pipeline.geometry.clearance import ROUTES, route_from_name
from pipeline.io.jsonio import write_json_atomic
from pipeline.model.arm import DEFAULT_URDF, PlanarArm, load_planar_arm
from pipeline.offline.coefficients import Coefficients, load_coefficients
from pipeline.online.repair import RepairConfig, generate_certified

from .cli import DEFAULT_COEFFICIENTS, load_coefficients_for_cli
from .sweep import SweepRange, sample_cases


@dataclass(frozen=True)
class OnlineCase:
    """Outcome of one certify-or-repair query.

    Attributes:
        L, W: Obstacle size [m].
        status: "certified" (regression answer certified), "repaired", or "refused".
        certified_clearance_m: Certified clearance of the returned trajectory [m] (None if refused).
        regression_certified_clearance_m: Certified clearance of the regression's answer [m].
        reason: Why it was refused ("" otherwise).
        seconds: Wall time of the query [s].
    """

    L: float
    W: float
    status: str
    certified_clearance_m: float | None
    regression_certified_clearance_m: float | None
    reason: str
    seconds: float


def query(
    coefficients: Coefficients, arm: PlanarArm, length_m: float, width_m: float, config: RepairConfig
) -> OnlineCase:
    """One certify-or-repair query, its outcome recorded rather than raised."""
    start = time.perf_counter()
    try:
        answer = generate_certified(coefficients, length_m, width_m, arm, out_of_range="ignore", config=config)
    except NoCertifiedTrajectoryError as exc:
        return OnlineCase(
            length_m, width_m, "refused", None, exc.certified_clearance_m, exc.reason, time.perf_counter() - start
        )
    except UnreachableObstacleError as exc:
        return OnlineCase(length_m, width_m, "refused", None, None, str(exc), time.perf_counter() - start)
    return OnlineCase(
        length_m,
        width_m,
        "repaired" if answer.repaired else "certified",
        answer.certified_clearance_m,
        answer.regression_certificate.certified_clearance_m,
        "",
        time.perf_counter() - start,
    )


def _run_chunk(task: tuple) -> list[OnlineCase]:
    source, urdf, cases, config = task
    coefficients, arm = load_coefficients(source), load_planar_arm(urdf)
    return [query(coefficients, arm, float(L), float(W), config) for L, W in cases]


def run(
    source: str, cases: np.ndarray, config: RepairConfig, urdf: Path, jobs: int = 1, progress: bool = True
) -> list[OnlineCase]:
    """Run every case; results in case order whatever ``jobs``."""
    chunks = np.array_split(cases, max(1, min(len(cases), 8 * jobs)))
    tasks = [(source, urdf, chunk, config) for chunk in chunks if len(chunk)]
    bar = tqdm(total=len(cases), desc="certify-or-repair", unit="case", disable=not progress, file=sys.stderr)
    results: list[OnlineCase] = []
    if jobs == 1:
        for task in tasks:
            results.extend(_run_chunk(task))
            bar.update(len(task[2]))
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            for chunk in pool.map(_run_chunk, tasks):
                results.extend(chunk)
                bar.update(len(chunk))
    bar.close()
    return results


def summarize(cases: list[OnlineCase], margin_m: float) -> dict:
    """Counts per status, refusal reasons, and the invariant check."""
    status = Counter(case.status for case in cases)
    unsafe = [
        case for case in cases if case.status != "refused" and not (case.certified_clearance_m or -1.0) >= margin_m
    ]
    reasons = Counter(case.reason.split(" (")[0] if case.reason else "" for case in cases if case.status == "refused")
    times = np.array([case.seconds for case in cases])
    returned = [case.certified_clearance_m for case in cases if case.certified_clearance_m is not None]
    return {
        "cases": len(cases),
        "certified_from_regression": status["certified"],
        "repaired": status["repaired"],
        "refused": status["refused"],
        "refused_fraction": status["refused"] / len(cases),
        "refusal_reasons": dict(reasons),
        "answers_below_margin": len(unsafe),
        "min_returned_certified_clearance_m": min(returned) if returned else None,
        "median_query_s": float(np.median(times)),
        "max_query_s": float(np.max(times)),
        "margin_m": margin_m,
    }


def parser() -> argparse.ArgumentParser:
    defaults = RepairConfig()
    p = argparse.ArgumentParser(
        prog="python -m verify.online_sweep",
        description="Certify-or-repair on random obstacles: each answer certified >= margin, or refused.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("--coefficients", default=DEFAULT_COEFFICIENTS, help="coefficients file, or 'paper'")
    p.add_argument("--n", type=int, default=1000, help="number of random obstacles")
    p.add_argument("--seed", type=int, default=0, help="random seed of the obstacle sizes")
    p.add_argument(
        "--beyond", type=float, default=0.0, help="widen the fitted range by this fraction of its width per side"
    )
    p.add_argument("--jobs", type=int, default=1, help="worker processes")
    p.add_argument("--route", choices=tuple(ROUTES), default=defaults.route.name, help="certificate's distance route")
    p.add_argument("--max-seconds", type=float, default=defaults.max_seconds, help="repair time budget per query [s]")
    p.add_argument("--no-repair", action="store_true", help="refuse instead of repairing")
    p.add_argument("--urdf", type=Path, default=DEFAULT_URDF, help="URDF of the arm")
    p.add_argument("--json", type=Path, help="write cases and summary to this JSON file (atomically)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    return p


def main(argv: list[str] | None = None) -> int:
    """Exit 0 if every answer is certified >= margin or refused; 1 if any answer breaks that; 2 on bad input."""
    args = parser().parse_args(argv)
    try:
        if args.n < 1 or args.jobs < 1 or not 0 <= args.beyond < 10:
            raise PipelineError(f"--n {args.n} and --jobs {args.jobs} must be >= 1, --beyond {args.beyond} in [0, 10)")
        coefficients = load_coefficients_for_cli(args.coefficients)
        fitted = SweepRange.from_fitted(coefficients.fitted_range_m)
        grow_l = args.beyond * (fitted.L_m[1] - fitted.L_m[0])
        grow_w = args.beyond * (fitted.W_m[1] - fitted.W_m[0])
        sweep_range = SweepRange(
            (max(1e-3, fitted.L_m[0] - grow_l), fitted.L_m[1] + grow_l),
            (max(1e-3, fitted.W_m[0] - grow_w), fitted.W_m[1] + grow_w),
        )
        config = RepairConfig(
            route=route_from_name(args.route), max_seconds=args.max_seconds, repair=not args.no_repair
        )
        cases = sample_cases(sweep_range, args.n, args.seed)
        results = run(args.coefficients, cases, config, args.urdf, args.jobs, not args.no_progress)
    except PipelineError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    summary = summarize(results, coefficients.scene.margin_m)
    summary["range"] = {"L": list(sweep_range.L_m), "W": list(sweep_range.W_m)}
    print(
        f"certify-or-repair on {args.coefficients} ({coefficients.family.name}), {len(results)} cases, "
        f"L in [{sweep_range.L_m[0]:.4f}, {sweep_range.L_m[1]:.4f}] m, "
        f"W in [{sweep_range.W_m[0]:.4f}, {sweep_range.W_m[1]:.4f}] m"
    )
    print(
        f"  certified from the regression {summary['certified_from_regression']}, repaired {summary['repaired']}, "
        f"refused {summary['refused']} ({100 * summary['refused_fraction']:.1f} %)"
    )
    for reason, count in summary["refusal_reasons"].items():
        print(f"    refused {count}: {reason}")
    low = summary["min_returned_certified_clearance_m"]
    print(
        f"  answers below the {1e3 * summary['margin_m']:.1f} mm margin: {summary['answers_below_margin']}; "
        f"smallest certified clearance returned: {'n/a' if low is None else f'{1e3 * low:.3f} mm'}"
    )
    print(f"  query time median {1e3 * summary['median_query_s']:.1f} ms, max {1e3 * summary['max_query_s']:.1f} ms")
    if args.json:
        write_json_atomic(args.json, {"summary": summary, "cases": [asdict(case) for case in results]})
    return 0 if summary["answers_below_margin"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
