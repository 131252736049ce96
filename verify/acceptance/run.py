"""The acceptance verifier: ``python -m verify.sweep``.

For ``n`` obstacle sizes (L, W) drawn uniformly (seeded) from the coefficients' fitted range
(or ``--range``), the trajectory is generated from the coefficients exactly as an online user
would (:func:`pipeline.online.generator.generate`) and measured by :func:`verify.metrics.measure_case`:
sampled and certified clearance (Pinocchio + Coal, continuous-time certificate of
:mod:`pipeline.geometry.sinusoid_certificate`), endpoint errors, tracking errors, joint peaks against the URDF.

Exit status: 0 if every case passes, 1 if any case fails (they are listed with their (L, W)),
2 on bad input (one line on stderr, no traceback), 130 if interrupted.

``--coefficients paper`` judges the paper's own Eq. 9 with the same verifier; ``--compare A B``
runs both on the same sampled cases and prints them side by side.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import datetime
import importlib
import importlib.metadata
import math
import multiprocessing
import os
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from pipeline.exceptions import DataFileError, InvalidParameterError, PipelineError
from pipeline.geometry.link_reach import LinkReach
from pipeline.geometry.motion_certificate import DEFAULT_MAX_EVALUATIONS, DEFAULT_RESOLUTION_M, DEFAULT_TOLERANCE_M
from pipeline.io.jsonio import json_safe, write_json_atomic
from pipeline.io.provenance import package_versions, sha256_file
from pipeline.model.arm import PlanarArm, load_planar_arm
from pipeline.model.obstacle import Obstacle
from pipeline.validation import check_finite, check_non_negative, check_positive, check_positive_int
from verify.cli import DEFAULT_COEFFICIENTS, HelpFormatter, Parser, load_coefficients_for_cli

from .metrics import AcceptanceThresholds, CaseResult, MeasureSettings, check_arm_matches, measure_case
from .sweep_report import format_comparison, format_summary

#: Default coefficients file (relative to the working directory).
DEFAULT_CASES = 1000
DEFAULT_SEED = 0
EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130

#: The paper's DOE grid (Table 1) [m].
DOE_L_M = (0.20, 0.25, 0.30)
DOE_W_M = (0.08, 0.10, 0.12)
#: Where the four case studies sit in the fitted range, as fractions (of L, of W); they fall off
#: the DOE grid: with the paper's range they are (0.270, 0.110), (0.220, 0.090), (0.280, 0.085)
#: and (0.230, 0.115) m.
CASE_STUDY_FRACTIONS = ((0.70, 0.75), (0.20, 0.25), (0.80, 0.125), (0.30, 0.875))


Pair = tuple[float, float]


# --------------------------------------------------------------------------------------------
# Cases


@dataclass(frozen=True)
class SweepRange:
    """The rectangle of obstacle sizes sampled [m].

    Attributes:
        L_m: (min, max) of L [m].
        W_m: (min, max) of W [m].
    """

    L_m: Pair
    W_m: Pair

    def __post_init__(self) -> None:
        for name, (lo, hi) in (("L", self.L_m), ("W", self.W_m)):
            check_positive(f"{name} min", lo)
            check_positive(f"{name} max", hi)
            if lo > hi:
                raise InvalidParameterError(f"{name} range", (lo, hi), "min <= max")
        object.__setattr__(self, "L_m", (float(self.L_m[0]), float(self.L_m[1])))
        object.__setattr__(self, "W_m", (float(self.W_m[0]), float(self.W_m[1])))

    @classmethod
    def from_fitted(cls, fitted_range_m: dict[str, Sequence[float]]) -> SweepRange:
        """The range of a coefficients file's ``fitted_range_m`` ({"L": (lo, hi), "W": (lo, hi)})."""
        return cls(tuple(fitted_range_m["L"]), tuple(fitted_range_m["W"]))  # type: ignore[arg-type]

    def contains(self, other: SweepRange) -> bool:
        """True if ``other`` lies inside this range."""
        return (
            self.L_m[0] <= other.L_m[0] <= other.L_m[1] <= self.L_m[1]
            and self.W_m[0] <= other.W_m[0] <= other.W_m[1] <= self.W_m[1]
        )

    def intersection(self, other: SweepRange) -> SweepRange | None:
        """The common part of both ranges, or None if they do not overlap."""
        lo_l, hi_l = max(self.L_m[0], other.L_m[0]), min(self.L_m[1], other.L_m[1])
        lo_w, hi_w = max(self.W_m[0], other.W_m[0]), min(self.W_m[1], other.W_m[1])
        if lo_l > hi_l or lo_w > hi_w:
            return None
        return SweepRange((lo_l, hi_l), (lo_w, hi_w))

    def to_dict(self) -> dict[str, list[float]]:
        """{"L": [lo, hi], "W": [lo, hi]} [m]."""
        return {"L": list(self.L_m), "W": list(self.W_m)}


def sample_cases(sweep_range: SweepRange, n: int, seed: int) -> np.ndarray:
    """n obstacle sizes (L, W) [m], uniform in ``sweep_range``, from ``numpy.random.default_rng(seed)``.

    Returns shape (n, 2). The same (range, n, seed) always gives the same cases.
    """
    check_positive_int("n", n, minimum=1)
    check_positive_int("seed", seed, minimum=0)
    rng = np.random.default_rng(seed)
    lengths = rng.uniform(sweep_range.L_m[0], sweep_range.L_m[1], n)
    widths = rng.uniform(sweep_range.W_m[0], sweep_range.W_m[1], n)
    return np.stack([lengths, widths], -1)


def case_study_sizes(fitted: SweepRange) -> list[Pair]:
    """The four case-study obstacles (L, W) [m]: inside the fitted range, off the DOE grid, to 1 mm."""
    sizes = []
    for fl, fw in CASE_STUDY_FRACTIONS:
        length = round(fitted.L_m[0] + fl * (fitted.L_m[1] - fitted.L_m[0]), 3)
        width = round(fitted.W_m[0] + fw * (fitted.W_m[1] - fitted.W_m[0]), 3)
        sizes.append((length, width))
    return sizes


def on_doe_grid(length_m: float, width_m: float) -> bool:
    """True if (L, W) is one of the paper's nine DOE points."""
    return any(math.isclose(length_m, a, abs_tol=1e-9) for a in DOE_L_M) and any(
        math.isclose(width_m, b, abs_tol=1e-9) for b in DOE_W_M
    )


# --------------------------------------------------------------------------------------------
# Running cases (in-process or in worker processes)


@dataclass(frozen=True)
class _Chunk:
    """A batch of cases for one worker call (everything picklable)."""

    source: str
    sha256: str
    urdf_path: str | None
    settings: MeasureSettings
    cases: tuple[tuple[int, float, float], ...]


def _measure_chunk(chunk: _Chunk, coefficients: Any = None, arm: PlanarArm | None = None) -> list[CaseResult]:
    """Measure a batch of cases; loads the coefficients and arm unless given."""
    if coefficients is None:
        coefficients = load_coefficients_for_cli(chunk.source)
        if coefficients.source_sha256 != chunk.sha256:
            raise DataFileError(chunk.source, "changed while the sweep was running (sha256 differs)")
    arm = arm or load_planar_arm(chunk.urdf_path)
    reach = LinkReach.from_arm(arm)
    return [
        measure_case(coefficients, length, width, arm, chunk.settings, index=index, reach=reach)
        for index, length, width in chunk.cases
    ]


def resolve_jobs(jobs: int) -> int:
    """Number of worker processes: ``jobs``, or every usable CPU if 0."""
    check_positive_int("jobs", jobs, minimum=0)
    if jobs == 0:
        try:
            return len(os.sched_getaffinity(0))
        except AttributeError:  # pragma: no cover - not Linux
            return os.cpu_count() or 1
    return jobs


def run_cases(
    source: str,
    cases_m: np.ndarray,
    settings: MeasureSettings,
    *,
    jobs: int = 1,
    urdf_path: str | None = None,
    progress: bool = False,
    label: str = "",
    coefficients: Any = None,
    arm: PlanarArm | None = None,
) -> tuple[CaseResult, ...]:
    """Measure every case (L, W) of ``cases_m`` (shape (n, 2) [m]); results in case order.

    The results do not depend on ``jobs``: each case is measured independently and
    deterministically. ``jobs`` > 1 uses that many worker processes (spawned; each loads the
    coefficients and the arm itself and checks the coefficients' hash).

    Args:
        source: Coefficients file, or "paper".
        cases_m: Obstacle sizes, shape (n, 2) [m].
        settings: Measurement settings.
        jobs: Worker processes (0: every CPU; 1: in this process).
        urdf_path: URDF of the arm (default: the project's).
        progress: Show a tqdm progress bar on stderr.
        label: Progress-bar label.
        coefficients, arm: Already loaded objects for the in-process path (optional).
    """
    jobs = resolve_jobs(jobs)
    cases = np.asarray(cases_m, dtype=float).reshape(-1, 2)
    coefficients = coefficients if coefficients is not None else load_coefficients_for_cli(source)
    indexed = [(i, float(length), float(width)) for i, (length, width) in enumerate(cases)]
    size = max(1, min(16, math.ceil(len(indexed) / (4 * jobs))))
    chunks = [
        _Chunk(source, coefficients.source_sha256, urdf_path, settings, tuple(indexed[i : i + size]))
        for i in range(0, len(indexed), size)
    ]
    results: list[CaseResult] = []
    with tqdm(total=len(indexed), desc=label or "cases", unit="case", file=sys.stderr, disable=not progress) as bar:
        if jobs == 1 or len(chunks) == 1:
            arm = arm or load_planar_arm(urdf_path)
            for chunk in chunks:
                results.extend(_measure_chunk(chunk, coefficients, arm))
                bar.update(len(chunk.cases))
        else:
            context = multiprocessing.get_context("spawn")
            with concurrent.futures.ProcessPoolExecutor(max_workers=jobs, mp_context=context) as pool:
                futures = [pool.submit(_measure_chunk, chunk) for chunk in chunks]
                try:
                    for future in concurrent.futures.as_completed(futures):
                        chunk_results = future.result()
                        results.extend(chunk_results)
                        bar.update(len(chunk_results))
                except BaseException:
                    for future in futures:
                        future.cancel()
                    raise
    results.sort(key=lambda r: r.index)
    return tuple(results)


# --------------------------------------------------------------------------------------------
# Summary, provenance, report


def _stat(values: list[float], fn: Callable[[np.ndarray], Any]) -> float | None:
    return float(fn(np.asarray(values))) if values else None


def _brief(case: CaseResult) -> dict[str, Any]:
    return {
        "index": case.index,
        "L": case.L_m,
        "W": case.W_m,
        "certified_clearance_m": case.certified_clearance_m,
        "clearance_m": case.clearance_m,
        "endpoint_error_m": case.endpoint_error_m,
        "tracking_max_m": case.tracking_max_m,
        "failures": list(case.failures),
        "error": case.error,
    }


def summarize(cases: Sequence[CaseResult], thresholds: AcceptanceThresholds, worst: int = 5) -> dict[str, Any]:
    """Aggregate statistics of a sweep (every length in m). Deterministic given the cases."""
    measured = [c for c in cases if c.error is None]
    certified = [c.certified_clearance_m for c in measured if c.certified_clearance_m is not None]
    sampled = [c.clearance_m for c in measured if c.clearance_m is not None]
    endpoint = [c.endpoint_error_m for c in measured if c.endpoint_error_m is not None]
    tracking_max = [c.tracking_max_m for c in measured if c.tracking_max_m is not None]
    tracking_rms = [c.tracking_rms_m for c in measured if c.tracking_rms_m is not None]
    n = len(cases)
    n_passed = sum(c.passed for c in cases)
    keep = sum(bool(c.keeps_margin) for c in cases)
    by_clearance = sorted(
        (c for c in measured if c.certified_clearance_m is not None), key=lambda c: (c.certified_clearance_m, c.index)
    )
    by_endpoint = sorted((c for c in measured), key=lambda c: (-(c.endpoint_error_m or 0.0), c.index))
    velocity = [c.peak_velocity_rad_s for c in measured if c.peak_velocity_rad_s is not None]
    acceleration = [c.peak_acceleration_rad_s2 for c in measured if c.peak_acceleration_rad_s2 is not None]
    samples = [c.time_samples for c in measured if c.time_samples is not None]
    evaluations = [c.certificate_evaluations for c in measured if c.certificate_evaluations is not None]
    return {
        "all_passed": n_passed == n,
        "n_cases": n,
        "n_passed": n_passed,
        "n_failed": n - n_passed,
        "pass_rate": n_passed / n if n else None,
        "n_errors": n - len(measured),
        "n_extrapolated": sum(c.extrapolated for c in cases),
        "n_certified_collision_free": sum(bool(c.collision_free) for c in cases),
        "margin_m": thresholds.margin_m,
        "n_keep_margin": keep,
        "keep_margin_fraction": keep / n if n else None,
        "certified_clearance_min_m": _stat(certified, np.min),
        "certified_clearance_median_m": _stat(certified, np.median),
        "clearance_min_m": _stat(sampled, np.min),
        "clearance_median_m": _stat(sampled, np.median),
        "endpoint_error_median_m": _stat(endpoint, np.median),
        "endpoint_error_p99_m": _stat(endpoint, lambda a: np.percentile(a, 99)),
        "endpoint_error_max_m": _stat(endpoint, np.max),
        "tracking_max_m": _stat(tracking_max, np.max),
        "tracking_max_median_m": _stat(tracking_max, np.median),
        "tracking_rms_median_m": _stat(tracking_rms, np.median),
        "tracking_rms_max_m": _stat(tracking_rms, np.max),
        "peak_velocity_max_rad_s": [float(v) for v in np.max(velocity, axis=0)] if velocity else None,
        "peak_acceleration_max_rad_s2": [float(v) for v in np.max(acceleration, axis=0)] if acceleration else None,
        "n_within_joint_limits": sum(
            bool(c.within_velocity_limits and c.within_position_limits and c.within_acceleration_limits is not False)
            for c in measured
        ),
        "time_samples_min": min(samples) if samples else None,
        "time_samples_max": max(samples) if samples else None,
        "certificate_evaluations_total": int(sum(evaluations)),
        "n_certificate_not_converged": sum(c.certificate_converged is False for c in measured),
        "worst_clearance": [_brief(c) for c in by_clearance[:worst]],
        "worst_endpoint_error": [_brief(c) for c in by_endpoint[:worst]],
        "failing": [_brief(c) for c in cases if not c.passed],
    }


@dataclass(frozen=True)
class SweepRun:
    """One coefficients set judged on one set of cases.

    Attributes:
        label: Short name ("paper", or the file's stem).
        source: The coefficients source as given.
        cases: One result per sampled case, in case order.
        case_studies: The four case studies (indices -1..-4 are not used: index 0..3, own list).
        summary: :func:`summarize` of ``cases``.
        provenance: Coefficients hash, seed, range, settings, package versions.
        sweep_range: The sampled range.
        fitted_range: The coefficients' fitted range.
        elapsed_s: Wall time of the sweep [s].
        jobs: Worker processes used.
    """

    label: str
    source: str
    cases: tuple[CaseResult, ...]
    case_studies: tuple[CaseResult, ...]
    summary: dict[str, Any]
    provenance: dict[str, Any]
    sweep_range: SweepRange
    fitted_range: SweepRange
    elapsed_s: float
    jobs: int
    settings: MeasureSettings = field(default_factory=MeasureSettings)

    def __post_init__(self) -> None:
        check_non_negative("elapsed_s", self.elapsed_s)

    @property
    def passed(self) -> bool:
        """True if every case passed."""
        return bool(self.summary["all_passed"])

    @property
    def extrapolating(self) -> bool:
        """True if the sampled range leaves the fitted range."""
        return not self.fitted_range.contains(self.sweep_range)

    def to_json(self) -> dict[str, Any]:
        """{"cases": [...], "summary": {...}, "provenance": {...}, "case_studies": [...], "timing": {...}}."""
        return json_safe(
            {
                "label": self.label,
                "cases": [c.to_json() for c in self.cases],
                "summary": self.summary,
                "case_studies": [c.to_json() for c in self.case_studies],
                "provenance": self.provenance,
                "timing": {
                    "elapsed_s": self.elapsed_s,
                    "cases_per_s": len(self.cases) / self.elapsed_s if self.elapsed_s > 0 else None,
                    "jobs": self.jobs,
                },
            }
        )


def run_sweep(
    source: str,
    *,
    n: int = DEFAULT_CASES,
    seed: int = DEFAULT_SEED,
    sweep_range: SweepRange | None = None,
    settings: MeasureSettings | None = None,
    jobs: int = 1,
    urdf_path: str | None = None,
    progress: bool = False,
    label: str | None = None,
    cases_m: np.ndarray | None = None,
    case_studies: bool = True,
    argv: Sequence[str] | None = None,
) -> SweepRun:
    """Judge one coefficients set on n seeded cases (or the given ``cases_m``).

    Args:
        source: Coefficients file or "paper".
        n: Number of cases (ignored if ``cases_m`` is given).
        seed: Seed of the case sampler.
        sweep_range: Sampled range; default the coefficients' fitted range.
        settings: Measurement settings; default :class:`MeasureSettings`.
        jobs: Worker processes (0: every CPU).
        urdf_path: URDF of the arm; default the project's.
        progress: Show a progress bar on stderr.
        label: Name of the run; default "paper" or the file's stem.
        cases_m: Explicit cases (n, 2) [m] instead of sampling (``seed`` is then only recorded).
        case_studies: Also measure the four case studies.
        argv: Command line to record in the provenance.

    Raises:
        PipelineError: bad coefficients, range or settings.
    """
    settings = settings or MeasureSettings()
    coefficients = load_coefficients_for_cli(source)
    fitted = SweepRange.from_fitted(coefficients.fitted_range_m)
    chosen = sweep_range or fitted
    cases = sample_cases(chosen, n, seed) if cases_m is None else np.asarray(cases_m, dtype=float).reshape(-1, 2)
    arm = load_planar_arm(urdf_path)
    check_arm_matches(coefficients, arm)
    for length, width in ((chosen.L_m[0], chosen.W_m[0]), (chosen.L_m[1], chosen.W_m[1])):
        Obstacle.in_scene(length, width, coefficients.scene)  # fails early on impossible sizes
    name = label or ("paper" if source == "paper" else Path(source).stem)
    start = time.perf_counter()
    results = run_cases(
        source,
        cases,
        settings,
        jobs=jobs,
        urdf_path=urdf_path,
        progress=progress,
        label=name,
        coefficients=coefficients,
        arm=arm,
    )
    elapsed = time.perf_counter() - start
    studies: tuple[CaseResult, ...] = ()
    if case_studies:
        reach = LinkReach.from_arm(arm)
        studies = tuple(
            measure_case(coefficients, length, width, arm, settings, index=i, reach=reach)
            for i, (length, width) in enumerate(case_study_sizes(fitted))
        )
    urdf = Path(urdf_path) if urdf_path else arm.urdf_path
    provenance = {
        "coefficients": {
            "source": source,
            "path": None if source == "paper" else str(Path(source).resolve()),
            "sha256": coefficients.source_sha256,
            "family": coefficients.family.name,
            "fitted_range_m": fitted.to_dict(),
            "provenance": coefficients.provenance,
        },
        "seed": seed,
        "cases_given_explicitly": cases_m is not None,
        "n_cases": len(results),
        "range_m": chosen.to_dict(),
        "range_is_fitted_range": sweep_range is None,
        "extrapolating": not fitted.contains(chosen),
        "settings": settings.to_dict(),
        "urdf": {"path": str(urdf), "sha256": sha256_file(urdf)},
        "scene": coefficients.scene.to_dict(),
        "packages": package_versions(),
        "command": list(argv) if argv is not None else None,
        "created_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    }
    return SweepRun(
        label=name,
        source=source,
        cases=results,
        case_studies=studies,
        summary=summarize(results, settings.thresholds),
        provenance=json_safe(provenance),
        sweep_range=chosen,
        fitted_range=fitted,
        elapsed_s=elapsed,
        jobs=resolve_jobs(jobs),
        settings=settings,
    )


# --------------------------------------------------------------------------------------------
# Command line


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface of ``python -m verify.sweep``."""
    parser = Parser(
        prog="python -m verify.sweep",
        description=(
            "Acceptance verifier: judge a coefficients file (or the paper's Eq. 9) on random obstacle "
            "sizes (L, W): certified clearance (Pinocchio + Coal, continuous time), endpoint accuracy, "
            "tracking, joint limits. Exit status 0 if every case passes, 1 if any fails, 2 on bad input."
        ),
        formatter_class=HelpFormatter,
    )
    source = parser.add_mutually_exclusive_group()
    source.add_argument(
        "--coefficients",
        metavar="FILE",
        default=DEFAULT_COEFFICIENTS,
        help="coefficients file to judge, or 'paper' for the paper's Eq. 9",
    )
    source.add_argument(
        "--compare",
        nargs=2,
        metavar=("A", "B"),
        default=None,
        help="judge two coefficients sources (files or 'paper') on the same cases and print them side by side; "
        "the default range is the intersection of their fitted ranges (default: off)",
    )
    parser.add_argument("--n", type=int, default=DEFAULT_CASES, help="number of sampled cases [cases] (>= 1)")
    parser.add_argument("--seed", type=int, default=DEFAULT_SEED, help="seed of the (L, W) sampler (>= 0)")
    parser.add_argument(
        "--range",
        nargs=4,
        type=float,
        metavar=("LMIN", "LMAX", "WMIN", "WMAX"),
        default=None,
        help="sample L in [LMIN, LMAX] m and W in [WMIN, WMAX] m instead of the fitted range "
        "(cases outside it are reported as extrapolation) (default: the coefficients' fitted range)",
    )
    parser.add_argument(
        "--jobs",
        type=int,
        default=1,
        help="worker processes [processes] (0: every CPU); the results do not depend on it",
        metavar="J",
    )
    parser.add_argument(
        "--samples",
        type=int,
        default=None,
        help="time samples per case [samples] (>= 2) (default: enough that no link point moves more than --resolution "
        "between samples)",
    )
    parser.add_argument(
        "--resolution",
        type=float,
        default=DEFAULT_RESOLUTION_M,
        metavar="M",
        help="motion resolution of the default time sampling [m]",
    )
    parser.add_argument(
        "--tolerance",
        type=float,
        default=DEFAULT_TOLERANCE_M,
        metavar="M",
        help="certificate refinement tolerance: bisect until the certified bound is within this of the "
        "sampled minimum [m]",
    )
    parser.add_argument(
        "--max-evaluations",
        type=int,
        default=DEFAULT_MAX_EVALUATIONS,
        metavar="N",
        help="certificate refinement budget per case [clearance evaluations]",
    )
    parser.add_argument(
        "--min-clearance",
        type=float,
        default=0.0,
        metavar="M",
        help="a case passes only if its certified clearance is > this [m] (0: certified collision-free)",
    )
    parser.add_argument(
        "--max-endpoint-error",
        type=float,
        default=0.005,
        metavar="M",
        help="a case passes only if both endpoint errors are <= this [m]",
    )
    parser.add_argument(
        "--margin",
        type=float,
        default=0.01,
        metavar="M",
        help="safety margin [m]: the fraction of cases whose certified clearance keeps it is reported",
    )
    parser.add_argument("--require-margin", action="store_true", help="also fail the cases that do not keep --margin")
    parser.add_argument(
        "--max-tracking-error",
        type=float,
        default=None,
        metavar="M",
        help="fail the cases whose max tracking error exceeds this [m] (default: report only)",
    )
    parser.add_argument(
        "--joint-limits",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="fail the cases whose joint speed or angle leaves the URDF's limits",
    )
    parser.add_argument(
        "--max-acceleration",
        nargs=2,
        type=float,
        default=None,
        metavar=("A1", "A2"),
        help="joint acceleration limits [rad/s^2] (the URDF has none) (default: report only)",
    )
    parser.add_argument(
        "--urdf",
        metavar="FILE",
        default=None,
        help="URDF of the arm (default: the project's urdf/planar_2link.urdf)",
        type=str,
    )
    parser.add_argument(
        "--json",
        metavar="FILE",
        type=Path,
        default=None,
        help="write cases, summary and provenance as JSON (atomically) (default: none)",
    )
    parser.add_argument(
        "--plots",
        metavar="DIR",
        type=Path,
        default=None,
        help="write PNG plots (clearance and endpoint error over (L, W), the four case studies) (default: none)",
    )
    parser.add_argument(
        "--meshcat",
        action="store_true",
        help="after the sweep, serve the results in a Meshcat viewer on the loopback interface until Ctrl-C "
        "(with --compare, the first run)",
    )
    parser.add_argument(
        "--html",
        metavar="FILE",
        type=Path,
        default=None,
        help="write a self-contained HTML page (Meshcat) of the results; with --compare one file per run, "
        "suffixed _1 and _2 (default: none)",
    )
    parser.add_argument(
        "--list-failures",
        type=int,
        default=None,
        metavar="K",
        help="list at most K failing cases on stdout (default: all; --json has all)",
    )
    parser.add_argument(
        "--progress", action=argparse.BooleanOptionalAction, default=True, help="progress bar on stderr"
    )
    return parser


def _settings_from_args(args: argparse.Namespace) -> MeasureSettings:
    thresholds = AcceptanceThresholds(
        min_certified_clearance_m=args.min_clearance,
        max_endpoint_error_m=args.max_endpoint_error,
        margin_m=args.margin,
        require_margin=args.require_margin,
        max_tracking_error_m=args.max_tracking_error,
        check_joint_limits=args.joint_limits,
        acceleration_limits_rad_s2=tuple(args.max_acceleration) if args.max_acceleration else None,
    )
    return MeasureSettings(
        resolution_m=args.resolution,
        time_samples=args.samples,
        tolerance_m=args.tolerance,
        max_evaluations=args.max_evaluations,
        thresholds=thresholds,
    )


def _validate_args(args: argparse.Namespace) -> None:
    """Raise InvalidParameterError on bad values before any work starts."""
    check_positive_int("--n", args.n, minimum=1)
    check_positive_int("--seed", args.seed, minimum=0)
    check_positive_int("--jobs", args.jobs, minimum=0)
    if args.samples is not None:
        check_positive_int("--samples", args.samples, minimum=2)
    check_positive("--resolution [m]", args.resolution)
    check_positive("--tolerance [m]", args.tolerance)
    check_positive_int("--max-evaluations", args.max_evaluations, minimum=0)
    check_non_negative("--max-endpoint-error [m]", args.max_endpoint_error)
    check_non_negative("--margin [m]", args.margin)
    check_finite("--min-clearance [m]", args.min_clearance)
    if args.max_tracking_error is not None:
        check_non_negative("--max-tracking-error [m]", args.max_tracking_error)
    if args.max_acceleration is not None:
        for value in args.max_acceleration:
            check_positive("--max-acceleration [rad/s^2]", value)
    if args.list_failures is not None:
        check_positive_int("--list-failures", args.list_failures, minimum=0)
    if args.range is not None:
        lmin, lmax, wmin, wmax = args.range
        for name, value in (("LMIN", lmin), ("LMAX", lmax), ("WMIN", wmin), ("WMAX", wmax)):
            check_positive(f"--range {name} [m]", value)
        if lmin > lmax:
            raise InvalidParameterError("--range", args.range, f"LMIN <= LMAX (got LMIN {lmin} > LMAX {lmax})")
        if wmin > wmax:
            raise InvalidParameterError("--range", args.range, f"WMIN <= WMAX (got WMIN {wmin} > WMAX {wmax})")
    for path, what in ((args.json, "--json"), (args.html, "--html")):
        if path is not None and not path.parent.is_dir():
            raise InvalidParameterError(what, str(path), "a file in an existing directory")
    if args.plots is not None and args.plots.exists() and not args.plots.is_dir():
        raise InvalidParameterError("--plots", str(args.plots), "a directory")


def _viewer(args: argparse.Namespace) -> Any:
    """The module verify.viewer.sweep_view if --meshcat or --html was given (imported only then)."""
    if not (args.meshcat or args.html):
        return None
    flag = "--meshcat" if args.meshcat else "--html"
    try:
        module = importlib.import_module("verify.viewer.sweep_view")
    except ImportError as exc:
        raise PipelineError(
            f"{flag} needs the viewer (verify.viewer.sweep_view), which is unavailable: {exc}"
        ) from None
    for wanted, name in ((args.meshcat, "show_sweep"), (args.html, "sweep_html")):
        if wanted and not callable(getattr(module, name, None)):
            raise PipelineError(f"{flag} needs verify.viewer.sweep_view.{name}, which does not exist")
    return module


def _show(viewer: Any, runs: Sequence[SweepRun], coefficients: Sequence[Any], args: argparse.Namespace) -> None:
    """Write the HTML view (one file per run) and/or serve the Meshcat view (first run) of the sweep."""
    from pipeline.online.generator import generate

    arm = load_planar_arm(args.urdf)
    for k, (run, coefficient_set) in enumerate(zip(runs, coefficients, strict=True)):

        def regenerate(length_m: float, width_m: float, chosen: Any = coefficient_set) -> Any:
            return generate(chosen, length_m, width_m, out_of_range="ignore")

        cases = [case.to_json() for case in run.cases]
        if args.html is not None:
            path = args.html if len(runs) == 1 else args.html.with_name(f"{args.html.stem}_{k + 1}{args.html.suffix}")
            viewer.sweep_html(cases, regenerate, path, arm=arm)
            print(f"wrote {path} ({run.label})")
        if args.meshcat and k == 0:
            if len(runs) > 1:
                print(f"Meshcat shows the first run only ({run.label})")
            try:
                viewer.show_sweep(cases, regenerate, arm=arm)
            except KeyboardInterrupt:
                pass


def _labels(sources: Sequence[str]) -> list[str]:
    labels = ["paper" if s == "paper" else Path(s).stem for s in sources]
    if len(set(labels)) < len(labels):
        labels = [f"{label} ({name})" for label, name in zip(labels, "AB", strict=False)]
    return labels


def main(argv: Sequence[str] | None = None) -> int:
    """Run the verifier; returns the exit status (0 all pass, 1 some fail, 2 bad input, 130 interrupted)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help (0) or a usage error (2), already printed
        return int(exc.code or 0)
    try:
        _validate_args(args)
        settings = _settings_from_args(args)
        viewer = _viewer(args)
        sources = list(args.compare) if args.compare else [args.coefficients]
        coefficients = [load_coefficients_for_cli(s) for s in sources]
        if args.range is not None:
            chosen: SweepRange | None = SweepRange((args.range[0], args.range[1]), (args.range[2], args.range[3]))
        elif len(coefficients) > 1:
            ranges = [SweepRange.from_fitted(c.fitted_range_m) for c in coefficients]
            chosen = ranges[0].intersection(ranges[1])
            if chosen is None:
                raise InvalidParameterError(
                    "--compare", sources, "coefficients with overlapping fitted ranges, or --range"
                )
        else:
            chosen = None
        sweep_range = chosen or SweepRange.from_fitted(coefficients[0].fitted_range_m)
        cases = sample_cases(sweep_range, args.n, args.seed)
        runs = [
            run_sweep(
                source,
                n=args.n,
                seed=args.seed,
                sweep_range=chosen,
                settings=settings,
                jobs=args.jobs,
                urdf_path=args.urdf,
                progress=args.progress,
                label=label,
                cases_m=cases,
                argv=["python", "-m", "verify.sweep", *argv],
            )
            for source, label in zip(sources, _labels(sources), strict=True)
        ]
        for run in runs:
            print(format_summary(run, args.list_failures))
            print()
        if len(runs) > 1:
            print(format_comparison(runs))
        if args.json is not None:
            data = runs[0].to_json() if len(runs) == 1 else {"runs": [r.to_json() for r in runs]}
            write_json_atomic(args.json, data)
            print(f"wrote {args.json}")
        if args.plots is not None:
            from .plots import write_plots

            for run in runs:
                directory = args.plots if len(runs) == 1 else args.plots / run.label.replace(" ", "_")
                for path in write_plots(run, directory, urdf_path=args.urdf):
                    print(f"wrote {path}")
        if viewer is not None:
            _show(viewer, runs, coefficients, args)
    except KeyboardInterrupt:
        print(f"{parser.prog}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except (PipelineError, OSError) as exc:
        print(f"{parser.prog}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    return EXIT_OK if all(run.passed for run in runs) else EXIT_FAILED


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
