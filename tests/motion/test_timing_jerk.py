"""Jerk of the timings and of a timed trajectory: sigma''' matches finite differences of sigma''
away from the knots, its interval ranges enclose dense samples, the paper timing's is 0, and
TimedTrajectory.jerk matches central differences of TimedTrajectory.ddq (for a rest-to-rest and a
smoothed timing)."""

from __future__ import annotations

import functools

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline import generate, load_coefficients
from pipeline.motion.smooth_timing import smoothed
from pipeline.motion.timed_trajectory import TimedTrajectory
from pipeline.motion.timing import PAPER_TIMING, RestToRestTiming
from pipeline.motion.trajectory import joint_jerks

profiles = st.tuples(st.floats(0.5, 10.0), st.floats(0.05, 1.0), st.floats(0.01, 0.5))


def _timing(profile) -> RestToRestTiming:
    path, scale, share = profile
    return RestToRestTiming(path, scale, share * path / scale)


def _knots(timing: RestToRestTiming) -> np.ndarray:
    """Where sigma changes polynomial: the ends and both ends of the ramps."""
    return np.array([0.0, timing.ramp_s, timing.duration_s - timing.ramp_s, timing.duration_s])


@settings(max_examples=30, deadline=None)
@given(profiles)
def test_rest_to_rest_jerk_matches_finite_differences(profile) -> None:
    timing = _timing(profile)
    h = 1e-6 * timing.duration_s
    tau = np.linspace(0.0, timing.duration_s, 20001)
    away = np.min(np.abs(tau[:, None] - _knots(timing)[None, :]), axis=1) > 2.0 * h
    tau = tau[away]
    central = (timing.ddsigma(tau + h) - timing.ddsigma(tau - h)) / (2.0 * h)
    peak = 6.0 * timing.speed_scale / timing.ramp_s**2  # |sigma'''| at most (at the ramps' ends)
    # sigma'' is a quadratic on each ramp: the central difference is exact up to rounding.
    rounding = 1e-15 * (1.5 * timing.speed_scale / timing.ramp_s) / h
    assert np.all(np.abs(central - timing.dddsigma(tau)) <= 1e-9 * peak + 10.0 * rounding)
    assert np.all(np.abs(timing.dddsigma(tau)) <= peak * (1 + 1e-12))
    middle = (tau > timing.ramp_s) & (tau < timing.duration_s - timing.ramp_s)
    assert np.all(timing.dddsigma(tau[middle]) == 0.0)
    ends = np.array([0.0, timing.duration_s])  # +6 c / r^2 at both ends (sigma'' rises, then falls back)
    assert np.allclose(timing.dddsigma(ends), [peak, peak], rtol=1e-12)


@settings(max_examples=100, deadline=None)
@given(profiles, st.floats(0.0, 1.0), st.floats(0.0, 1.0), st.sampled_from(["any", "on knots"]))
def test_rest_to_rest_jerk_ranges_enclose_dense_samples(profile, a, b, kind) -> None:
    timing = _timing(profile)
    if kind == "on knots":
        knots = _knots(timing)
        lo, hi = sorted((knots[int(a * 3.999)], knots[int(b * 3.999)]))
    else:
        lo, hi = sorted((a * timing.duration_s, b * timing.duration_s))
    low, high = (float(v[0]) for v in timing.jerk_ranges(np.array([lo]), np.array([hi])))
    inner = _knots(timing)[(_knots(timing) >= lo) & (_knots(timing) <= hi)]
    tau = np.concatenate([np.linspace(lo, hi, 5001), inner])
    values = timing.dddsigma(tau)
    tol = 1e-12 * 6.0 * timing.speed_scale / timing.ramp_s**2
    assert low <= high and low <= values.min() + tol and values.max() <= high + tol, (lo, hi, low, high)
    eight = timing.ranges_with_jerk(np.array([lo]), np.array([hi]))
    assert len(eight) == 8 and float(eight[6][0]) == low and float(eight[7][0]) == high


def test_rest_to_rest_jerk_ranges_of_arrays() -> None:
    timing = RestToRestTiming(3.0, 0.7, 0.8)
    lo = np.array([0.0, 0.1, 0.8, 1.0, 0.0, timing.duration_s - 0.3])
    hi = np.array([0.2, 0.8, 2.0, 4.0, timing.duration_s, timing.duration_s])
    low, high = timing.jerk_ranges(lo, hi)
    assert low.shape == lo.shape == high.shape
    for k in range(lo.size):
        values = timing.dddsigma(np.linspace(lo[k], hi[k], 5001))
        assert low[k] <= values.min() + 1e-12 and values.max() <= high[k] + 1e-12


def test_paper_timing_has_no_jerk() -> None:
    timing = PAPER_TIMING.for_path(3.7)
    tau = np.linspace(0.0, 3.7, 101)
    assert np.all(timing.dddsigma(tau) == 0.0) and timing.dddsigma(tau).shape == tau.shape
    low, high = timing.jerk_ranges(np.array([0.0, 1.0]), np.array([2.0, 3.7]))
    assert np.all(low == 0.0) and np.all(high == 0.0)
    assert np.array_equal(timing.knots_s, [0.0, 3.7])
    assert len(timing.ranges_with_jerk(np.array([0.0]), np.array([1.0]))) == 8


def test_rest_to_rest_knots_cover_the_motion() -> None:
    timing = RestToRestTiming(3.0, 0.7, 0.8)
    knots = np.asarray(timing.knots_s)
    assert knots[0] == 0.0 and knots[-1] == timing.duration_s and np.all(np.diff(knots) > 0.0)


@functools.cache
def _trajectory():
    return generate(load_coefficients("paper"), 0.27, 0.09, out_of_range="ignore").trajectory


def _smooth_timing(seed: int, pieces: int, path: float):
    rng = np.random.default_rng(seed)
    durations = rng.uniform(0.05, 0.5, pieces)
    speeds = np.concatenate([[0.0], rng.uniform(0.3, 1.5, pieces - 1), [0.0]])
    u = np.diff(speeds) / durations
    steps = np.diff(np.concatenate([[0.0], u, [0.0]]))
    around = np.minimum(np.concatenate([[np.inf], durations]), np.concatenate([durations, [np.inf]]))
    windows = 0.4 * around * rng.uniform(0.2, 1.0, pieces + 1)
    timing, _ = smoothed(np.concatenate([[0.0], np.cumsum(durations)]), steps, windows, path)
    return timing


def _check_jerk_against_ddq(executed: TimedTrajectory, knots: np.ndarray) -> None:
    h = 1e-5 * executed.duration_s
    tau = np.linspace(0.0, executed.duration_s, 4001)
    away = np.min(np.abs(tau[:, None] - knots[None, :]), axis=1) > 3.0 * h
    tau = tau[away]
    central = (executed.ddq(tau + h) - executed.ddq(tau - h)) / (2.0 * h)
    jerk = executed.jerk(tau)
    assert jerk.shape == (tau.size, 2)
    scale = float(np.abs(jerk).max())
    # Error of the central difference: h^2 |d4q| / 6, with |d4q| below 1e3 |jerk| / T' here; rounding
    # of ddq (1e-15 of it) over 2 h.
    tol = 1e3 * scale * h * h / executed.duration_s + 1e-14 * float(np.abs(executed.ddq(tau)).max()) / h
    assert np.all(np.abs(central - jerk) <= tol + 1e-9 * scale), np.abs(central - jerk).max()
    assert executed.jerk(np.float64(tau[len(tau) // 2])).shape == (2,)


@settings(max_examples=10, deadline=None)
@given(st.floats(0.2, 1.0), st.floats(0.02, 0.5))
def test_timed_jerk_matches_finite_differences_of_ddq_rest_to_rest(scale, share) -> None:
    trajectory = _trajectory()
    path = trajectory.duration_s
    timing = RestToRestTiming(path, scale, share * path / scale)
    _check_jerk_against_ddq(TimedTrajectory(trajectory, timing), _knots(timing))


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(2, 30))
def test_timed_jerk_matches_finite_differences_of_ddq_smooth(seed, pieces) -> None:
    trajectory = _trajectory()
    timing = _smooth_timing(seed, pieces, trajectory.duration_s)
    executed = TimedTrajectory(trajectory, timing)
    _check_jerk_against_ddq(executed, timing.breakpoints_s)


def test_timed_jerk_of_the_paper_timing_is_the_path_jerk() -> None:
    trajectory = _trajectory()
    executed = TimedTrajectory(trajectory, PAPER_TIMING)
    tau = np.linspace(0.0, trajectory.duration_s, 101)
    assert np.allclose(executed.jerk(tau), joint_jerks(trajectory.parameters, tau), rtol=1e-14, atol=1e-14)
