"""The region map of one coefficients file: the defaults a family needs, the execution bounds of
its leaves for an arm, and the lines that report it.

``python -m pipeline.build`` and ``python -m pipeline.certify_range`` both go through here.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from pipeline.certify.execution_range import execution_bounds
from pipeline.certify.range_certificate import (
    DEFAULT_ENDPOINT_TOLERANCE_M,
    RangeCertificateConfig,
)
from pipeline.certify.range_model import RangeModel
from pipeline.certify.region_map import DEFAULT_MAP_NAME, STATUSES, RegionMap
from pipeline.io.executor import Executor
from pipeline.model.dynamics import PlanarDynamics
from pipeline.model.limits import ArmLimits
from pipeline.offline.coefficients import Coefficients

__all__ = ["DEFAULT_MAP_NAME", "default_config", "summary_lines", "with_execution_bounds"]


def default_config(
    coefficients: Coefficients,
    *,
    margin_m: float | None = None,
    endpoint_tolerance_m: float | None = None,
    min_cell: float | None = None,
    boundary_cell: float | None = None,
    extra_depth: int | None = None,
    merge_spread_m: float | None = None,
    second_order: bool | None = None,
    strip_split: int | None = None,
    infeasibility_cuts: int | None = None,
    tilt_cuts: int | None = None,
    clearance_cuts: int | None = None,
    jobs: int = 1,
    executor: Executor | None = None,
) -> RangeCertificateConfig:
    """The certificate's settings for these coefficients; None takes the default (endpoint
    tolerance 0 for a family that pins the endpoints; the rest by the number of axes,
    :meth:`RangeCertificateConfig.for_axes`). The tasks run on ``executor``, or on ``jobs`` local
    processes (:mod:`pipeline.io.executor`)."""
    if endpoint_tolerance_m is None:
        endpoint_tolerance_m = 0.0 if coefficients.family.pins_endpoints else DEFAULT_ENDPOINT_TOLERANCE_M
    return RangeCertificateConfig.for_axes(
        coefficients.variables.k,
        margin_m=margin_m,
        endpoint_tolerance_m=endpoint_tolerance_m,
        min_cell=min_cell,
        boundary_cell=None if boundary_cell is None else min(boundary_cell, 1.0),
        extra_depth=extra_depth,
        merge_spread_m=merge_spread_m,
        second_order=second_order,
        strip_split=strip_split,
        infeasibility_cuts=infeasibility_cuts,
        tilt_cuts=tilt_cuts,
        clearance_cuts=clearance_cuts,
        jobs=jobs,
        executor=executor,
    )


def with_execution_bounds(
    region_map: RegionMap,
    coefficients: Coefficients,
    dynamics: PlanarDynamics,
    limits: ArmLimits,
    executor: int | Executor = 1,
) -> RegionMap:
    """``region_map`` with the execution bounds of its leaves for the arm of ``dynamics`` and
    ``limits`` (:mod:`pipeline.certify.execution_bounds`), computed in fixed chunks of leaves on
    ``executor`` (a number of local processes or an executor, :mod:`pipeline.io.executor`; the
    bounds do not depend on it)."""
    bounds = execution_bounds(
        RangeModel.from_coefficients(coefficients),
        region_map.leaf_centres_m(),
        region_map.leaf_sizes_m() / 2.0,
        dynamics,
        limits,
        executor,
    )
    return replace(region_map, execution=bounds)


def summary_lines(region_map: RegionMap) -> list[str]:
    """Two lines: area fraction per status, then bounds, cells and time; a third with the
    execution bounds' fractions if the map has them, a fourth with its near-optimal cells'."""
    summary = region_map.summary()
    fractions = summary["area_fraction"]
    return (
        [
            "range certificate: "
            + ", ".join(f"{name} {100 * fractions[name]:.2f} %" for name in STATUSES)
            + f" of the area (margin {1e3 * region_map.margin_m:.2f} mm, endpoint tolerance "
            f"{1e3 * region_map.endpoint_tolerance_m:.2f} mm)",
            f"certified collision-free {100 * summary['certified_collision_free_fraction']:.2f} %; clearance bound min "
            f"{1e3 * summary['clearance_bound_min_m']:.3f} mm; endpoint bound max "
            f"{1e3 * summary['endpoint_bound_max_m']:.3f} mm, <= tolerance on "
            f"{100 * summary['endpoint_within_tolerance_fraction']:.2f} %; "
            f"{summary['cells']} cells in {region_map.seconds:.1f} s",
        ]
        + _execution_lines(region_map)
        + _cells_lines(region_map)
    )


def _cells_lines(region_map: RegionMap) -> list[str]:
    cells = region_map.near_optimal_cells
    if cells is None:
        return []
    durations = np.asarray(cells.table["duration_s"])
    certified = np.isfinite(durations)
    grid = " x ".join(str(n) for n in cells.cells_per_axis)
    limits = cells.limits
    line = (
        f"near-optimal cells: {int(certified.sum())} of {durations.size} certified ({grid} over "
        f"{', '.join(cells.axes)}; acceleration {limits.acceleration_rad_s2[0]:g}, {limits.acceleration_rad_s2[1]:g} "
        f"rad/s^2, jerk {limits.jerk_rad_s3[0]:g}, {limits.jerk_rad_s3[1]:g} rad/s^3)"
    )
    if certified.any():
        line += f", T' from {durations[certified].min():.3f} to {durations[certified].max():.3f} s"
    return [line]


def _execution_lines(region_map: RegionMap) -> list[str]:
    summary = region_map.execution_summary()
    if summary is None:
        return []
    breaks = summary["paper_breaks_fraction"]
    longest = summary["rest_to_rest_duration_max_s"]
    return [
        f"arm limits: the paper timing is proven within them on {100 * summary['paper_keeps_limits_fraction']:.2f} % "
        "of the range (bound above the limit: "
        + ", ".join(f"{name} {100 * breaks[name]:.2f} %" for name in breaks)
        + f"); rest-to-rest within them on {100 * summary['rest_to_rest_fraction']:.2f} %"
        + ("" if longest is None else f", T' <= {longest:.3f} s (T <= {summary['path_duration_max_s']:.3f} s)")
    ]
