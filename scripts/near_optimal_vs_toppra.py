"""The near time-optimal timing against TOPP-RA: T'/T_TOPP-RA on many random obstacles and three limit sets.

For ``--n`` random obstacles (L, W) uniform in the coefficients' fitted range (a seeded numpy
Generator), it times each answer's path with our near time-optimal timing
(``generate_certified(coefficients, L, W, timing=NEAR_OPTIMAL, limits=...)``: certified in
continuous time, smooth, at rest at both ends) and with TOPP-RA (:mod:`verify.benchmark.toppra_peer`:
toppra's time-optimal parameterization on the same exact path and limits, speed, acceleration and
the closed-form torque, at rest at both ends, ``--gridpoints`` uniform gridpoints), and prints per
limit set the median and the largest ratio T'/T_TOPP-RA over the obstacles (1 would be as fast as
TOPP-RA; TOPP-RA keeps its limits at its gridpoints only, ours everywhere). The limit sets:

* (a) the URDF's limits (positions, speeds 3 rad/s, efforts 10 N m for the shipped arm) and an
  acceleration limit of ``--acceleration-limit`` (5 rad/s^2) per joint;
* (b) as (a) with the speed limit lowered to 0.3 rad/s per joint (the speed limit binds);
* (c) as (a) with the effort limit lowered to 0.05 N m per joint (the torque limit binds);

each with the default jerk limit (:meth:`pipeline.model.limits.ArmLimits.with_servo_defaults`: the
acceleration limit / 50 ms, 100 rad/s^3 at 5 rad/s^2), then again with each of ``--jerk-limits``
(rad/s^3 per joint, set by the user, tighter than the default). TOPP-RA has no jerk limit: its
T_TOPP-RA is the same for every jerk limit (computed once per path and limit set), so a lower jerk
limit shows as a larger ratio. For the default jerk limit it also reports the ratio of the timing
the map holds (:mod:`pipeline.certify.near_optimal_cells`, the cells made for that limit set, only
those holding the obstacles): one timing per cell, certified for every obstacle of the cell.
It also reports TOPP-RA's own largest relative excess over each
limit, sampling its reconstructed motion at ``--oversample`` x its gridpoints (what the
gridpoint-only constraints let through between gridpoints). No threshold is applied: the script
reports, and exits 0 (2 on bad input).

    python scripts/near_optimal_vs_toppra.py --n 200
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

#: The limit sets: key, description, and what replaces the URDF's limits (besides the acceleration).
LIMIT_SETS: tuple[tuple[str, str, dict[str, tuple[float, float]]], ...] = (
    ("a", "URDF limits", {}),
    ("b", "speed 0.3 rad/s", {"velocity_rad_s": (0.3, 0.3)}),
    ("c", "effort 0.05 N m", {"effort_n_m": (0.05, 0.05)}),
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python scripts/near_optimal_vs_toppra.py", description=__doc__.splitlines()[0]
    )
    parser.add_argument("--coefficients", default="results/coefficients.json", help="coefficients file, or 'paper'")
    parser.add_argument("--n", type=int, default=200, help="random obstacles per limit set [count] (default: 200)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the obstacles' numpy Generator (default: 0)")
    parser.add_argument(
        "--acceleration-limit",
        type=float,
        default=5.0,
        help="acceleration limit of both joints in every set [rad/s^2] (default: 5)",
    )
    parser.add_argument(
        "--jerk-limits",
        type=float,
        nargs="*",
        default=[50.0, 25.0],
        metavar="J",
        help="user-set jerk limits of both joints, one table each [rad/s^3] (default: 50 25)",
    )
    parser.add_argument(
        "--gridpoints", type=int, default=2000, help="TOPP-RA's uniform gridpoints per path [count] (default: 2000)"
    )
    parser.add_argument(
        "--oversample",
        type=int,
        default=100,
        help="TOPP-RA's motion is sampled at this many instants per gridpoint for its excess [count] (default: 100)",
    )
    parser.add_argument("--json", type=Path, metavar="FILE", default=None, help="write the results as JSON (atomic)")
    return parser


def _limit_sets(arm, acceleration: float, jerk_limits: list[float]) -> list[dict[str, Any]]:
    """Every (set, jerk limit) row: the default jerk first, then the user's, per set."""
    from pipeline.model.limits import ArmLimits

    base = ArmLimits.from_arm(arm, (acceleration, acceleration))
    rows = []
    for key, name, changes in LIMIT_SETS:
        limits = replace(base, **changes)
        default = limits.with_servo_defaults()
        rows.append({"set": key, "name": name, "jerk": "default", "limits": default})
        for jerk in jerk_limits:
            rows.append({"set": key, "name": name, "jerk": "user", "limits": replace(limits, jerk_rad_s3=(jerk, jerk))})
    return rows


def _limits_json(limits) -> dict[str, Any]:
    return {
        "velocity_rad_s": list(limits.velocity_rad_s),
        "acceleration_rad_s2": list(limits.acceleration_rad_s2),
        "effort_n_m": list(limits.effort_n_m),
        "jerk_rad_s3": list(limits.jerk_rad_s3),
    }


def _statistics(values: list[float]) -> dict[str, float | None]:
    if not values:
        return {"median": None, "max": None, "min": None}
    return {"median": float(np.median(values)), "max": float(np.max(values)), "min": float(np.min(values))}


def _format(value: float | None, digits: str = ".4f") -> str:
    return "-" if value is None or not math.isfinite(value) else format(value, digits)


def _format_excess(value: float | None) -> str:
    if value is None:
        return "-"
    return "0" if value == 0.0 else f"{100 * value:.3g} %"


def _map_ratios(coefficients, dynamics, limits, lengths, widths, peer, row) -> list[float]:
    """T'/T_TOPP-RA of the map's near-optimal timing, made for these limits: the cells holding the
    obstacles (:func:`pipeline.certify.cell_timings.near_optimal_cells`, only those cells),
    each obstacle's T' the T' of its cell, on the paths TOPP-RA timed (the regression's answers)."""
    from pipeline import generate
    from pipeline.certify.cell_timings import near_optimal_cells

    points = np.column_stack([lengths, widths])
    probe = near_optimal_cells(coefficients, dynamics, limits, only=np.array([], dtype=np.int64))
    index = probe.cells_of(points)
    cells = near_optimal_cells(coefficients, dynamics, limits, only=index[index >= 0])
    ratios = []
    for i, (length, width) in enumerate(points):
        known = peer.get((row["set"], i))
        if known is None or isinstance(known[1], str) or index[i] < 0:
            continue
        if known[0] != generate(coefficients, float(length), float(width)).trajectory:  # a repaired path
            continue
        duration = cells.table["duration_s"][index[i]]
        if math.isfinite(duration):
            ratios.append(float(duration / known[1].duration_s))
    return ratios


def run(args: argparse.Namespace, log=print) -> dict[str, Any]:
    """Every limit set and jerk limit on the same obstacles; the results as plain JSON."""
    from pipeline import NEAR_OPTIMAL, PipelineError, generate_certified, load_coefficients
    from pipeline.online.arm_check import arm_for
    from pipeline.online.execution import dynamics_of
    from verify.benchmark.toppra_peer import ToppraPeerError, ToppraSettings, toppra_timing, toppra_version

    started = time.perf_counter()
    coefficients = load_coefficients(args.coefficients)
    arm = arm_for(coefficients)
    dynamics = dynamics_of(arm)
    rng = np.random.default_rng(args.seed)
    (l_lo, l_hi), (w_lo, w_hi) = coefficients.fitted_range_m["L"], coefficients.fitted_range_m["W"]
    lengths, widths = rng.uniform(l_lo, l_hi, args.n), rng.uniform(w_lo, w_hi, args.n)
    settings = ToppraSettings(gridpoints=args.gridpoints, oversample=args.oversample)
    peer: dict[tuple[str, int], Any] = {}  # (set, obstacle) -> (trajectory, ToppraResult or the failure)
    rows = []
    for row in _limit_sets(arm, args.acceleration_limit, args.jerk_limits):
        limits = row["limits"]
        ratios: list[float] = []
        refusals: dict[str, int] = {}
        examples: dict[str, str] = {}
        failures: list[str] = []
        t_ours: list[float] = []
        for i, (length, width) in enumerate(zip(lengths, widths, strict=True)):
            try:
                answer = generate_certified(
                    coefficients, float(length), float(width), arm, timing=NEAR_OPTIMAL, limits=limits
                )
            except PipelineError as exc:
                refusals[type(exc).__name__] = refusals.get(type(exc).__name__, 0) + 1
                examples.setdefault(type(exc).__name__, f"L = {length:.4f} m, W = {width:.4f} m: {exc}")
                continue
            t_ours.append(answer.duration_s)
            known = peer.get((row["set"], i))
            if known is None or known[0] != answer.trajectory:  # TOPP-RA ignores the jerk limit: once per path
                try:
                    result: Any = toppra_timing(answer.trajectory, answer.execution.limits, dynamics, settings)
                except ToppraPeerError as exc:
                    result = exc.reason
                known = peer[(row["set"], i)] = (answer.trajectory, result)
            if isinstance(known[1], str):
                failures.append(known[1])
            else:
                ratios.append(answer.duration_s / known[1].duration_s)
        map_ratios = (
            _map_ratios(coefficients, dynamics, limits, lengths, widths, peer, row) if row["jerk"] == "default" else []
        )
        results = [r for (key, _), (_, r) in peer.items() if key == row["set"] and not isinstance(r, str)]
        excess = {
            name: (max(r.excess[k] for r in results) if results else None)
            for k, name in enumerate(("speed", "acceleration", "torque"))
        }
        rows.append(
            {
                "set": row["set"],
                "name": row["name"],
                "jerk": row["jerk"],
                "limits": _limits_json(limits),
                "obstacles": args.n,
                "paths": len(ratios),
                "refusals": refusals,
                "refusal_examples": examples,
                "toppra_failures": failures,
                "ratio": _statistics(ratios),
                "ratios": ratios,
                "map_ratio": _statistics(map_ratios),
                "map_paths": len(map_ratios),
                "t_prime_s": _statistics(t_ours),
                "toppra_excess_max": excess,
            }
        )
        log(
            f"  ({row['set']}) {row['name']}, jerk {limits.jerk_rad_s3[0]:g} rad/s^3: {len(ratios)} paths, "
            f"{time.perf_counter() - started:.0f} s"
        )
    return {
        "command": "python scripts/near_optimal_vs_toppra.py " + " ".join(args.argv),
        "coefficients": args.coefficients,
        "n": args.n,
        "seed": args.seed,
        "obstacles_m": [[float(length), float(width)] for length, width in zip(lengths, widths, strict=True)],
        "acceleration_limit_rad_s2": args.acceleration_limit,
        "jerk_limits_rad_s3": list(args.jerk_limits),
        "toppra": {"version": toppra_version(), "gridpoints": args.gridpoints, "oversample": args.oversample},
        "rows": rows,
        "elapsed_s": time.perf_counter() - started,
    }


def format_tables(data: dict[str, Any]) -> str:
    """The printed tables: the default jerk limit, then each user-set jerk limit."""
    lines = [
        f"$ {data['command']}",
        f"{data['n']} random obstacles (seed {data['seed']}) of {data['coefficients']}; acceleration limit "
        f"{data['acceleration_limit_rad_s2']:g} rad/s^2 per joint in every set; TOPP-RA (toppra "
        f"{data['toppra']['version']}) at {data['toppra']['gridpoints']} gridpoints, at rest at both ends, torque from "
        "the closed form.",
    ]
    ratio = "T'/T_TOPP-RA median"
    header = (
        f"{'limit set':<36} {'jerk limit':>16} {'paths':>6} {ratio:>19} {'max':>8} {'refused':>8}"
        f" {'from the map: paths':>20} {'median':>8} {'max':>8}"
    )
    tables = [("the default jerk limit (acceleration / 50 ms)", "default")]
    tables += [(f"a user-set jerk limit of {j:g} rad/s^3", j) for j in data["jerk_limits_rad_s3"]]
    for title, which in tables:
        lines += ["", f"T'/T_TOPP-RA with {title}:", header, "-" * len(header)]
        for row in data["rows"]:
            jerk = row["limits"]["jerk_rad_s3"][0]
            if (which == "default") != (row["jerk"] == "default") or (which != "default" and jerk != which):
                continue
            label = f"({row['set']}) {row['name']} + {row['limits']['acceleration_rad_s2'][0]:g} rad/s^2"
            lines.append(
                f"{label:<36} {f'{jerk:g} rad/s^3':>16} {row['paths']:>6} {_format(row['ratio']['median']):>19} "
                f"{_format(row['ratio']['max']):>8} {sum(row['refusals'].values()):>8}"
                + (
                    f" {row['map_paths']:>20} {_format(row['map_ratio']['median']):>8} "
                    f"{_format(row['map_ratio']['max']):>8}"
                    if row["jerk"] == "default"
                    else ""
                )
            )
    refused = [row for row in data["rows"] if row["refusals"] or row["toppra_failures"]]
    if refused:
        lines += ["", "Not timed (ours refused or raised, or TOPP-RA failed), the first of each kind:"]
    for row in refused:
        where = f"  ({row['set']}) {row['name']}, jerk {row['limits']['jerk_rad_s3'][0]:g} rad/s^3"
        for name, count in row["refusals"].items():
            lines.append(f"{where}: {count} x {name}, e.g. {row['refusal_examples'][name]}")
        if row["toppra_failures"]:
            lines.append(f"{where}: TOPP-RA failed {len(row['toppra_failures'])} x, e.g. {row['toppra_failures'][0]}")
    lines += [
        "",
        f"TOPP-RA's own largest relative excess over a limit (its motion sampled at {data['toppra']['oversample']}x "
        f"its {data['toppra']['gridpoints']} gridpoints; ours is certified: 0):",
    ]
    for row in data["rows"]:
        if row["jerk"] == "default":
            excess = row["toppra_excess_max"]
            lines.append(
                f"  ({row['set']}) {row['name']}: "
                + ", ".join(f"{name} {_format_excess(value)}" for name, value in excess.items())
            )
    lines.append(f"Wall time: {data['elapsed_s']:.0f} s.")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    args.argv = argv
    for name, value in (("--n", args.n), ("--gridpoints", args.gridpoints), ("--oversample", args.oversample)):
        if value < (2 if name == "--gridpoints" else 1):
            parser.error(f"{name} {value}: too small")
    if not (math.isfinite(args.acceleration_limit) and args.acceleration_limit > 0.0):
        parser.error(f"--acceleration-limit {args.acceleration_limit}: a positive finite limit [rad/s^2]")
    if any(not (math.isfinite(j) and j > 0.0) for j in args.jerk_limits):
        parser.error(f"--jerk-limits {args.jerk_limits}: positive finite limits [rad/s^3]")

    from pipeline import PipelineError
    from pipeline.io.jsonio import write_json_atomic
    from pipeline.io.output_paths import check_output_file

    try:
        check_output_file(args.json, "--json")
        data = run(args, log=lambda message: print(message, file=sys.stderr, flush=True))
    except PipelineError as error:
        print(f"near_optimal_vs_toppra: {error}", file=sys.stderr)
        return 2
    print(format_tables(data))
    if args.json is not None:
        write_json_atomic(args.json, data)
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
