"""Timings: the rest-to-rest profile starts and ends at rest, is smooth and monotone, its
derivatives match finite differences, and its interval ranges enclose dense samples."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from pipeline.exceptions import InvalidParameterError
from pipeline.motion.timing import PAPER_TIMING, RestToRestTiming

profiles = st.tuples(st.floats(0.5, 10.0), st.floats(0.05, 1.0), st.floats(0.01, 0.5))


def _timing(profile) -> RestToRestTiming:
    path, scale, share = profile
    return RestToRestTiming(path, scale, share * path / scale)


@settings(max_examples=50, deadline=None)
@given(profiles)
def test_rest_at_both_ends_and_the_whole_path(profile) -> None:
    timing = _timing(profile)
    ends = np.array([0.0, timing.duration_s])
    assert_allclose(timing.sigma(ends), [0.0, timing.path_duration_s], rtol=1e-12, atol=1e-12)
    assert np.all(np.abs(timing.dsigma(ends)) <= 1e-12) and np.all(np.abs(timing.ddsigma(ends)) <= 1e-12)
    assert timing.duration_s == pytest.approx(timing.path_duration_s / timing.speed_scale + timing.ramp_s)
    tau = np.linspace(0.0, timing.duration_s, 20001)
    assert np.all(np.diff(timing.sigma(tau)) >= 0.0)
    assert np.all(timing.dsigma(tau) <= timing.speed_scale + 1e-15)
    assert np.abs(timing.ddsigma(tau)).max() <= 1.5 * timing.speed_scale / timing.ramp_s * (1 + 1e-12)


@settings(max_examples=30, deadline=None)
@given(profiles)
def test_derivatives_match_finite_differences(profile) -> None:
    timing = _timing(profile)
    tau = np.linspace(0.0, timing.duration_s, 400001)
    step = tau[1] - tau[0]
    central = (timing.sigma(tau[2:]) - timing.sigma(tau[:-2])) / (2 * step)
    assert_allclose(central, timing.dsigma(tau[1:-1]), rtol=0, atol=1e-6 * max(1.0, timing.speed_scale))
    second = (timing.dsigma(tau[2:]) - timing.dsigma(tau[:-2])) / (2 * step)
    scale = timing.speed_scale / timing.ramp_s
    assert_allclose(second, timing.ddsigma(tau[1:-1]), rtol=0, atol=1e-3 * scale)


@settings(max_examples=30, deadline=None)
@given(profiles, st.floats(0.0, 1.0), st.floats(0.0, 1.0))
def test_ranges_enclose_every_value_of_the_interval(profile, a, b) -> None:
    timing = _timing(profile)
    lo, hi = sorted((a * timing.duration_s, b * timing.duration_s))
    s_lo, s_hi, d1_lo, d1_hi, d2_lo, d2_hi = (float(v[0]) for v in timing.ranges(np.array([lo]), np.array([hi])))
    tau = np.linspace(lo, hi, 5001)
    assert s_lo <= timing.sigma(tau).min() + 1e-12 and timing.sigma(tau).max() <= s_hi + 1e-12
    assert d1_lo <= timing.dsigma(tau).min() + 1e-12 and timing.dsigma(tau).max() <= d1_hi + 1e-12
    assert d2_lo <= timing.ddsigma(tau).min() + 1e-9 and timing.ddsigma(tau).max() <= d2_hi + 1e-9


def test_the_paper_timing_is_the_identity() -> None:
    timing = PAPER_TIMING.for_path(3.7)
    tau = np.linspace(0, 3.7, 11)
    assert timing.duration_s == 3.7
    assert (
        np.array_equal(timing.sigma(tau), tau) and np.all(timing.dsigma(tau) == 1) and np.all(timing.ddsigma(tau) == 0)
    )


@pytest.mark.parametrize(
    ("arguments", "name"), [((3.7, 1.2, 0.1), "speed_scale"), ((3.7, 0.5, 8.0), "ramp_s"), ((0.0, 0.5, 0.1), "path")]
)
def test_bad_profiles_are_refused(arguments, name) -> None:
    with pytest.raises(InvalidParameterError, match=name):
        RestToRestTiming(*arguments)
