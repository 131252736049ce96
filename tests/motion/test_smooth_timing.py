"""The smoothed timing: from random piecewise constant path accelerations that start and end at
rest, :func:`smoothed` gives a C2 sigma from 0 to T, at rest at both ends, monotone, whose
derivatives match finite differences and an independent closed form (the superposition of one
ramp per step), and whose interval ranges enclose dense samples.

The closed form: a step du at time t with window delta becomes du times the ramp
``clip((tau - a) / delta, 0, 1)`` (a = t - delta / 2, all times shifted by half the first window),
whose integrals are h^2 / (2 delta), then h - delta / 2 (sigma'), and h^3 / (6 delta), then
(h - delta / 2)^2 / 2 + delta^2 / 24 (sigma), with h = tau - a.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline.exceptions import InvalidParameterError
from pipeline.motion.smooth_timing import SmoothTiming, smoothed


def _profile(seed: int, pieces: int, window_share: float, zero_steps: bool = False):
    """(step times, steps, windows, T, durations, speeds) of a random rest-to-rest profile."""
    rng = np.random.default_rng(seed)
    durations = rng.uniform(0.02, 1.0, pieces)
    speeds = np.concatenate([[0.0], rng.uniform(0.2, 2.0, pieces - 1), [0.0]])
    if zero_steps and pieces >= 4:  # equal accelerations on neighbouring pieces: steps of exactly 0
        k = rng.integers(1, pieces - 2)
        speeds[k + 1] = speeds[k] + (speeds[k] - speeds[k - 1]) * durations[k] / durations[k - 1]
        speeds[k + 1] = abs(speeds[k + 1]) + 0.2
    u = np.diff(speeds) / durations
    steps = np.diff(np.concatenate([[0.0], u, [0.0]]))
    times = np.concatenate([[0.0], np.cumsum(durations)])
    path = float(np.sum(durations * (speeds[:-1] + speeds[1:]) / 2.0))
    around = np.minimum(np.concatenate([[np.inf], durations]), np.concatenate([durations, [np.inf]]))
    windows = window_share * around * rng.uniform(0.1, 1.0, pieces + 1)
    return times, steps, windows, path, durations, speeds


def _reference(times, steps, windows, tau):
    """(sigma, sigma', sigma'', sigma''') of the unscaled superposition of ramps (module docstring)."""
    start = times + windows[0] / 2.0 - windows / 2.0
    h = tau[:, None] - start[None, :]
    d = windows[None, :]
    inside, after = (h > 0.0) & (h < d), h >= d
    r0 = np.where(inside, 1.0 / d, 0.0)
    r1 = np.where(after, 1.0, np.where(inside, h / d, 0.0))
    r2 = np.where(after, h - d / 2.0, np.where(inside, h * h / (2.0 * d), 0.0))
    r3 = np.where(after, (h - d / 2.0) ** 2 / 2.0 + d * d / 24.0, np.where(inside, h**3 / (6.0 * d), 0.0))
    return tuple((r * steps[None, :]).sum(1) for r in (r3, r2, r1, r0))


def _lowest_reference_speed(times, steps, windows) -> float:
    """min sigma' / max sigma' of the reference between the first and the last window (at dense
    samples and every window's ends): at rest only at the ends, positive between unless it dips."""
    start = times + windows[0] / 2.0
    end = start[-1] + windows[-1] / 2.0
    tau = np.concatenate([np.linspace(0.0, end, 20001), start - windows / 2.0, start + windows / 2.0])
    tau = tau[(tau >= windows[0]) & (tau <= end - windows[-1])]
    speed = _reference(times, steps, windows, tau)[1]
    return float(speed.min() / speed.max())


def _windows_used(times, steps, windows, timing) -> np.ndarray:
    """The given windows, or all of the widest (:func:`smoothed`'s documented fallback, which must be
    taken when sigma' would dip below 0 with the given ones; it is also taken spuriously, on rounding:
    see test_no_fallback_when_the_windows_do_not_overlap)."""
    widest = np.full_like(windows, windows.max())
    if _lowest_reference_speed(times, steps, windows) < -1e-9:
        return widest
    end = times[-1] + windows[0] / 2.0 + windows[-1] / 2.0
    return windows if timing.duration_s == pytest.approx(end, rel=1e-12) else widest


def _rounding(timing: SmoothTiming) -> tuple[float, float, float]:
    """Rounding of sigma, sigma', sigma'' as the cumulative sums build them (1e-12 of the sums of the
    |increments|, each carried on through the next integral): dsigma(T') is exactly 0 and sigma(T')
    exactly T, while the last cubic ends within this (it grows with the jerk, so with narrow windows)."""
    h = np.diff(timing.breakpoints_s)
    end = timing.duration_s
    c1, c2, k = np.abs(timing.start[:, 1]), np.abs(timing.start[:, 2]), np.abs(timing.jerk)
    # The jerk of each segment is a running sum of the ramps' slopes: its rounding (at most the unit
    # roundoff times the sum of the partial sums) persists in every later segment and is integrated
    # over the rest of the motion.
    jerk_drift = 2.3e-16 * float(np.sum(k))
    r2 = 1e-12 * max(1.0, np.sum(k * h)) + jerk_drift * end
    r1 = 1e-12 * max(1.0, np.sum(c2 * h + k * h * h / 2)) + r2 * end + jerk_drift * end**2 / 2
    r0 = 1e-12 * max(1.0, np.sum(c1 * h + c2 * h * h / 2 + k * h**3 / 6)) + r1 * end + jerk_drift * end**3 / 6
    return r0, r1, r2


def _polynomial_at_end(timing: SmoothTiming) -> np.ndarray:
    """(sigma, sigma', sigma'') of each segment's cubic at the segment's right end, (m, 3)."""
    w = np.diff(timing.breakpoints_s)
    c0, c1, c2, k = timing.start[:, 0], timing.start[:, 1], timing.start[:, 2], timing.jerk
    return np.column_stack([c0 + w * (c1 + w * (c2 / 2.0 + w * k / 6.0)), c1 + w * (c2 + w * k / 2.0), c2 + w * k])


profiles = st.tuples(st.integers(0, 2**32 - 1), st.integers(2, 60), st.floats(0.01, 1.0), st.booleans())


@settings(max_examples=40, deadline=None)
@given(profiles)
def test_smoothed_matches_the_superposition_of_ramps(profile) -> None:
    seed, pieces, share, zeros = profile
    times, steps, windows, path, _, _ = _profile(seed, pieces, share, zeros)
    timing, factor = smoothed(times, steps, windows, path)
    windows = _windows_used(times, steps, windows, timing)
    end = times[-1] + windows[0] / 2.0 + windows[-1] / 2.0
    assert timing.duration_s == pytest.approx(end, rel=1e-12)
    assert timing.path_duration_s == path
    # The whole timing is scaled by the factor that puts sigma's end on T; sigma itself moved by
    # du delta^2 / 24 per window.
    rel = max(1e-9, _rounding(timing)[0] / path)
    assert factor == pytest.approx(path / (path + np.sum(steps * windows**2) / 24.0), rel=rel)
    tau = np.concatenate([np.linspace(0.0, timing.duration_s, 5001), timing.breakpoints_s])
    want = _reference(times, steps, windows, tau)
    got = (timing.sigma(tau), timing.dsigma(tau), timing.ddsigma(tau))
    for g, w, r in zip(got, want[:3], _rounding(timing), strict=True):
        scale = max(1.0, float(np.abs(w).max()))
        assert np.allclose(g, factor * w, rtol=0.0, atol=max(1e-9 * scale, r))
    # sigma''' piecewise constant, within the windows' slopes du / delta: equal to their sum
    # (times the factor) away from the breakpoints.
    mid = 0.5 * (timing.breakpoints_s[:-1] + timing.breakpoints_s[1:])
    assert np.array_equal(timing.dddsigma(mid), timing.jerk)
    assert np.allclose(timing.jerk, factor * _reference(times, steps, windows, mid)[3], rtol=1e-9, atol=1e-9)
    slopes = np.abs(steps / windows).sum()
    assert np.all(np.abs(timing.jerk) <= factor * slopes * (1 + 1e-12))
    if np.all(windows == windows.max()):
        # One width for all (the fallback): a box average of sigma'', so sigma ends at T (factor 1).
        assert factor == pytest.approx(1.0, rel=1e-9)


@settings(max_examples=40, deadline=None)
@given(profiles)
def test_rest_at_both_ends_and_the_whole_path(profile) -> None:
    seed, pieces, share, zeros = profile
    times, steps, windows, path, _, _ = _profile(seed, pieces, share, zeros)
    timing, _ = smoothed(times, steps, windows, path)
    ends = np.array([0.0, timing.duration_s])
    assert timing.sigma(ends)[0] == 0.0 and timing.sigma(ends)[1] == path
    assert np.all(timing.dsigma(ends) == 0.0) and np.all(timing.ddsigma(ends) == 0.0)
    assert timing.breakpoints_s[0] == 0.0 and np.all(np.diff(timing.breakpoints_s) > 0.0)
    assert np.array_equal(timing.knots_s, timing.breakpoints_s)
    # The cubics themselves end there too (no jump at T' hidden by the exact end values).
    last = _polynomial_at_end(timing)[-1]
    r0, r1, r2 = _rounding(timing)
    scale = max(1.0, float(np.abs(timing.start[:, 1]).max()))
    assert abs(last[0] - path) <= max(1e-9 * path, r0) and abs(last[1]) <= max(1e-9 * scale, r1)
    assert abs(last[2]) <= max(1e-9 * max(1.0, float(np.abs(timing.start[:, 2]).max())), r2)


@settings(max_examples=40, deadline=None)
@given(profiles)
def test_continuous_through_every_breakpoint(profile) -> None:
    seed, pieces, share, zeros = profile
    times, steps, windows, path, _, _ = _profile(seed, pieces, share, zeros)
    timing, _ = smoothed(times, steps, windows, path)
    left = _polynomial_at_end(timing)[:-1]
    right = timing.start[1:]
    scale = np.maximum(1.0, np.abs(timing.start).max(0))
    assert np.all(np.abs(left - right) <= 1e-9 * scale)
    # And evaluated just either side of each interior breakpoint.
    knots = timing.breakpoints_s[1:-1]
    eps = 1e-10 * timing.duration_s
    slopes = (
        np.abs(timing.start[:, 2]).max() + np.abs(timing.jerk).max() * timing.duration_s,
        np.abs(timing.jerk).max(),
    )
    for f, q in ((timing.dsigma, 1), (timing.ddsigma, 2)):
        assert np.all(
            np.abs(f(knots + eps) - f(knots - eps)) <= 2.0 * eps * slopes[q - 1] * (1 + 1e-6) + 1e-9 * scale[q]
        )


@settings(max_examples=40, deadline=None)
@given(profiles)
def test_monotone_and_unchanged_outside_the_windows(profile) -> None:
    """Windows that do not overlap (at most half of the pieces beside them): sigma' is the average of
    the positive unsmoothed speed over a window, so sigma is non-decreasing; outside every window
    sigma' is the unsmoothed speed (times the factor)."""
    seed, pieces, share, zeros = profile
    times, steps, windows, path, durations, speeds = _profile(seed, pieces, min(share, 0.5), zeros)
    timing, factor = smoothed(times, steps, windows, path)
    windows = _windows_used(times, steps, windows, timing)  # the given ones, or the fallback's
    tau = np.linspace(0.0, timing.duration_s, 20001)
    sigma = timing.sigma(tau)
    assert np.all(np.diff(sigma) >= -4.0 * np.spacing(path))
    assert np.all(timing.dsigma(tau) >= -1e-12)
    assert np.all((sigma >= 0.0) & (sigma <= path))
    shifted = tau - windows[0] / 2.0
    centre = times[None, :]
    outside = np.all(np.abs(shifted[:, None] - centre) > windows[None, :] / 2.0 + 1e-9, axis=1)
    outside &= (shifted > 0.0) & (shifted < times[-1])
    piece = np.clip(np.searchsorted(times, shifted[outside], side="right") - 1, 0, pieces - 1)
    u = np.diff(speeds) / durations
    original = speeds[piece] + u[piece] * (shifted[outside] - times[piece])
    # A few times the rounding estimate: over a long profile with very narrow windows (jerks of 1e5
    # and more) the cumulative sums drift by up to 1.4 times it (seen: 1.6e-8 against 1.1e-8).
    atol = max(1e-9 * speeds.max(), 4.0 * _rounding(timing)[1])
    assert np.allclose(timing.dsigma(tau[outside]), factor * original, rtol=0.0, atol=atol)


@settings(max_examples=30, deadline=None)
@given(profiles)
def test_derivatives_match_finite_differences(profile) -> None:
    seed, pieces, share, zeros = profile
    times, steps, windows, path, _, _ = _profile(seed, pieces, share, zeros)
    timing, _ = smoothed(times, steps, windows, path)
    h = 1e-5 * timing.duration_s
    tau = np.linspace(h, timing.duration_s - h, 20001)
    jerk = float(np.abs(timing.jerk).max())
    acc = float(np.abs(timing.start[:, 2]).max()) + jerk * float(np.diff(timing.breakpoints_s).max())
    rounding = 1e-14 * path / h
    # sigma is C2: the central difference of sigma is off sigma' by at most h^2 max|sigma'''| / 6.
    first = (timing.sigma(tau + h) - timing.sigma(tau - h)) / (2.0 * h)
    assert np.all(np.abs(first - timing.dsigma(tau)) <= h * h * jerk / 6.0 + rounding)
    # sigma'' has kinks: the central difference of sigma' is off by at most h max|sigma'''|.
    second = (timing.dsigma(tau + h) - timing.dsigma(tau - h)) / (2.0 * h)
    assert np.all(np.abs(second - timing.ddsigma(tau)) <= h * jerk + 1e-14 * (1.0 + acc) / h + rounding)
    # sigma''' away from the breakpoints: sigma'' is linear there.
    knots = timing.breakpoints_s
    away = np.min(np.abs(tau[:, None] - knots[None, :]), axis=1) > 2.0 * h
    third = (timing.ddsigma(tau[away] + h) - timing.ddsigma(tau[away] - h)) / (2.0 * h)
    assert np.all(np.abs(third - timing.dddsigma(tau[away])) <= 1e-12 * (1.0 + acc) / h + 1e-9 * jerk)


@st.composite
def intervals(draw):
    seed, pieces, share, zeros = draw(profiles)
    timing, _ = smoothed(*_profile(seed, pieces, share, zeros)[:4])
    knots = timing.breakpoints_s
    end = timing.duration_s

    def point():
        kind = draw(st.sampled_from(["any", "knot", "near knot", "end"]))
        if kind == "knot":
            return float(knots[draw(st.integers(0, knots.size - 1))])
        if kind == "near knot":
            return float(np.clip(knots[draw(st.integers(0, knots.size - 1))] + draw(st.floats(-1e-9, 1e-9)), 0, end))
        if kind == "end":
            return float(draw(st.sampled_from([0.0, end])))
        return draw(st.floats(0.0, 1.0)) * end

    lo, hi = sorted((point(), point()))
    return timing, lo, hi


def _check_enclosure(timing: SmoothTiming, lo: float, hi: float, ranges) -> None:
    knots = timing.breakpoints_s
    inner = knots[(knots > lo) & (knots < hi)]
    tau = np.concatenate([np.linspace(lo, hi, 2001), inner])
    for q, f in enumerate((timing.sigma, timing.dsigma, timing.ddsigma)):
        values = f(tau)
        low, high = float(ranges[2 * q][0]), float(ranges[2 * q + 1][0])
        tol = _rounding(timing)[q]
        assert low <= high and low <= values.min() + tol and values.max() <= high + tol, (q, lo, hi, low, high)
    # sigma''' jumps at breakpoints and its value there is the right-hand one: sample [lo, hi), and
    # hi too when it is not a breakpoint (the range of an interval ending on one is that of the
    # segment before it).
    jerk_tau = tau if hi not in knots else tau[tau < hi]
    if jerk_tau.size:
        values = timing.dddsigma(jerk_tau)
        low, high = float(ranges[6][0]), float(ranges[7][0])
        assert low <= values.min() and values.max() <= high, (lo, hi, low, high)


@settings(max_examples=200, deadline=None)
@given(intervals())
def test_ranges_enclose_dense_samples(case) -> None:
    timing, lo, hi = case
    with_jerk = timing.ranges_with_jerk(np.array([lo]), np.array([hi]))
    assert len(with_jerk) == 8
    plain = timing.ranges(np.array([lo]), np.array([hi]))
    assert all(np.array_equal(a, b) for a, b in zip(plain, with_jerk[:6], strict=True))
    jerk = timing.jerk_ranges(np.array([lo]), np.array([hi]))
    assert np.array_equal(jerk[0], with_jerk[6]) and np.array_equal(jerk[1], with_jerk[7])
    _check_enclosure(timing, lo, hi, with_jerk)


@settings(max_examples=30, deadline=None)
@given(profiles, st.integers(0, 2**32 - 1))
def test_ranges_of_many_intervals_at_once(profile, seed) -> None:
    """Arrays of intervals (as the certificates pass them), some spanning many segments, some ending
    exactly on a breakpoint: each row is the range of its own interval."""
    timing, _ = smoothed(*_profile(*profile)[:4])
    rng = np.random.default_rng(seed)
    knots = timing.breakpoints_s
    a = rng.uniform(0.0, timing.duration_s, 40)
    b = rng.uniform(0.0, timing.duration_s, 40)
    a[:10] = knots[rng.integers(0, knots.size, 10)]
    b[5:20] = knots[rng.integers(0, knots.size, 15)]
    b[20:25] = knots[np.minimum(np.searchsorted(knots, a[20:25], side="right"), knots.size - 1)]
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    ranges = timing.ranges_with_jerk(lo, hi)
    assert all(r.shape == lo.shape for r in ranges)
    for row in range(lo.size):
        _check_enclosure(timing, lo[row], hi[row], [r[row : row + 1] for r in ranges])


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(2, 60))
def test_modest_windows_barely_scale_the_timing(seed, pieces) -> None:
    times, steps, windows, path, _, _ = _profile(seed, pieces, 0.1)
    _, factor = smoothed(times, steps, windows, path)
    assert abs(factor - 1.0) <= 1e-2


def test_a_profile_that_does_not_move_is_refused() -> None:
    with pytest.raises(InvalidParameterError):
        smoothed(np.array([0.0, 1.0]), np.array([0.0, 0.0]), np.array([0.1, 0.1]), 2.0)


def test_no_fallback_when_the_windows_do_not_overlap() -> None:
    times, steps, windows, path, _, _ = _profile(5, 12, 0.5, zero_steps=True)
    assert _lowest_reference_speed(times, steps, windows) > 0.05  # truly positive between the end windows
    timing, _ = smoothed(times, steps, windows, path)
    assert timing.duration_s == pytest.approx(times[-1] + windows[0] / 2.0 + windows[-1] / 2.0, rel=1e-12)


def test_overlapping_ramps_that_reverse_the_motion_fall_back_to_one_width() -> None:
    """A slow peak of speed (0.05) followed at once by a braking step whose wide window lowers sigma'
    by |du| delta / 8 = 0.076 would make sigma' negative: the documented fallback gives every ramp
    the widest width, sigma' stays >= 0 and the factor is 1."""
    times = np.array([0.0, 1.0, 1.01, 1.51, 2.51])
    speeds = np.array([0.0, 0.05, 0.02, 1.0, 0.0])
    u = np.diff(speeds) / np.diff(times)
    steps = np.diff(np.concatenate([[0.0], u, [0.0]]))
    path = float(np.sum(np.diff(times) * (speeds[:-1] + speeds[1:]) / 2.0))
    windows = np.array([0.2, 0.2, 0.02, 0.2, 0.2])
    assert _lowest_reference_speed(times, steps, windows) < -1e-3  # the given windows would reverse it
    timing, factor = smoothed(times, steps, windows, path)
    assert factor == pytest.approx(1.0, rel=1e-9)
    assert timing.duration_s == pytest.approx(times[-1] + windows.max(), rel=1e-12)
    tau = np.linspace(0.0, timing.duration_s, 20001)
    assert np.all(timing.dsigma(tau) >= -1e-12) and np.all(np.diff(timing.sigma(tau)) >= -4.0 * np.spacing(path))
