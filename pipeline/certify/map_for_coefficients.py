"""The region map of one coefficients file: the defaults a family needs, the certification, the
file written beside the coefficients (linked by their sha256), and the lines that report it.

``python -m pipeline.build`` and ``python -m pipeline.certify_range`` both go through here.
"""

from __future__ import annotations

from pathlib import Path

from pipeline.certify.range_certificate import (
    DEFAULT_BOUNDARY_CELL,
    DEFAULT_ENDPOINT_TOLERANCE_M,
    DEFAULT_MIN_CELL,
    RangeCertificateConfig,
    certify_range,
)
from pipeline.certify.region_map import DEFAULT_MAP_NAME, STATUSES, RegionMap, save_region_map
from pipeline.offline.coefficients import Coefficients

__all__ = ["DEFAULT_MAP_NAME", "certify_and_save", "default_config", "summary_lines"]


def default_config(
    coefficients: Coefficients,
    *,
    margin_m: float | None = None,
    endpoint_tolerance_m: float | None = None,
    min_cell: float | None = None,
    boundary_cell: float | None = None,
    jobs: int = 1,
) -> RangeCertificateConfig:
    """The certificate's settings for these coefficients; None takes the default (endpoint
    tolerance 0 for a family that pins the endpoints)."""
    pinned = coefficients.family.pins_endpoints
    if endpoint_tolerance_m is None:
        endpoint_tolerance_m = 0.0 if pinned else DEFAULT_ENDPOINT_TOLERANCE_M
    if min_cell is None:
        min_cell = DEFAULT_MIN_CELL
    if boundary_cell is None:
        boundary_cell = DEFAULT_BOUNDARY_CELL
    return RangeCertificateConfig(
        margin_m=margin_m,
        endpoint_tolerance_m=endpoint_tolerance_m,
        min_cell=min_cell,
        boundary_cell=min(boundary_cell, 1.0),
        jobs=jobs,
    )


def certify_and_save(
    coefficients: Coefficients, config: RangeCertificateConfig, output: Path | None
) -> tuple[RegionMap, str | None]:
    """Certify ``coefficients`` (as loaded from their file, so that the map links to its sha256)
    and write the map atomically to ``output`` (if given); returns (map, the map file's sha256)."""
    region_map = certify_range(coefficients, config)
    digest = save_region_map(region_map, output) if output is not None else None
    return region_map, digest


def summary_lines(region_map: RegionMap) -> list[str]:
    """Two lines: area fraction per status, then bounds, cells and time."""
    summary = region_map.summary()
    fractions = summary["area_fraction"]
    return [
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
