"""The benchmark's printed table: medians per query, ratios to the generator alone (a) and to the
generator with certification (b), the ratios of OMPL (d) to (a), (a*) and (b) (and, over (L, W, x),
of OMPL on the moved obstacles to (a*) on them), and the fraction of answers certified collision-free."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from pipeline.build.run import stage_summary

if TYPE_CHECKING:  # pragma: no cover
    from .results import BenchReport

#: How a skipped row is named where its key is not its name (the rows over (L, W, x)).
_SKIPPED_NAMES = {
    "a_range_x": "(a*) over (L, W, x)",
    "d_x": "(d) over (L, W, x)",
    "n_opt": "(n*) and (tp) toppra",
    "toppra": "(tp) toppra",
}


def _format_time(seconds: float) -> str:
    if not math.isfinite(seconds):
        return "-"
    if seconds < 1e-3:
        return f"{seconds * 1e6:.3g} us"
    if seconds < 1.0:
        return f"{seconds * 1e3:.3g} ms"
    return f"{seconds:.3g} s"


def _format_ratio(ratio: float | None) -> str:
    if ratio is None or not math.isfinite(ratio):
        return "-"
    if ratio >= 100:
        return f"{ratio:,.0f}x"
    return f"{ratio:.3g}x"


def _format_fraction(fraction: float) -> str:
    return "-" if not math.isfinite(fraction) else f"{100 * fraction:.0f}%"


def format_report(report: BenchReport) -> str:
    """The table and notes printed on stdout."""
    lines = (
        _header_lines(report) + _table_lines(report) + _ratio_lines(report) + _rate_lines(report) + _note_lines(report)
    )
    lines.append(f"Total benchmark wall time: {report.elapsed_s:.1f} s.")
    return "\n".join(lines)


def _header_lines(report: BenchReport) -> list[str]:
    fitted = report.coefficients["fitted_range_m"]
    machine = report.machine
    versions = machine["versions"]
    lines = [
        f"$ {report.command}",
        f"Benchmark of coefficients '{report.coefficients['source']}' (family {report.coefficients['family']}) "
        f"on {len(report.cases_m)} random obstacles (seed {report.settings['seed']}), "
        f"L in [{fitted['L'][0]:.3f}, {fitted['L'][1]:.3f}] m, W in [{fitted['W'][0]:.3f}, {fitted['W'][1]:.3f}] m; "
        f"margin {report.margin_m * 1e3:.0f} mm.",
        f"Machine: {machine['platform']}, {machine['usable_cpus']} usable CPU(s), load average "
        f"{machine['load_average_1_5_15_min']} at the start; Python {versions['python']}, "
        f"numpy {versions['numpy']}, pin {versions['pin']}, coal {versions['coal']}, ompl {versions['ompl']}.",
        "",
    ]
    return lines


def _table_lines(report: BenchReport) -> list[str]:
    a, b = report.method("a"), report.method("b")
    reference_a = a.median_s if a else float("nan")
    reference_b = b.median_s if b else None
    header = (
        f"{'method':<44} {'obst.':>5} {'runs':>6} {'median/query':>12} {'vs (a)':>9} {'vs (b)':>9} "
        f"{'answered':>8} {'cert. free':>10} {'keeps margin':>12}"
    )
    lines = [header, "-" * len(header)]
    for m in report.methods:
        ratio_b = None if reference_b is None else m.median_s / reference_b
        lines.append(
            f"{m.label:<44} {m.obstacles:>5} {len(m.times_s):>6} {_format_time(m.median_s):>12} "
            f"{_format_ratio(m.median_s / reference_a):>9} {_format_ratio(ratio_b):>9} "
            f"{_format_fraction(m.answered_fraction):>8} {_format_fraction(m.certified_fraction):>10} "
            f"{_format_fraction(m.keeps_margin_fraction):>12}"
        )
    for key, reason in report.skipped.items():
        lines.append(f"{_SKIPPED_NAMES.get(key, f'({key})')} skipped: {reason}")
    lines.append("")
    return lines


def _pose_axes(report: BenchReport) -> str:
    """The variables of the rows over the obstacle's pose, as "(L, W, x)" or "(L, W, x, d)"."""
    names = ("L", "W", "x") if report.over_x is None else tuple(report.over_x["fitted_range_m"])
    return f"({', '.join(names)})"


def _ratio_lines(report: BenchReport) -> list[str]:
    """The ratios of medians per query, measured side by side in this run, and the (a*) line: its median
    per query, its batched time per obstacle, and the fractions of in-range queries it certifies."""
    ratios = report.ratios()
    names = (("d_over_a", "(d) / (a)"), ("d_over_a_range", "(d) / (a*)"), ("d_over_b", "(d) / (b)"))
    shown = [f"{text} = {_format_ratio(ratios[key])}" for key, text in names if ratios[key] is not None]
    if ratios["b_over_a_range"] is not None:
        shown.append(f"(b) / (a*) = {_format_ratio(ratios['b_over_a_range'])}")
    if ratios.get("d_x_over_a_range_x") is not None:
        shown.append(f"over {_pose_axes(report)}: (d) / (a*) = {_format_ratio(ratios['d_x_over_a_range_x'])}")
    if ratios.get("n_opt_over_toppra") is not None:
        shown.append(f"(n*) / (tp) = {_format_ratio(ratios['n_opt_over_toppra'])}")
    lines = [f"Ratios of the medians per query (this run): {', '.join(shown)}."] if shown else []
    summary = report.a_range_summary()
    if summary is not None:
        batched = summary["batched_us_per_obstacle"]
        certified = _format_fraction(_nan(summary["certified_fraction"]))
        margin = _format_fraction(_nan(summary["margin_fraction"]))
        lines.append(
            f"(a*) range certificate: median {summary['median_us']:.3g} us per query, "
            + (f"{batched:.3g} us per obstacle batched, " if batched is not None else "")
            + f"certified clearance > 0 on {certified} and >= the margin on {margin} of "
            f"{summary['in_range_queries']} in-range queries."
        )
    summary_x = report.a_range_x_summary()
    if summary_x is not None:
        certified = _format_fraction(_nan(summary_x["certified_fraction"]))
        margin = _format_fraction(_nan(summary_x["margin_fraction"]))
        lines.append(
            f"(a*) over {_pose_axes(report)}: median {summary_x['median_us']:.3g} us per query, certified "
            "clearance > 0 on "
            f"{certified} and >= the margin on {margin} of {summary_x['in_range_queries']} in-range queries."
        )
    lines += _near_optimal_lines(report)
    return lines + [""] if lines else lines


def _format_excess(excess: dict[str, float | None]) -> str:
    """``speed 0, acceleration 0.012 %, ...``: relative excesses as percentages (0 where none)."""
    return ", ".join(
        f"{name} {'-' if value is None else ('0' if value == 0.0 else f'{100 * value:.3g} %')}"
        for name, value in excess.items()
    )


def _near_optimal_lines(report: BenchReport) -> list[str]:
    """The (n*) against TOPP-RA lines: T'/T_TOPP-RA over the same paths and limits, and each
    method's largest sampled excess over a limit."""
    summary = report.near_optimal
    if summary is None:
        return []
    lines = []
    if summary["paths"]:
        lines.append(
            f"(n*) near-optimal vs (tp) toppra ({summary['toppra_gridpoints']} grid points), same paths and limits: "
            f"T'/T_TOPP-RA median {summary['duration_ratio_median']:.4f}, max {summary['duration_ratio_max']:.4f} "
            f"(min {summary['duration_ratio_min']:.4f}) over {summary['paths']} paths."
        )
    if summary.get("map_over_toppra"):
        median, largest = summary["map_over_toppra"]
        lines.append(
            f"(n*m) near-optimal from the map vs (tp), same paths and limits: T'/T_TOPP-RA median {median:.4f}, "
            f"max {largest:.4f}."
        )
    lines.append(
        f"Largest relative excess over a limit, sampled at {summary['oversample']}x the grid: (n*) at "
        f"{summary['ours_samples_per_breakpoint']}x the breakpoints of its timing: "
        f"{_format_excess(summary['ours_excess_max'])}"
        + (
            f"; (tp) at {summary['toppra_samples_per_gridpoint']}x its grid points: "
            f"{_format_excess(summary['toppra_excess_max'])}."
            if summary["paths"]
            else "."
        )
    )
    return lines


def _nan(value: float | None) -> float:
    return math.nan if value is None else value


def _rate_lines(report: BenchReport) -> list[str]:
    lines = []
    if report.sweep is not None:
        without, with_ = report.sweep["without_certificate"], report.sweep["with_certificate"]
        lines.append(
            f"Sweep rate (verify.acceptance.run.run_cases, {report.sweep['n_cases']} cases, 1 process): "
            f"{without['cases_per_s']:.1f} cases/s without the certificate, "
            f"{with_['cases_per_s']:.1f} cases/s with it."
        )
    build = report.build
    if build is not None:
        for key in ("file", "reduced"):
            info = build.get(key)
            if info is None:
                continue
            seconds = info["experiment_seconds"]
            spread = (
                f" (per experiment: median {info['experiment_median_s']:.1f} s, "
                f"min {min(seconds):.1f} s, max {max(seconds):.1f} s)"
                if seconds
                else ""
            )
            stages = stage_summary(info) if info.get("stages_s") else ""
            older = ", an older file: no writing stage" if info.get("older_format") else ""
            lines.append(
                f"Build time ({info['source']}{older}): {info['total_s']:.1f} s wall in all"
                + (f" ({stages})" if stages else "")
                + f" for {info['experiments']} experiments{spread}, jobs {info['jobs']}; "
                f"{info['coal_queries']:,} Coal distance queries."
            )
        if build.get("missing"):
            lines.append(f"Build time: {build['missing']}.")
    return lines


def _note_lines(report: BenchReport) -> list[str]:
    lines = ["", "Notes:"]
    for m in report.methods:
        lines.append(f"  {m.label.split(':')[0] if ':' in m.label else m.label.split()[0]} {m.note}")
    d = report.method("d")
    if d is not None:
        x = d.extra
        lines.append(
            f"  (d) valid state: {x['validity']}"
            + (" (the same margin as ours)" if x["validity_margin_m"] == report.margin_m else "")
            + f", checked along motions every "
            f"{x['validity_resolution']} of the joint-space extent ({x['validity_resolution_rad']:.3f} rad); "
            f"time limit {x['time_limit_s']} s. Unanswered: {x['planner_failures']} of {d.queries} queries "
            f"(start configuration within the margin: {x['failure_reasons']['start_invalid']}, goal configuration "
            f"within the margin: {x['failure_reasons']['goal_invalid']}, no path in time: "
            f"{x['failure_reasons']['not_solved']}); median over the answered queries only: "
            f"{_format_time(x['median_answered_s'] if x['median_answered_s'] is not None else math.nan)}. "
            "Its path joins the start and goal configurations "
            "(IK of P1 and P5); it does not track the desired path."
        )
    if report.range_map is not None:
        lines.append(f"  (a*) region map: {report.range_map['description']}.")
    if report.over_x is not None:
        info = report.over_x
        box = ", ".join(f"{name} in [{lo:.3f}, {hi:.3f}] m" for name, (lo, hi) in info["fitted_range_m"].items())
        region = info["region_map"]
        lines.append(
            f"  (a*) over {_pose_axes(report)}: coefficients {info['source']} ({box}); region map {region['path']} "
            f"({region['cells']:,} cells, certified collision-free on "
            f"{100 * region['certified_collision_free_fraction']:.2f} % of the box); (d) over {_pose_axes(report)} "
            "plans around the answer's obstacle, moved as the query asks."
        )
    lines += [
        "  vs (a), vs (b): median time per query divided by that of (a) and of (b).",
        "  answered: queries that returned a trajectory or path; cert. free: answers whose certified clearance "
        "(rigorous lower bound over the whole continuous motion, Pinocchio + Coal) is > 0; keeps margin: >= "
        f"{report.margin_m * 1e3:.0f} mm.",
        "  These are ratios measured in one run on this machine, not absolute claims.",
    ]
    return lines
