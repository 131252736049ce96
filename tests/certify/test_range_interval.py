"""Interval arithmetic and jets (pipeline.certify.interval), and the rigorous enclosures of
T(L, W) (pipeline.certify.duration) against the path module's own arc length and finite
differences of it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline.certify.duration import DurationModel, duration_at
from pipeline.certify.interval import Interval, Jet, lower_bound, upper_bound
from pipeline.exceptions import InvalidParameterError
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.motion.path import desired_path

finite = st.floats(-20.0, 20.0, allow_nan=False)
width = st.floats(0.0, 8.0, allow_nan=False)


def _samples(x: Interval, n: int = 41) -> np.ndarray:
    return np.linspace(x.lo, x.hi, n)


@settings(max_examples=200, deadline=None)
@given(a=finite, wa=width, b=finite, wb=width)
def test_interval_operations_contain_every_pointwise_result(a: float, wa: float, b: float, wb: float) -> None:
    x, y = Interval(a, a + wa), Interval(b, b + wb)
    xs, ys = np.meshgrid(_samples(x), _samples(y))

    # Round-to-nearest: results may miss by a few ulps (the module docstring's rounding policy).
    def tol(values: np.ndarray) -> np.ndarray:
        return 1e-12 * np.maximum(1.0, np.abs(values))

    for result, values in (
        (x + y, xs + ys),
        (x - y, xs - ys),
        (x * y, xs * ys),
        (x.square(), xs**2),
        (x.sin(), np.sin(xs)),
        (x.cos(), np.cos(xs)),
    ):
        assert np.all(values >= result.lo - tol(values)) and np.all(values <= result.hi + tol(values))
    if b >= 1e-6:  # away from overflow: the certificate's quantities are of order 1e-3..1e3
        ratio, values = x / y, xs / ys
        assert np.all(values >= ratio.lo - tol(values)) and np.all(values <= ratio.hi + tol(values))


def test_sin_range_is_exact_at_peaks_and_troughs() -> None:
    s = Interval(np.array([0.0, 1.0, 3.0, -2.0]), np.array([math.pi, 1.2, 5.0, 10.0])).sin()
    assert s.hi[0] == 1.0 and s.lo[0] == pytest.approx(0.0, abs=1e-15)
    assert s.lo[1] == pytest.approx(math.sin(1.0)) and s.hi[1] == pytest.approx(math.sin(1.2))
    assert s.lo[2] == -1.0 and s.hi[2] == pytest.approx(math.sin(3.0))
    assert (s.lo[3], s.hi[3]) == (-1.0, 1.0)


def test_sqrt_of_a_negative_interval_is_refused() -> None:
    with pytest.raises(InvalidParameterError):
        Interval(-1.0, 1.0).sqrt()


def _function(x: Jet, y: Jet) -> Jet:
    """A composite of every jet operation: sqrt(1 + (x sin(y))^2) / (2 + cos(x y)) - x^2."""
    return ((x * y.sin()).square() + 1.0).sqrt() / ((x * y).cos() + 2.0) - x.square()


def _plain(x: float, y: float) -> float:
    return math.sqrt(1 + (x * math.sin(y)) ** 2) / (math.cos(x * y) + 2) - x * x


@settings(max_examples=60, deadline=None)
@given(x0=st.floats(-2.0, 2.0), y0=st.floats(-2.0, 2.0), r=st.floats(1e-4, 0.1))
def test_second_order_jets_enclose_value_gradient_and_hessian(x0: float, y0: float, r: float) -> None:
    """Value, finite-difference gradient and Hessian at points of the box lie in the box jet."""
    box = _function(Jet.variable(x0, r, 0, 2, order=2), Jet.variable(y0, r, 1, 2, order=2))
    h = 1e-4
    for u, v in np.random.default_rng(0).uniform(-r, r, (15, 2)) + (x0, y0):
        f = _plain(u, v)
        fx = (_plain(u + h, v) - _plain(u - h, v)) / (2 * h)
        fy = (_plain(u, v + h) - _plain(u, v - h)) / (2 * h)
        fxy = (_plain(u + h, v + h) - _plain(u + h, v - h) - _plain(u - h, v + h) + _plain(u - h, v - h)) / (4 * h * h)
        assert box.value.lo - 1e-12 <= f <= box.value.hi + 1e-12
        for k, g in enumerate((fx, fy)):
            assert box.grad.lo[k] - 1e-6 <= g <= box.grad.hi[k] + 1e-6
        assert box.hess.lo[0, 1] - 1e-3 <= fxy <= box.hess.hi[0, 1] + 1e-3


def test_mean_value_bounds_are_sound_and_tighten_quadratically() -> None:
    """lower/upper_bound enclose the true range; their excess shrinks ~4x per halving."""
    excess = []
    for r in (0.02, 0.01, 0.005):
        center = np.array([0.7, -0.3])
        point = _function(Jet.variable(center[0], 0.0, 0, 2), Jet.variable(center[1], 0.0, 1, 2))
        box = _function(Jet.variable(center[0], r, 0, 2), Jet.variable(center[1], r, 1, 2))
        grid = np.linspace(-r, r, 81)
        values = np.array([[_plain(center[0] + a, center[1] + b) for b in grid] for a in grid])
        lo, hi = lower_bound(point, box, np.array([r, r])), upper_bound(point, box, np.array([r, r]))
        assert lo <= values.min() and values.max() <= hi
        excess.append(values.min() - lo)
    assert excess[0] / excess[1] > 3.0 and excess[1] / excess[2] > 3.0


def _path_duration(L: float, W: float, scene: Scene) -> float:
    """T from the path module (64-panel Gauss-Legendre on x), independent of the certificate's."""
    return desired_path(Obstacle.in_scene(L, W, scene), scene).duration_s


def test_duration_and_gradient_match_the_path_module() -> None:
    scene = Scene()
    rng = np.random.default_rng(3)
    L, W = rng.uniform(0.2, 0.3, 12), rng.uniform(0.08, 0.12, 12)
    value, grad = duration_at(L, W, scene)
    assert np.all(value.rad < 1e-9)
    h = 1e-6
    for k in range(L.size):
        assert value.mid[k] == pytest.approx(_path_duration(L[k], W[k], scene), abs=1e-12)
        d_l = (_path_duration(L[k] + h, W[k], scene) - _path_duration(L[k] - h, W[k], scene)) / (2 * h)
        d_w = (_path_duration(L[k], W[k] + h, scene) - _path_duration(L[k], W[k] - h, scene)) / (2 * h)
        assert grad.mid[k] == pytest.approx([d_l, d_w], abs=1e-7)


def test_duration_jet_encloses_t_and_its_gradient_over_boxes() -> None:
    scene = Scene(apex_dy_m=0.09)  # not the paper's numbers: nothing is tuned to them
    model = DurationModel(scene, (0.2, 0.3), (0.08, 0.12), grid=16)
    rng = np.random.default_rng(4)
    centers = np.column_stack([rng.uniform(0.21, 0.29, 10), rng.uniform(0.09, 0.11, 10)])
    radius = np.column_stack([rng.uniform(1e-4, 5e-3, 10), rng.uniform(1e-4, 5e-3, 10)])
    jet = model.jet(centers, radius, k=2)
    h = 1e-6
    for k in range(10):
        for u, v in centers[k] + radius[k] * rng.uniform(-1, 1, (8, 2)):
            t = _path_duration(u, v, scene)
            assert jet.value.lo[k] <= t <= jet.value.hi[k]
            d_l = (_path_duration(u + h, v, scene) - _path_duration(u - h, v, scene)) / (2 * h)
            d_w = (_path_duration(u, v + h, scene) - _path_duration(u, v - h, scene)) / (2 * h)
            assert jet.grad.lo[k, 0] - 1e-7 <= d_l <= jet.grad.hi[k, 0] + 1e-7
            assert jet.grad.lo[k, 1] - 1e-7 <= d_w <= jet.grad.hi[k, 1] + 1e-7


def test_duration_at_a_node_does_not_depend_on_its_batch() -> None:
    """T at (L, W) is the same to the bit alone, in any batch and at any position in it, and the
    jet of boxes that share a node (boxes along s) equals the jet of that node's box alone: the
    map's bytes must not depend on how its boxes were chunked or spread over workers."""
    scene = Scene()
    rng = np.random.default_rng(11)
    L, W = rng.uniform(0.2, 0.3, 257), rng.uniform(0.08, 0.12, 257)
    value, grad = duration_at(L, W, scene)
    for k in (0, 1, 5, 128, 256):
        alone_value, alone_grad = duration_at(L[k : k + 1], W[k : k + 1], scene)
        assert alone_value.lo[0] == value.lo[k] and alone_value.hi[0] == value.hi[k]
        assert np.array_equal(alone_grad.lo[0], grad.lo[k]) and np.array_equal(alone_grad.hi[0], grad.hi[k])
    shifted_value, _ = duration_at(L[3:], W[3:], scene)
    assert np.array_equal(shifted_value.lo, value.lo[3:])
    model = DurationModel(scene, (0.2, 0.3), (0.08, 0.12), grid=16)
    node = np.array([[0.25, 0.1, 0.5]])
    radius = np.array([[1e-3, 1e-3, 0.1]])
    centers = np.vstack([np.repeat(node, 3, axis=0) + [[0, 0, -0.2], [0, 0, 0], [0, 0, 0.2]], [[0.21, 0.09, 0.5]]])
    radii = np.repeat(radius, 4, axis=0)
    shared, single = model.jet(centers, radii), model.jet(node, radius)
    for k in range(3):
        assert shared.value.lo[k] == single.value.lo[0] and shared.value.hi[k] == single.value.hi[0]
        assert np.array_equal(shared.grad.lo[k], single.grad.lo[0])
    assert shared.value.lo[3] != shared.value.lo[0]


def test_duration_model_refuses_boxes_outside_its_range_and_bad_grids() -> None:
    model = DurationModel(Scene(), (0.2, 0.3), (0.08, 0.12), grid=4)
    with pytest.raises(InvalidParameterError):
        model.jet(np.array([[0.35, 0.1]]), np.array([[0.01, 0.01]]))
    with pytest.raises(InvalidParameterError):
        DurationModel(Scene(), (0.2, 0.3), (0.08, 0.12), grid=3)
