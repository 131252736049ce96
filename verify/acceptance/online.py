"""Certify-or-repair over many obstacles (the library of ``python -m verify.online_sweep``).

For each sampled (L, W) the online generator runs with certification on
(:func:`pipeline.online.repair.generate_certified`). Every answer must either carry a certified
clearance of at least the margin or be a refusal that says why; :func:`summarize_online` checks
that invariant on every case and counts how many answers came straight from the regression,
how many were repaired, and how many were refused.
"""

from __future__ import annotations

import functools
import re
import sys
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from pipeline import load_coefficients
from pipeline.exceptions import (
    ExecutionRefusedError,
    InvalidParameterError,
    NoCertifiedTrajectoryError,
    UnreachableObstacleError,
)
from pipeline.io.parallel import process_map
from pipeline.io.progress import progress_enabled
from pipeline.model.arm import PlanarArm, load_planar_arm
from pipeline.offline.coefficients import Coefficients
from pipeline.online.repair import RepairConfig, generate_certified
from pipeline.validation import check_non_negative, check_positive, check_positive_int
from verify.acceptance.run import arm_for_sweep, chunk_size, load_unchanged

#: The outcomes of one query.
STATUSES = ("certified", "repaired", "refused")


@dataclass(frozen=True)
class OnlineCase:
    """Outcome of one certify-or-repair query.

    Attributes:
        L_m, W_m: Obstacle size [m].
        status: "certified" (the regression's answer certified as is), "repaired", or "refused".
        certified_clearance_m: Certified clearance of the returned trajectory [m] (None if refused).
        regression_certified_clearance_m: Certified clearance of the regression's answer [m] (None if unknown).
        reason: Why it was refused ("" otherwise).
        seconds: Wall time of the query [s].
    """

    L_m: float
    W_m: float
    status: str
    certified_clearance_m: float | None
    regression_certified_clearance_m: float | None
    reason: str
    seconds: float

    def __post_init__(self) -> None:
        check_positive("L_m", self.L_m)
        check_positive("W_m", self.W_m)
        check_non_negative("seconds", self.seconds)
        if self.status not in STATUSES:
            raise InvalidParameterError("status", self.status, f"one of {STATUSES}")
        if (self.status == "refused") != (self.certified_clearance_m is None):
            raise InvalidParameterError(
                "certified_clearance_m", self.certified_clearance_m, "a clearance exactly when the query was answered"
            )

    def to_json(self) -> dict[str, Any]:
        """{"L", "W", "status", "certified_clearance_m", "regression_certified_clearance_m", "reason", "seconds"}."""
        return {
            "L": self.L_m,
            "W": self.W_m,
            "status": self.status,
            "certified_clearance_m": self.certified_clearance_m,
            "regression_certified_clearance_m": self.regression_certified_clearance_m,
            "reason": self.reason,
            "seconds": self.seconds,
        }


def _kind(reason: str) -> str:
    """An execution refusal's reason without its figures, so that equal causes count together:
    "endpoint error at P5 4.2 mm > tolerance 2.0 mm" -> "endpoint error at P5 > tolerance"."""
    return re.sub(r"\s*\(by [^)]*\)|\s-?\d+(\.\d+)?\s*(mm|rad/s\^2|rad/s|rad|N m)", "", reason).strip()


def query(
    coefficients: Coefficients, arm: PlanarArm, length_m: float, width_m: float, config: RepairConfig
) -> OnlineCase:
    """One certify-or-repair query, its outcome recorded rather than raised. The per-query
    certificate always runs: a region map attached to ``coefficients`` is not used (the sweep
    checks the certify-or-repair, not the map)."""
    start = time.perf_counter()
    try:
        answer = generate_certified(
            coefficients, length_m, width_m, arm, out_of_range="ignore", config=config, region_map=None
        )
    except NoCertifiedTrajectoryError as exc:
        return OnlineCase(
            length_m, width_m, "refused", None, exc.certified_clearance_m, exc.reason, time.perf_counter() - start
        )
    except ExecutionRefusedError as exc:  # certified collision-free, but it misses an endpoint or breaks a limit
        reason = "; ".join(_kind(r) for r in exc.reasons)
        return OnlineCase(length_m, width_m, "refused", None, None, reason, time.perf_counter() - start)
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


@functools.lru_cache(maxsize=4)
def _loaded(source: str, sha256: str, urdf: str) -> tuple[Coefficients, PlanarArm]:
    """The worker's coefficients and arm, loaded once per (file, content): a file rewritten under
    the same name is never served from the cache, it is refused (``run.load_unchanged``)."""
    return load_unchanged(source, sha256), load_planar_arm(urdf)


def _query_in_worker(
    source: str, sha256: str, urdf: str, config: RepairConfig, case: tuple[float, float]
) -> OnlineCase:
    coefficients, arm = _loaded(source, sha256, urdf)
    return query(coefficients, arm, case[0], case[1], config)


def run_online_cases(
    source: str,
    cases_m: np.ndarray,
    config: RepairConfig,
    urdf: str | Path | None = None,
    jobs: int = 1,
    progress: bool = True,
    coefficients: Coefficients | None = None,
    arm: PlanarArm | None = None,
) -> list[OnlineCase]:
    """Query every case (L, W) of ``cases_m`` (shape (n, 2) [m]); results in case order whatever ``jobs``.

    Every query runs the per-query certify-or-repair (:func:`query`: no region map, even one
    attached to ``coefficients``).

    Args:
        source: Coefficients file or the paper's name (loaded by each worker process).
        config: Certify-or-repair settings.
        urdf: URDF of the arm (None: the one recorded with the coefficients; ignored if ``arm``
            is given).
        jobs: Processes (1: in this one).
        progress: tqdm progress bar on stderr (only if it is a terminal).
        coefficients, arm: Already loaded objects (optional); ``arm`` must be the coefficients'.
    """
    cases = [(float(length), float(width)) for length, width in np.asarray(cases_m, dtype=float).reshape(-1, 2)]
    loaded = coefficients if coefficients is not None else load_coefficients(source, region_map=None)
    arm = arm if arm is not None else arm_for_sweep(loaded, urdf)
    if jobs == 1:

        def function(case: tuple[float, float]) -> OnlineCase:
            return query(loaded, arm, case[0], case[1], config)

    else:
        function = functools.partial(_query_in_worker, source, loaded.source_sha256, str(arm.urdf_path), config)
    shown = progress_enabled(progress)
    with tqdm(total=len(cases), desc="certify-or-repair", unit="case", disable=not shown, file=sys.stderr) as bar:
        return process_map(
            function,
            cases,
            jobs=jobs,
            chunk_size=chunk_size(len(cases), jobs),
            on_done=lambda done: bar.update(len(done)),
        )


@dataclass(frozen=True)
class OnlineSummary:
    """Counts per status, refusal reasons, and the invariant check of a certify-or-repair sweep.

    Attributes:
        n_cases: Queries.
        n_certified_from_regression, n_repaired, n_refused: Queries per outcome.
        refusal_reasons: Reason (without its parenthesised detail) -> count.
        answers_below_margin: Answers whose certified clearance is below the margin (must be 0).
        min_returned_certified_clearance_m: Smallest certified clearance returned [m] (None: no answer).
        median_query_s, max_query_s: Query wall times [s].
        margin_m: The scene's margin [m].
    """

    n_cases: int
    n_certified_from_regression: int
    n_repaired: int
    n_refused: int
    refusal_reasons: tuple[tuple[str, int], ...]
    answers_below_margin: int
    min_returned_certified_clearance_m: float | None
    median_query_s: float
    max_query_s: float
    margin_m: float

    def __post_init__(self) -> None:
        check_positive_int("n_cases", self.n_cases, minimum=1)
        counts = (self.n_certified_from_regression, self.n_repaired, self.n_refused)
        if min(counts) < 0 or sum(counts) != self.n_cases:
            raise InvalidParameterError("counts", counts, f"non-negative counts adding up to n_cases = {self.n_cases}")
        check_non_negative("margin_m", self.margin_m)

    @property
    def refused_fraction(self) -> float:
        """Fraction of the queries refused."""
        return self.n_refused / self.n_cases

    @property
    def invariant_holds(self) -> bool:
        """Every answer is certified at least the margin (refusals aside)."""
        return self.answers_below_margin == 0

    def to_json(self) -> dict[str, Any]:
        """The "summary" document of ``--json``."""
        return {
            "cases": self.n_cases,
            "certified_from_regression": self.n_certified_from_regression,
            "repaired": self.n_repaired,
            "refused": self.n_refused,
            "refused_fraction": self.refused_fraction,
            "refusal_reasons": dict(self.refusal_reasons),
            "answers_below_margin": self.answers_below_margin,
            "min_returned_certified_clearance_m": self.min_returned_certified_clearance_m,
            "median_query_s": self.median_query_s,
            "max_query_s": self.max_query_s,
            "margin_m": self.margin_m,
        }


def summarize_online(cases: Sequence[OnlineCase], margin_m: float) -> OnlineSummary:
    """Counts per status, refusal reasons, and the invariant check (``cases`` not empty)."""
    if not cases:
        raise InvalidParameterError("cases", cases, "at least one query")
    status = Counter(case.status for case in cases)
    unsafe = [
        case for case in cases if case.status != "refused" and not (case.certified_clearance_m or -1.0) >= margin_m
    ]
    reasons = Counter(case.reason.split(" (")[0] if case.reason else "" for case in cases if case.status == "refused")
    times = np.array([case.seconds for case in cases])
    returned = [case.certified_clearance_m for case in cases if case.certified_clearance_m is not None]
    return OnlineSummary(
        n_cases=len(cases),
        n_certified_from_regression=status["certified"],
        n_repaired=status["repaired"],
        n_refused=status["refused"],
        refusal_reasons=tuple(reasons.items()),
        answers_below_margin=len(unsafe),
        min_returned_certified_clearance_m=min(returned) if returned else None,
        median_query_s=float(np.median(times)),
        max_query_s=float(np.max(times)),
        margin_m=margin_m,
    )


def format_online_report(summary: OnlineSummary, header: str) -> str:
    """The lines printed on stdout, after ``header`` (what was run, on which range)."""
    lines = [
        header,
        f"  certified from the regression {summary.n_certified_from_regression}, repaired {summary.n_repaired}, "
        f"refused {summary.n_refused} ({100 * summary.refused_fraction:.1f} %)",
    ]
    lines += [f"    refused {count}: {reason}" for reason, count in summary.refusal_reasons]
    low = summary.min_returned_certified_clearance_m
    lines.append(
        f"  answers below the {1e3 * summary.margin_m:.1f} mm margin: {summary.answers_below_margin}; "
        f"smallest certified clearance returned: {'n/a' if low is None else f'{1e3 * low:.3f} mm'}"
    )
    lines.append(f"  query time median {1e3 * summary.median_query_s:.1f} ms, max {1e3 * summary.max_query_s:.1f} ms")
    return "\n".join(lines)
