"""The sweep's human-readable report: the summary a person reads on stdout, and the side-by-side
comparison of two coefficients sets (``python -m verify.sweep --compare A B``)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

from .range_check import BoundCheck, ExecutionCheck, RangeCheck
from .results import JOINT_QUANTITIES, CaseResult, Pair

if TYPE_CHECKING:  # pragma: no cover
    from .cases import SweepRange
    from .run import SweepRun
    from .summary import SweepSummary


def _mm(value: float | None, digits: int = 3) -> str:
    return "n/a" if value is None else f"{value * 1e3:.{digits}f} mm"


def _samples(bounds: tuple[int, int] | None) -> str:
    return "None..None" if bounds is None else f"{bounds[0]}..{bounds[1]}"


def _case_line(case: CaseResult) -> str:
    head = f"#{case.index:<4d} L = {case.L_m:.4f} m, W = {case.W_m:.4f} m"
    head += "".join(f", {name} = {value:.4f} m" for name, value in case.extra)
    if case.extrapolated:
        head += " (extrapolated)"
    if case.error is not None:
        return f"{head}: {case.error}"
    detail = (
        f"certified {_mm(case.certified_clearance_m)}, sampled {_mm(case.clearance_m)}, "
        f"endpoint {_mm(case.endpoint_error_m)}, tracking max {_mm(case.tracking_max_m, 2)}"
    )
    if case.failures:
        detail += " -- " + "; ".join(case.failures)
    return f"{head}: {detail}"


def _ranges(box: SweepRange) -> list[tuple[str, tuple[float, float]]]:
    """(name, (lo, hi)) of every variable of ``box`` [m]."""
    return list(zip(box.names, box.ranges_m, strict=True))


def _over(run: SweepRun) -> str:
    """ " over (L, W, x)" for a sweep over more variables than (L, W); empty for (L, W)."""
    names = run.sweep_range.names
    return f" over ({', '.join(names)})" if len(names) > 2 else ""


def _summary_rows(run: SweepRun) -> list[tuple[str, str]]:
    """The summary's (label, text) rows: what was swept, the verdicts, the joints, the sampling, the
    region map's check, the speed and the errors."""
    s = run.summary
    n = s.n_cases
    rows = _swept_rows(run) + _verdict_rows(run)
    if s.peak_velocity_max_rad_s is not None and s.peak_acceleration_max_rad_s2 is not None:
        measured = n - s.n_errors
        rows.append(_joints_row(s, measured))
        rows += _rest_to_rest_rows(s, measured)
    rows.append(_sampling_row(run))
    if run.range_check is not None:
        rows += _map_rows(run.range_check)
    rate = n / run.elapsed_s if run.elapsed_s > 0 else float("inf")
    rows.append(("speed", f"{run.elapsed_s:.1f} s, {rate:.1f} cases/s with {run.jobs} job(s)"))
    if s.n_errors:
        rows.append(("errors", f"{s.n_errors} cases could not be generated"))
    return rows


def _swept_rows(run: SweepRun) -> list[tuple[str, str]]:
    """The coefficients, the cases and range swept, and how many lie outside the fitted range."""
    s = run.summary
    n = s.n_cases
    return [
        (
            "coefficients",
            f"{run.source} (family {run.provenance['coefficients']['family']}, "
            f"sha256 {str(run.provenance['coefficients']['sha256'])[:12]})",
        ),
        (
            "cases",
            f"{n}{_over(run)}, {run.sweep_range.describe()}"
            + (" (the fitted range)" if not run.extrapolating else " (EXTRAPOLATION beyond the fitted range)"),
        ),
        (
            "extrapolated",
            f"{s.n_extrapolated} / {n} cases outside the fitted range "
            + ", ".join(f"{name} [{lo:.4f}, {hi:.4f}] m" for name, (lo, hi) in _ranges(run.fitted_range)),
        ),
    ]


def _verdict_rows(run: SweepRun) -> list[tuple[str, str]]:
    """The cases passed, collision-free and keeping the margin; clearance, endpoint and tracking errors."""
    s = run.summary
    t = run.settings.thresholds
    n = s.n_cases
    return [
        ("PASSED", f"{s.n_passed} / {n} ({100.0 * (s.pass_rate or 0.0):.1f} %)"),
        (
            "collision-free",
            f"certified {s.n_certified_collision_free} / {n}; keep the "
            f"{t.margin_m * 1e3:.1f} mm margin {s.n_keep_margin} / {n} "
            f"({100.0 * (s.keep_margin_fraction or 0.0):.1f} %)",
        ),
        (
            "clearance",
            f"certified min {_mm(s.certified_clearance.min)}, median "
            f"{_mm(s.certified_clearance.median)}; sampled min {_mm(s.sampled_clearance.min)}, median "
            f"{_mm(s.sampled_clearance.median)}"
            + (
                " (decide mode: a bound is tight only where the margin is not kept)"
                if run.settings.certify and run.settings.certificate_mode == "decide"
                else ""
            ),
        ),
        (
            "endpoint error",
            f"median {_mm(s.endpoint_error.median)}, p99 {_mm(s.endpoint_error.p99)}, "
            f"max {_mm(s.endpoint_error.max)} (limit {_mm(t.max_endpoint_error_m, 1)})",
        ),
        (
            "tracking error",
            f"max {_mm(s.tracking_max.max, 2)}, median of max {_mm(s.tracking_max.median, 2)}, "
            f"RMS median {_mm(s.tracking_rms.median, 2)}",
        ),
    ]


def _joints_row(s: SweepSummary, measured: int) -> tuple[str, str]:
    """The joints' speed and acceleration peaks, the certified torque bound (paper timing) and the
    cases within the URDF's limits, of the ``measured`` cases."""
    return (
        "joints",
        "speed peak ({:.3f}, {:.3f}) rad/s, acceleration peak ({:.3f}, {:.3f}) rad/s^2, "
        "certified torque bound ({:.4f}, {:.4f}) N m (paper timing); {} / {} within the URDF limits".format(
            *s.peak_velocity_max_rad_s,
            *s.peak_acceleration_max_rad_s2,
            *(s.torque_bound_max_n_m or (float("nan"), float("nan"))),
            s.n_within_joint_limits,
            measured,
        ),
    )


def _sampling_row(run: SweepRun) -> tuple[str, str]:
    """The clearance samples per case, the certificate's mode and tolerance, and its evaluations."""
    s = run.summary
    return (
        "sampling",
        f"{_samples(s.time_samples_range)} clearance samples per case"
        + (
            " (the certificate's)"
            if run.settings.certify
            else f" ({run.settings.resolution_m * 1e3:g} mm motion resolution)"
            if run.settings.time_samples is None
            else " (fixed by --samples)"
        )
        + f", certificate {run.settings.certificate_mode}, tolerance "
        f"{run.settings.tolerance_m * 1e3:g} mm, {s.certificate_evaluations_total} clearance evaluations"
        + (f", {s.n_certificate_not_converged} not converged" if s.n_certificate_not_converged else ""),
    )


def _room_text(room: dict[str, Pair | None]) -> str:
    """The least room of one timing: the limited quantities, per joint, in their units."""
    parts = [
        f"{name} ({pair[0]:.4g}, {pair[1]:.4g}) {unit}"
        for name, unit in JOINT_QUANTITIES
        if (pair := room[name]) is not None and not all(math.isinf(v) for v in pair)
    ]
    return ", ".join(parts) or "n/a"


def _rest_to_rest_rows(s: SweepSummary, measured: int) -> list[tuple[str, str]]:
    """The rest-to-rest timing's verdict and T' / T, and both timings' least room to the limits."""
    room = s.least_room
    unlimited = [
        name
        for name, _ in JOINT_QUANTITIES
        if all(r[name] is None or all(math.isinf(v) for v in r[name]) for r in room.values())
    ]
    ratio = "n/a" if s.rest_to_rest_ratio_max is None else f"{s.rest_to_rest_ratio_max:.4f}"
    return [
        (
            "rest-to-rest",
            f"{s.n_rest_to_rest_passed} / {measured} certified within the limits over [0, T'] "
            f"(bounds >= samples, at rest at both ends); T'/T max {ratio}",
        ),
        (
            "least room",
            f"limit - bound, paper: {_room_text(room['paper'])}; rest-to-rest: {_room_text(room['rest_to_rest'])}"
            + (f" ({', '.join(unlimited)} unlimited)" if unlimited else ""),
        ),
    ]


def _bound_text(check: BoundCheck | None, what: str) -> str:
    if check is None or check.checked == 0:
        return f"{what}: none checked"
    worst = "n/a" if check.worst_slack_m is None else f"{check.worst_slack_m * 1e3:.4f} mm"
    return (
        f"{what}: {len(check.violations)} violation(s) of {check.checked}, worst slack {worst} "
        f"(allowed {check.allowed_slack_m * 1e3:.4g} mm)"
    )


def _map_rows(check: RangeCheck) -> list[tuple[str, str]]:
    """The region map's claims and the cross-check, as summary rows."""
    m = check.map
    fractions = ", ".join(f"{name} {100 * value:.2f} %" for name, value in m.area_fraction.items())
    where = m.path or "given in memory"
    if not m.belongs:
        return [
            (
                "region map",
                f"{where} does NOT belong to these coefficients (made for sha256 {m.coefficients_sha256[:12]}); "
                "not used for the cross-check",
            )
        ]
    rows = [
        ("region map", f"{where} ({m.cells} cells, belongs to these coefficients): {fractions} of the area"),
        (
            "map bounds",
            f"clearance bound min {_mm(m.clearance_bound_min_m)} in the cell L [{m.worst_cell_L_m[0]:.4f}, "
            f"{m.worst_cell_L_m[1]:.4f}] m, W [{m.worst_cell_W_m[0]:.4f}, {m.worst_cell_W_m[1]:.4f}] m"
            + "".join(f", {name} [{lo:.4f}, {hi:.4f}] m" for name, (lo, hi) in m.worst_cell_extra_m)
            + "; "
            f"endpoint bound max {_mm(m.endpoint_bound_max_m)} (tolerance {_mm(m.endpoint_tolerance_m)})",
        ),
    ]
    skipped = f"{check.n_out_of_range} out of the map's range, {check.n_not_measured} not generated"
    if check.n_certificate_decided:
        skipped += f"; {check.n_certificate_decided} certificates only decided the margin: sampled check only"
    if check.n_certificate_unconverged:
        skipped += f"; {check.n_certificate_unconverged} certificates not converged"
    verdict = "PASS" if check.passed else f"FAIL ({len(check.violations)} case(s) contradict the map)"
    rows += [
        ("map check", f"{verdict}: {check.n_cases} cases ({skipped})"),
        ("  clearance", _bound_text(check.certified, "certified >= map bound")),
        ("  sampled", _bound_text(check.sampled, "sampled (Coal) >= map bound")),
        ("  endpoints", _bound_text(check.endpoint, "endpoint error <= map bound")),
    ]
    if check.execution is not None:
        rows.append(("  execution", _execution_text(check.execution)))
    return rows


def _execution_text(check: ExecutionCheck) -> str:
    units = {"angle": "rad", "speed": "rad/s", "acceleration": "rad/s^2", "torque": "N m"}
    worst = ", ".join(
        f"{name} {value:.4g} {units[name]}" if value is not None else f"{name} not compared"
        for name, value in check.worst_slack.items()
    )
    verdict = "ok" if not check.violations else f"{len(check.violations)} VIOLATION(S)"
    return f"{verdict}: joints of {check.checked} cases within the map's bounds (paper timing); least room: {worst}"


def _map_violation_lines(run: SweepRun, list_failures: int | None) -> list[str]:
    check = run.range_check
    if check is None or check.passed:
        return []
    by_index = {c.index: c for c in run.cases}
    violations = check.violations if list_failures is None else check.violations[:list_failures]
    lines = [f"REGION MAP CONTRADICTED by {len(check.violations)} case(s):"]
    region_map = check.region_map
    for index in violations:
        case = by_index[index]
        cell = "" if region_map is None else _cell_text(region_map.bounds_at(*case.point))
        lines.append("  " + _case_line(case) + cell)
    if len(violations) < len(check.violations):
        lines.append(f"  ... and {len(check.violations) - len(violations)} more (all are in --json)")
    return lines


def _cell_text(bounds: tuple[float, float, str] | None) -> str:
    if bounds is None:
        return ""
    return f" -- map: clearance >= {_mm(bounds[0])}, endpoint <= {_mm(bounds[1])} ({bounds[2]})"


def format_summary(run: SweepRun, list_failures: int | None = None) -> str:
    """The human summary printed on stdout."""
    lines = [f"== verify.sweep: {run.label} =="]
    rows = _summary_rows(run)
    width = max(len(k) for k, _ in rows)
    lines += [f"{k:<{width}}  {v}" for k, v in rows]
    lines.append("worst clearance:")
    lines += ["  " + _case_line(c) for c in run.summary.worst_clearance]
    lines.append("worst endpoint error:")
    lines += ["  " + _case_line(c) for c in run.summary.worst_endpoint_error]
    if run.case_studies:
        lines.append("case studies (inside the fitted range, off the DOE grid):")
        lines += ["  " + _case_line(c).replace(f"#{c.index:<4d}", f"case {c.index + 1}") for c in run.case_studies]
    failing = run.summary.failing
    if failing:
        shown = failing if list_failures is None else failing[:list_failures]
        lines.append(f"FAILED: {len(failing)} case(s):")
        lines += ["  " + _case_line(c) for c in shown]
        if len(shown) < len(failing):
            lines.append(f"  ... and {len(failing) - len(shown)} more (all are in --json)")
    map_lines = _map_violation_lines(run, list_failures)
    lines += map_lines
    if failing or map_lines:
        lines.append("verdict: FAIL" + (" (the region map is contradicted)" if map_lines else ""))
    else:
        lines.append(
            "verdict: PASS (every case passed"
            + (", the region map holds)" if run.range_check is not None and run.range_check.checked else ")")
        )
    return "\n".join(lines)


def format_comparison(runs: Sequence[SweepRun]) -> str:
    """The runs' summaries side by side (same cases)."""
    tables = [dict(_summary_rows(run)) for run in runs]
    keys = list(dict.fromkeys(k for table in tables for k in table))  # every run's rows, in order
    width = max(len(k) for k in keys)
    column = max(44, *(len(run.label) for run in runs))
    lines = [
        f"== verify.sweep: comparison on the same {runs[0].summary.n_cases} cases ==",
        f"{'':<{width}}  " + " | ".join(f"{run.label:<{column}}" for run in runs),
    ]
    for key in keys:
        cells = [table.get(key, "") for table in tables]
        wrapped = [_wrap(cell, column) for cell in cells]
        height = max(len(w) for w in wrapped)
        for row in range(height):
            name = key if row == 0 else ""
            lines.append(
                f"{name:<{width}}  " + " | ".join(f"{(w[row] if row < len(w) else ''):<{column}}" for w in wrapped)
            )
    if len(runs) == 2 and len(runs[0].cases) == len(runs[1].cases):
        a, b = runs
        only_a = sum(x.passed and not y.passed for x, y in zip(a.cases, b.cases, strict=True))
        only_b = sum(y.passed and not x.passed for x, y in zip(a.cases, b.cases, strict=True))
        lines.append(f"cases passing only with {a.label}: {only_a}; only with {b.label}: {only_b}")
    verdicts = ", ".join(f"{run.label}: {'PASS' if run.passed else 'FAIL'}" for run in runs)
    lines.append(f"verdicts: {verdicts}")
    return "\n".join(lines)


def _wrap(text: str, width: int) -> list[str]:
    words, lines, current = text.split(" "), [], ""
    for word in words:
        if current and len(current) + 1 + len(word) > width:
            lines.append(current)
            current = word
        else:
            current = f"{current} {word}" if current else word
    lines.append(current)
    return lines
