"""The benchmark's rows of the near time-optimal timing and its peer, TOPP-RA, on the same paths and limits.

**(n*) near-optimal certified, per query** times
``generate_certified(coefficients, L, W, timing=NearOptimal(from_map=False), region_map=m)`` one
query at a time on the bench's obstacles: the regression's path, its clearance (from the map's
cell where it decides, else per query), and the near time-optimal timing
(:mod:`pipeline.motion.near_optimal`) built and certified per query in continuous time against
the limits (the arm's URDF limits with the servo defaults
for acceleration and jerk filled in: ``answer.execution.limits``).

**(tp) toppra (N grid points), per query** times TOPP-RA (:mod:`verify.benchmark.toppra_peer`) on
each (n*) answer's path (``answer.trajectory``) under that answer's limits (speed, acceleration,
torque; TOPP-RA has no jerk limit): the toppra call alone (``ToppraResult.solve_s``: constraints,
set-up and ``compute_parameterization``), not the path's generation nor the check of its output.

The two rows are timed in interleaved passes after untimed warm-up passes (the first of which
gives the paths), as :mod:`verify.benchmark.per_query` times its rows. Besides the times, the
same run measures on every path the duration ratio T'/T_TOPP-RA (ours over TOPP-RA's) and each
method's largest relative excess over a limit, max(0, value / limit - 1), sampled at 100 times its
grid: TOPP-RA's reconstructed motion at 100 x its grid points (:func:`toppra_timing`), ours at 100 x
the number of breakpoints of its timing (``answer.executed.timing.knots_s``), torques from the
closed-form dynamics in both (:func:`sampled_excess`). Ours is certified, so its excess must be 0.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from pipeline.certify.region_map import RegionMap
from pipeline.exceptions import PipelineError
from pipeline.model.arm import PlanarArm
from pipeline.model.dynamics import PlanarDynamics
from pipeline.model.limits import ArmLimits
from pipeline.motion.near_optimal import NearOptimal
from pipeline.motion.timed_trajectory import TimedTrajectory
from pipeline.online.execution import dynamics_of
from pipeline.online.repair import generate_certified

from .results import DEFAULT_TOPPRA_GRIDPOINTS, WARMUP_CALLS
from .toppra_peer import EXCESS_QUANTITIES, ToppraPeerError, ToppraResult, ToppraSettings, toppra_timing

__all__ = [
    "DEFAULT_TOPPRA_GRIDPOINTS",
    "KEY",
    "OURS_EXCESS_QUANTITIES",
    "OVERSAMPLE",
    "TOPPRA_KEY",
    "NearOptimalRows",
    "bench_near_optimal",
    "sampled_excess",
]

#: Key of the near-optimal row.
#: (n*)'s timing: built and certified per query, not read off the map's near-optimal cells.
PER_QUERY = NearOptimal(from_map=False)
KEY = "n_opt"
#: Key of the TOPP-RA row.
TOPPRA_KEY = "toppra"
#: Samples per grid point (TOPP-RA) or per breakpoint of the timing (ours) of the sampled excess.
OVERSAMPLE = 100
#: The quantities of :func:`sampled_excess`, in order: TOPP-RA's and the jerk.
OURS_EXCESS_QUANTITIES: tuple[str, ...] = (*EXCESS_QUANTITIES, "jerk")


def _relative_excess(values: np.ndarray, limits: tuple[float, float]) -> float:
    """max over joints of max(0, max |value_i| / limit_i - 1); 0 for infinite limits."""
    peaks = np.max(np.abs(values), axis=0)
    return max([0.0, *(float(p) / lim - 1.0 for p, lim in zip(peaks, limits, strict=True) if math.isfinite(lim))])


def sampled_excess(
    executed: TimedTrajectory, dynamics: PlanarDynamics, limits: ArmLimits, oversample: int = OVERSAMPLE
) -> tuple[float, float, float, float]:
    """Largest relative excess of ``executed`` over ``limits`` per quantity of
    :data:`OURS_EXCESS_QUANTITIES` (speed, acceleration, torque, jerk), sampled at ``oversample``
    x the number of breakpoints of its timing (``timing.knots_s``) instants uniform over [0, T'];
    torques [N m] from the closed-form dynamics. Each is max(0, value / limit - 1) over joints (0:
    within the limits at every sample)."""
    knots = len(executed.timing.knots_s)
    t = np.linspace(0.0, executed.duration_s, oversample * max(knots, 2))
    q, dq, ddq = executed.states(t)
    torque = dynamics.torque(q, dq, ddq)
    jerk = executed.jerk(t)
    pairs = (
        (dq, limits.velocity_rad_s),
        (ddq, limits.acceleration_rad_s2),
        (torque, limits.effort_n_m),
        (jerk, limits.jerk_rad_s3),
    )
    speed, acceleration, effort, jerk_excess = (_relative_excess(values, bound) for values, bound in pairs)
    return speed, acceleration, effort, jerk_excess


@dataclass(frozen=True)
class NearOptimalRows:
    """What the two rows measured.

    Attributes:
        near_times_s: Every timed (n*) call [s].
        toppra_times_s: Every timed TOPP-RA call [s] (its ``solve_s``).
        answers: (n*)'s answers of the last pass, None where it refused.
        toppra: TOPP-RA's results of the last pass on the answers' paths, None where it failed or
            (n*) refused.
        ours_excess: Per answer, :func:`sampled_excess` of its executed motion (None where refused).
        gridpoints: TOPP-RA's gridpoints.
        passes: Timed passes of each row.
        refusals: (n*) refusals (last pass) by exception name.
        toppra_failures: TOPP-RA failures (last pass), with toppra's reasons.
    """

    near_times_s: tuple[float, ...]
    toppra_times_s: tuple[float, ...]
    answers: tuple[Any, ...]
    toppra: tuple[ToppraResult | None, ...]
    ours_excess: tuple[tuple[float, float, float, float] | None, ...]
    gridpoints: int
    passes: int
    refusals: dict[str, int]
    toppra_failures: tuple[str, ...]

    def duration_ratios(self) -> np.ndarray:
        """T'/T_TOPP-RA per path both timed [1]."""
        return np.array(
            [
                a.duration_s / r.duration_s
                for a, r in zip(self.answers, self.toppra, strict=True)
                if a is not None and r is not None
            ],
            dtype=float,
        )

    def summary(self) -> dict[str, Any]:
        """Plain-JSON figures: the duration ratio (median, min, max over paths) and each method's
        largest sampled relative excess per quantity (None where nothing was measured)."""
        ratios = self.duration_ratios()
        ours = [e for e in self.ours_excess if e is not None]
        peer = [r.excess for r in self.toppra if r is not None]
        near_median = float(np.median(self.near_times_s)) if self.near_times_s else None
        toppra_median = float(np.median(self.toppra_times_s)) if self.toppra_times_s else None
        return {
            "paths": int(ratios.size),
            "toppra_gridpoints": self.gridpoints,
            "oversample": OVERSAMPLE,
            "duration_ratio_median": float(np.median(ratios)) if ratios.size else None,
            "duration_ratio_min": float(np.min(ratios)) if ratios.size else None,
            "duration_ratio_max": float(np.max(ratios)) if ratios.size else None,
            "ours_excess_max": {
                name: (max(e[i] for e in ours) if ours else None) for i, name in enumerate(OURS_EXCESS_QUANTITIES)
            },
            "toppra_excess_max": {
                name: (max(e[i] for e in peer) if peer else None) for i, name in enumerate(EXCESS_QUANTITIES)
            },
            "ours_samples_per_breakpoint": OVERSAMPLE,
            "toppra_samples_per_gridpoint": OVERSAMPLE,
            "per_query_ratio_n_over_toppra": (
                None if near_median is None or not toppra_median else near_median / toppra_median
            ),
            "limits": _limits_json(self.answers),
            "refusals": dict(self.refusals),
            "toppra_failures": list(self.toppra_failures),
        }


def _limits_json(answers: Sequence[Any]) -> list[dict[str, Any]]:
    """The distinct limits the answers were certified against, as plain JSON."""
    found: list[ArmLimits] = []
    for answer in answers:
        if answer is not None and answer.execution.limits not in found:
            found.append(answer.execution.limits)
    return [
        {
            "velocity_rad_s": list(lim.velocity_rad_s),
            "acceleration_rad_s2": list(lim.acceleration_rad_s2),
            "effort_n_m": list(lim.effort_n_m),
            "jerk_rad_s3": list(lim.jerk_rad_s3),
        }
        for lim in found
    ]


def bench_near_optimal(
    coefficients: Any,
    cases: np.ndarray,
    arm: PlanarArm,
    region_map: RegionMap | None,
    repeats: int,
    gridpoints: int = DEFAULT_TOPPRA_GRIDPOINTS,
    *,
    with_toppra: bool = True,
) -> NearOptimalRows:
    """Time (n*) and TOPP-RA per query in ``repeats`` interleaved passes (module docstring), after
    untimed warm-up passes (at least :data:`WARMUP_CALLS` calls each), and measure their durations
    and sampled excesses on the last pass's answers.

    With ``with_toppra`` False (toppra is not installed), only (n*) is timed and measured.
    """
    rows = [(float(length), float(width)) for length, width in np.asarray(cases)[:, :2]]
    dynamics = dynamics_of(arm)
    settings = ToppraSettings(gridpoints=gridpoints, oversample=OVERSAMPLE)
    refusals: dict[str, int] = {}

    def near(length: float, width: float) -> Any:
        try:
            return generate_certified(
                coefficients, length, width, arm, timing=PER_QUERY, region_map=region_map, out_of_range="ignore"
            )
        except PipelineError as exc:
            refusals[type(exc).__name__] = refusals.get(type(exc).__name__, 0) + 1
            return None

    failures: list[str] = []

    def peer(answer: Any) -> ToppraResult | None:
        if answer is None or not with_toppra:
            return None
        try:
            return toppra_timing(answer.trajectory, answer.execution.limits, dynamics, settings)
        except ToppraPeerError as exc:
            failures.append(exc.reason)
            return None

    warm = -(-WARMUP_CALLS // len(rows))
    answers: list[Any] = []
    for _ in range(warm):
        answers = [near(length, width) for length, width in rows]
    for _ in range(warm):
        for answer in answers:
            peer(answer)
    near_times: list[float] = []
    toppra_times: list[float] = []
    results: list[ToppraResult | None] = []
    clock = time.perf_counter
    for _ in range(repeats):
        refusals.clear()
        failures.clear()
        answers = []
        for length, width in rows:
            started = clock()
            answer = near(length, width)
            near_times.append(clock() - started)
            answers.append(answer)
        results = [peer(answer) for answer in answers]
        toppra_times.extend(r.solve_s for r in results if r is not None)
    excess = tuple(
        None if a is None else sampled_excess(a.executed, dynamics, a.execution.limits, OVERSAMPLE) for a in answers
    )
    return NearOptimalRows(
        near_times_s=tuple(near_times),
        toppra_times_s=tuple(toppra_times),
        answers=tuple(answers),
        toppra=tuple(results),
        ours_excess=excess,
        gridpoints=gridpoints,
        passes=repeats,
        refusals=dict(refusals),
        toppra_failures=tuple(failures),
    )
