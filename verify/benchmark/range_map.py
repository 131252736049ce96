"""The region map (range certificate) that row (a*) of the benchmark looks its bounds up in.

By default the map attached to the coefficients (:func:`pipeline.load_coefficients` attaches the
one the build wrote beside them if it certifies them); ``--region-map FILE`` names one. Where
there is none (the paper's Eq. 9 has no file, or an older build's map certifies other
coefficients), the coefficients are certified here with the build's settings
(:func:`pipeline.certify.map_for_coefficients.default_config`, one process), and the report says
so and how long it took; it is not part of any timed row. That takes minutes in one process
(about one for the default build's coefficients, several for the paper's Eq. 9, whose band below
the margin is wide), and its stages are reported to ``progress``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pipeline.certify.map_files import load_region_map
from pipeline.certify.map_for_coefficients import default_config, with_execution_bounds
from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
from pipeline.certify.region_map import DEFAULT_MAP_NAME, RegionMap
from pipeline.exceptions import DataFileError, InvalidParameterError
from pipeline.io.progress import ProgressCallback
from pipeline.model.arm import PlanarArm
from pipeline.model.dynamics import identify_dynamics
from pipeline.model.limits import ArmLimits
from pipeline.offline.coefficients import Coefficients
from pipeline.online.loading import map_path_beside

#: How the map was obtained (``BenchRegionMap.origin``).
ORIGINS = ("file", "beside", "certified")


@dataclass(frozen=True)
class BenchRegionMap:
    """The map (a*) uses and where it came from.

    Attributes:
        region_map: The range certificate of the benchmarked coefficients.
        origin: "file" (``--region-map``), "beside" (the build's, beside the coefficients) or
            "certified" (certified by the benchmark, in-process).
        path: The map file, or None where it was certified in-process.
        certify_s: Wall time of the in-process certification [s] (None otherwise).
        reason: Why it was certified in-process (empty otherwise).
    """

    region_map: RegionMap
    origin: str
    path: Path | None = None
    certify_s: float | None = None
    reason: str = ""

    def __post_init__(self) -> None:
        if self.origin not in ORIGINS:
            raise InvalidParameterError("origin", self.origin, f"one of {ORIGINS}")

    def describe(self) -> str:
        """One sentence: which map, its size and, if certified here, how long that took."""
        summary = self.region_map.summary()
        fraction = summary["certified_collision_free_fraction"]
        cells = f"{summary['cells']:,} cells, certified collision-free on {100 * fraction:.2f} % of the area"
        if self.origin == "certified":
            return f"certified in-process in {self.certify_s:.1f} s ({self.reason}; {cells}); not part of any timed row"
        where = "named by --region-map" if self.origin == "file" else "the build's, beside the coefficients"
        return f"{self.path} ({where}; {cells})"

    def to_json(self) -> dict[str, Any]:
        """Plain-JSON form for the report."""
        summary = self.region_map.summary()
        return {
            "origin": self.origin,
            "description": self.describe(),
            "path": None if self.path is None else str(self.path),
            "certify_s": self.certify_s,
            "reason": self.reason or None,
            "coefficients_sha256": self.region_map.coefficients_sha256,
            "cells": summary["cells"],
            "area_fraction": summary["area_fraction"],
            "certified_collision_free_fraction": summary["certified_collision_free_fraction"],
            "clearance_bound_min_m": summary["clearance_bound_min_m"],
        }


def _missing_reason(coefficients: Coefficients) -> str:
    """Why no map is attached to ``coefficients`` (loaded with the one beside them), in words."""
    beside = map_path_beside(coefficients)
    if beside is None:
        return f"no region map exists for '{coefficients.source or '<memory>'}'"
    if beside.is_file():
        return f"{beside} certifies other coefficients"
    return f"no {DEFAULT_MAP_NAME} beside {coefficients.source}"


def bench_region_map(
    coefficients: Coefficients,
    path: Path | None = None,
    *,
    config: RangeCertificateConfig | None = None,
    log: Callable[[str], None] = lambda _: None,
    progress: ProgressCallback | None = None,
    arm: PlanarArm | None = None,
) -> BenchRegionMap:
    """The region map of ``coefficients`` for (a*): ``path`` if given, else the one attached to
    them (``coefficients.region_map``: :func:`pipeline.load_coefficients` attaches the one beside
    their file), else certified here with ``config`` (default: the build's, :func:`default_config`),
    its stages reported to ``progress``
    (:func:`pipeline.certify.range_certificate.certify_range`), with the execution bounds of ``arm``
    (its URDF limits and the acceleration limits recorded with the coefficients) if given.

    Raises:
        DataFileError: ``path`` is missing or malformed, or certifies other coefficients.
    """
    if path is not None:
        region_map = load_region_map(path)
        if not region_map.belongs_to(coefficients):
            raise DataFileError(
                path,
                f"--region-map certifies coefficients sha256 {region_map.coefficients_sha256[:12]}, not "
                f"{coefficients.source} (sha256 {coefficients.source_sha256[:12]}); run python -m "
                "pipeline.certify_range on them",
            )
        return BenchRegionMap(region_map, "file", Path(path))
    if coefficients.region_map is not None:
        return BenchRegionMap(coefficients.region_map, "beside", map_path_beside(coefficients))
    reason = _missing_reason(coefficients)
    log(f"certifying the coefficients' range for (a*) in-process ({reason}); this takes minutes ...")
    started = time.perf_counter()
    config = config if config is not None else default_config(coefficients)
    region_map = certify_range(coefficients, config, progress)
    if arm is not None:
        limits = ArmLimits.recorded(arm, coefficients.provenance)
        region_map = with_execution_bounds(region_map, coefficients, identify_dynamics(arm), limits)
    return BenchRegionMap(region_map, "certified", None, time.perf_counter() - started, reason)
