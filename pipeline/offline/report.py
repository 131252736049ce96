"""Text tables the CLIs print: our Table 2 and Eq. 9 beside the paper's, and how the regression was fitted."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from pipeline.motion.trajectory import PARAMETER_NAMES
from pipeline.offline.regression import BASIS


def table2(rows: Sequence[Mapping], paper_rows: Sequence[Mapping] | None, extra_names: Sequence[str] = ()) -> str:
    """Our Table 2 (one line per experiment), with the paper's row below each when given;
    ``extra_names``: the DOE's variables beyond L and W (e.g. ("x",)), a column each [m]."""
    header = f"{'Test':>4} {'src':>5} " + " ".join(f"{n:>7}" for n in PARAMETER_NAMES) + f" {'L':>5} {'W':>5}"
    header += "".join(f" {name:>6}" for name in extra_names)
    extra = f" {'fitness':>9} {'clear_mm':>8} {'end0_mm':>7} {'endT_mm':>7}"
    lines = [header + extra]
    for i, row in enumerate(rows):
        values = " ".join(f"{row['parameters'][n]:7.3f}" for n in PARAMETER_NAMES)
        moved = "".join(f" {row[name]:6.3f}" for name in extra_names)
        lines.append(
            f"{i + 1:>4} {'ours':>5} {values} {row['L']:5.3f} {row['W']:5.3f}{moved} {row['fitness']:9.3e} "
            f"{row['clearance_m'] * 1e3:8.2f} {row['endpoint_error_start_m'] * 1e3:7.2f} "
            f"{row['endpoint_error_end_m'] * 1e3:7.2f}"
        )
        if paper_rows is not None:
            paper = paper_rows[i]
            values = " ".join(f"{paper['parameters'][n]:7.3f}" for n in PARAMETER_NAMES)
            fitness = paper.get("fitness")
            tail = ""
            if fitness is not None:
                tail = (
                    f" {fitness:9.3e} {paper['clearance_m'] * 1e3:8.2f} "
                    f"{paper['endpoint_error_start_m'] * 1e3:7.2f} {paper['endpoint_error_end_m'] * 1e3:7.2f}"
                )
            lines.append(f"{'':>4} {'paper':>5} {values} {paper['L']:5.3f} {paper['W']:5.3f}{tail}")
    return "\n".join(lines)


def equation9(
    ours: Mapping[str, Sequence[float]],
    paper: Mapping[str, Sequence[float]] | None,
    quality: Mapping | None = None,
    basis: Sequence[str] = BASIS,
) -> str:
    """Our Eq. 9 coefficients beside the paper's, with R^2 and LOO RMSE per parameter (n/a where
    the design leaves too few runs for it); ``basis``: the names of the coefficients' terms
    (``Variables.basis``; the paper's six by default)."""
    header = f"{'param':>7} {'src':>5} " + " ".join(f"{b:>9}" for b in basis)
    if quality:
        header += f" {'R^2':>7} {'LOO_rmse':>9}"
    lines = [header]
    for name, values in ours.items():
        line = f"{name:>7} {'ours':>5} " + " ".join(f"{v:9.4g}" for v in values)
        if quality:
            r2, loo = quality["r_squared"][name], quality["loo_rmse"][name]
            known = loo is not None and np.isfinite(loo)
            line += f" {r2:7.4f} {loo:9.2e}" if known else f" {r2:7.4f} {'n/a':>9}"
        lines.append(line)
        if paper is not None and name in paper:
            lines.append(f"{'':>7} {'paper':>5} " + " ".join(f"{v:9.4g}" for v in paper[name]))
    return "\n".join(lines)


def regression_method(quality: Mapping) -> str:
    """One line: plain least squares, or what the endpoint constraint did (tolerance, grid
    endpoint error of the plain and the constrained fit, largest move from a DOE optimum)."""
    report = quality.get("endpoint_constraint")
    if report is None:
        return f"regression: {quality.get('regression', 'least squares')} per parameter (the paper's method)"
    status = "" if report["converged"] else " (NOT converged)"
    check = ""
    if "check_grid_endpoint_error_max_m" in report:
        points = report["check_grid_points"]
        check = (
            f", {report['check_grid_endpoint_error_max_m'] * 1e3:.3f} mm on a {points}x{points} check grid"
            f" (held {report['fit_tolerance_m'] * 1e3:.2f} mm, {report['check_points_added']} check points added)"
        )
    return (
        f"regression: {quality['regression']}{status}: endpoint error on a {report['grid_points']}x"
        f"{report['grid_points']} grid over the fitted range {report['grid_endpoint_error_max_plain_m'] * 1e3:.2f} mm"
        f" (plain fit) -> {report['grid_endpoint_error_max_m'] * 1e3:.2f} mm{check} (tolerance"
        f" {report['tolerance_m'] * 1e3:.2f} mm); largest move from a DOE optimum"
        f" {report['max_deviation_from_doe']:.4f} rad or rad/s"
    )
