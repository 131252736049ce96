"""pipeline.geometry.segment_distance: the compiled segment-to-rectangle distance gives the same
doubles as the vectorised NumPy form written out below (bit for bit, on random segments and on
the degenerate ones: points, axis-parallel segments, segments through and along the rectangle),
and lies within rounding of a dense sampling of the segment, which no vertex rule enters."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline.geometry.segment_distance import segment_rectangle_distance


def _dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[..., 0] * v[..., 0] + u[..., 1] * v[..., 1]


def numpy_distance(a: np.ndarray, b: np.ndarray, center: np.ndarray, half: np.ndarray) -> np.ndarray:
    """The vectorised form: vertex rule and slab test, one NumPy operation per step."""
    a, b = np.asarray(a, float) - center, np.asarray(b, float) - center
    half = np.asarray(half, float)

    def to_rectangle(p: np.ndarray) -> np.ndarray:
        excess = np.maximum(np.abs(p) - half, 0.0)
        return np.sqrt(_dot(excess, excess))

    def to_segment(c: np.ndarray) -> np.ndarray:
        ab = b - a
        length2 = _dot(ab, ab)
        s = np.clip(_dot(c - a, ab) / np.where(length2 > 0, length2, 1.0), 0.0, 1.0)
        offset = c - (a + s[..., None] * ab)
        return np.sqrt(_dot(offset, offset))

    best = np.minimum(to_rectangle(a), to_rectangle(b))
    for sx, sy in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
        best = np.minimum(best, to_segment(half * np.array([sx, sy])))
    direction = b - a
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (-half - a) / direction, (half - a) / direction
    inside = np.abs(a) <= half
    lo = np.where(direction == 0.0, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2))
    hi = np.where(direction == 0.0, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2))
    enter = np.maximum(np.maximum(lo[..., 0], lo[..., 1]), 0.0)
    leave = np.minimum(np.minimum(hi[..., 0], hi[..., 1]), 1.0)
    return np.where(enter <= leave, 0.0, best)


def sampled_distance(a: np.ndarray, b: np.ndarray, center: np.ndarray, half: np.ndarray, n: int = 20001) -> float:
    """Minimum over n points of the segment of their distance to the rectangle (0 inside)."""
    s = np.linspace(0.0, 1.0, n)[:, None]
    points = a + s * (b - a) - center
    excess = np.maximum(np.abs(points) - half, 0.0)
    return float(np.min(np.hypot(excess[:, 0], excess[:, 1])))


def random_rows(rng: np.random.Generator, n: int) -> tuple[np.ndarray, ...]:
    a = rng.uniform(-0.6, 0.6, (n, 2))
    b = rng.uniform(-0.6, 0.6, (n, 2))
    center = rng.uniform(-0.1, 0.1, (n, 2)) + [0.0, 0.45]
    half = rng.uniform(0.0, 0.2, (n, 2))
    return a, b, center, half


def test_same_doubles_as_the_numpy_form_on_random_segments() -> None:
    a, b, center, half = random_rows(np.random.default_rng(0), 20000)
    compiled = segment_rectangle_distance(a, b, center, half)
    assert np.array_equal(compiled, numpy_distance(a, b, center, half))
    assert 0.05 < np.mean(compiled == 0.0) < 0.95  # both branches are exercised


def test_same_doubles_on_degenerate_segments() -> None:
    center, half = np.array([0.1, 0.4]), np.array([0.15, 0.05])
    cases = [
        ([0.0, 0.0], [0.0, 0.0]),  # a point outside
        ([0.1, 0.4], [0.1, 0.4]),  # a point inside
        ([0.0, 0.2], [0.3, 0.2]),  # parallel to x, below
        ([0.0, 0.4], [0.3, 0.4]),  # parallel to x, through
        ([-0.05, 0.0], [-0.05, 0.9]),  # along the rectangle's left edge
        ([0.25, 0.45], [0.5, 0.45]),  # starting on its right edge
        ([0.25 + 1e-300, 0.2], [0.25 + 1e-300, 0.6]),  # a tiny offset from an edge
        ([0.0, 0.0], [1e-310, 1e-310]),  # a subnormal direction
    ]
    a = np.array([c[0] for c in cases])
    b = np.array([c[1] for c in cases])
    compiled = segment_rectangle_distance(a, b, center, half)
    assert np.array_equal(compiled, numpy_distance(a, b, center, half))
    assert compiled[1] == 0.0 and compiled[3] == 0.0 and compiled[5] == 0.0
    assert compiled[4] <= 1e-16  # on the edge, up to the rounding of -0.05 - 0.1
    assert compiled[2] == pytest.approx(0.15, abs=1e-15)


def test_broadcasting_and_shapes() -> None:
    rng = np.random.default_rng(1)
    a, b = rng.uniform(-0.5, 0.5, (3, 4, 2)), rng.uniform(-0.5, 0.5, (3, 4, 2))
    center, half = np.array([0.0, 0.4]), np.array([0.1, 0.05])
    out = segment_rectangle_distance(a, b, center, half)
    assert out.shape == (3, 4)
    assert np.array_equal(out, numpy_distance(a, b, center, half))
    assert segment_rectangle_distance(a[0, 0], b[0, 0], center, half).shape == ()


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.floats(-0.6, 0.6), min_size=4, max_size=4),
    st.lists(st.floats(-0.1, 0.1), min_size=2, max_size=2),
    st.lists(st.floats(0.0, 0.2), min_size=2, max_size=2),
)
def test_within_rounding_of_a_dense_sampling(ends: list[float], offset: list[float], half: list[float]) -> None:
    a, b = np.array(ends[:2]), np.array(ends[2:])
    center, half_ = np.array(offset) + [0.0, 0.3], np.array(half)
    exact = float(segment_rectangle_distance(a, b, center, half_))
    sampled = sampled_distance(a, b, center, half_)
    step = float(np.hypot(*(b - a))) / 20000
    assert exact <= sampled + 1e-12  # the minimum is no larger than any sample
    assert sampled <= exact + step / 2 + 1e-12  # and a sample lies within half a step of it
