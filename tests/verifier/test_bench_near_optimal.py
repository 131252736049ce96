"""The bench's rows (n*) and TOPP-RA (verify.benchmark.near_optimal): both timed per query after a
warm-up, on the same paths and the same limits (the answers' ``execution.limits``), the duration
ratio T'/T_TOPP-RA per path, and the sampled excess over the limits: 0 for our certified motion,
and what a tighter limit would show. No timing is asserted: these machines are noisy."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from pipeline import load_coefficients
from pipeline.model.limits import ArmLimits
from pipeline.offline.coefficients import Coefficients
from pipeline.online.execution import dynamics_of
from verify.benchmark import near_optimal as near
from verify.benchmark.results import WARMUP_CALLS
from verify.benchmark.toppra_peer import ToppraSettings, toppra_timing

CASES = np.array([[0.22, 0.09], [0.27, 0.11]])


@pytest.fixture(scope="module")
def paper() -> Coefficients:
    return load_coefficients("paper")


@pytest.fixture(scope="module")
def rows(paper: Coefficients, arm) -> near.NearOptimalRows:
    pytest.importorskip("toppra")
    return near.bench_near_optimal(paper, CASES, arm, None, repeats=2, gridpoints=30)


def test_both_rows_are_timed_per_query_on_the_same_paths_and_limits(rows: near.NearOptimalRows, arm) -> None:
    assert len(rows.near_times_s) == 2 * 2 and len(rows.toppra_times_s) == 2 * 2  # 2 passes over 2 obstacles
    assert all(t > 0.0 for t in rows.near_times_s + rows.toppra_times_s)
    assert rows.refusals == {} and rows.toppra_failures == ()
    for answer, result in zip(rows.answers, rows.toppra, strict=True):
        limits = answer.execution.limits
        assert all(math.isfinite(j) for j in limits.jerk_rad_s3)  # the servo defaults filled in
        again = toppra_timing(answer.trajectory, limits, dynamics_of(arm), ToppraSettings(30, near.OVERSAMPLE))
        assert again.duration_s == result.duration_s and again.excess == result.excess
        assert result.samples == 30 * near.OVERSAMPLE


def test_summary_gives_the_duration_ratios_and_each_methods_largest_excess(rows: near.NearOptimalRows) -> None:
    summary = rows.summary()
    ratios = [a.duration_s / r.duration_s for a, r in zip(rows.answers, rows.toppra, strict=True)]
    assert summary["paths"] == 2 and summary["toppra_gridpoints"] == 30
    assert summary["duration_ratio_median"] == pytest.approx(float(np.median(ratios)), rel=1e-15)
    assert summary["duration_ratio_max"] == max(ratios) and summary["duration_ratio_min"] == min(ratios)
    assert summary["ours_excess_max"] == {"speed": 0.0, "acceleration": 0.0, "torque": 0.0, "jerk": 0.0}  # certified
    assert summary["toppra_excess_max"] == {
        name: max(r.excess[k] for r in rows.toppra) for k, name in enumerate(("speed", "acceleration", "torque"))
    }
    assert summary["limits"] == [
        {
            "velocity_rad_s": list(rows.answers[0].execution.limits.velocity_rad_s),
            "acceleration_rad_s2": list(rows.answers[0].execution.limits.acceleration_rad_s2),
            "effort_n_m": list(rows.answers[0].execution.limits.effort_n_m),
            "jerk_rad_s3": list(rows.answers[0].execution.limits.jerk_rad_s3),
        }
    ]
    assert summary["per_query_ratio_n_over_toppra"] == pytest.approx(
        np.median(rows.near_times_s) / np.median(rows.toppra_times_s)
    )


def test_sampled_excess_samples_100_per_breakpoint_and_measures_a_tighter_limit(
    rows: near.NearOptimalRows, arm
) -> None:
    answer = rows.answers[0]
    executed, limits, dynamics = answer.executed, answer.execution.limits, dynamics_of(arm)
    assert near.sampled_excess(executed, dynamics, limits) == (0.0, 0.0, 0.0, 0.0)
    t = np.linspace(0.0, executed.duration_s, near.OVERSAMPLE * len(executed.timing.knots_s))
    _, dq, _ = executed.states(t)
    peak = np.max(np.abs(dq), axis=0)
    tighter = dataclasses.replace(limits, velocity_rad_s=tuple(0.5 * peak))
    speed, acceleration, torque, jerk = near.sampled_excess(executed, dynamics, tighter)
    assert speed == pytest.approx(1.0, rel=1e-12) and (acceleration, torque, jerk) == (0.0, 0.0, 0.0)
    unlimited = ArmLimits()  # infinite limits: no excess
    assert near.sampled_excess(executed, dynamics, unlimited) == (0.0, 0.0, 0.0, 0.0)


def test_warm_up_comes_first_and_without_toppra_only_n_star_runs(
    paper: Coefficients, arm, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls: list[tuple[float, float]] = []
    real = near.generate_certified

    def recording(coefficients, length, width, *given, **options):
        calls.append((length, width))
        return real(coefficients, length, width, *given, **options)

    monkeypatch.setattr(near, "generate_certified", recording)
    found = near.bench_near_optimal(paper, CASES, arm, None, repeats=1, with_toppra=False)
    warm = -(-WARMUP_CALLS // len(CASES)) * len(CASES)
    assert len(calls) == warm + len(CASES) and all(type(v) is float for call in calls for v in call)
    assert found.toppra == (None, None) and found.toppra_times_s == ()
    summary = found.summary()
    assert summary["paths"] == 0 and summary["duration_ratio_median"] is None
    assert summary["toppra_excess_max"] == {"speed": None, "acceleration": None, "torque": None}
    assert summary["ours_excess_max"]["speed"] == 0.0


def test_a_refusal_is_counted_not_raised(paper: Coefficients, arm) -> None:
    found = near.bench_near_optimal(paper, np.array([[0.25, 0.1], [0.9, 0.1]]), arm, None, 1, with_toppra=False)
    assert found.answers[1] is None and found.refusals == {"UnreachableObstacleError": 1}
    assert found.ours_excess[1] is None and found.ours_excess[0] is not None
