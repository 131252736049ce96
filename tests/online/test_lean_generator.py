"""The lean online generator (pipeline.online.generator) gives the numbers of the straightforward route
(QuarticPath by a Vandermonde solve and a 64-panel Gauss-Legendre arc length, then the family's
``expand``), refuses bad sizes with the project's error naming L and W, and its answers refuse times
outside [0, T] unless asked to clamp."""

from __future__ import annotations

import gc
import math
import pickle
import weakref
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from pipeline import load_coefficients
from pipeline.exceptions import (
    InvalidParameterError,
    ObstacleSizeError,
    PipelineError,
    UnreachableObstacleError,
)
from pipeline.model.kinematics import inverse_kinematics
from pipeline.model.obstacle import Obstacle
from pipeline.motion.families import EndpointContext
from pipeline.motion.path import constraint_points, desired_path
from pipeline.motion.trajectory import JointTrajectory
from pipeline.offline.coefficients import Coefficients
from pipeline.online.generator import generate
from pipeline.online.query_state import state_of


def reference_duration(points: np.ndarray, speed: float) -> float:
    """T of the former implementation: Vandermonde solve, 64 panels x 10-point Gauss-Legendre over [x5, x1]."""
    coefficients = np.linalg.solve(np.vander(points[:, 0], 5), points[:, 1])
    slope = np.polyder(coefficients)
    nodes, weights = np.polynomial.legendre.leggauss(10)
    edges = np.linspace(points[0, 0], points[-1, 0], 65)
    mid, half = (edges[1:] + edges[:-1]) / 2, (edges[:-1] - edges[1:]) / 2
    x = mid[:, None] + half[:, None] * nodes
    return float(np.sum(half * (np.sqrt(1.0 + np.polyval(slope, x) ** 2) @ weights))) / speed


def reference_parameters(coefficients: Coefficients, L: float, W: float) -> tuple[np.ndarray, float]:
    """The 8 parameters and T by the straightforward route."""
    scene = coefficients.scene
    points = constraint_points(Obstacle.in_scene(L, W, scene), scene)
    duration = reference_duration(points, scene.speed_m_s)
    free = coefficients.predict_free(L, W)
    context = None
    if coefficients.family.uses_endpoint_context:
        start = inverse_kinematics(points[0], coefficients.link_lengths_m, coefficients.elbow)
        end = inverse_kinematics(points[-1], coefficients.link_lengths_m, coefficients.elbow)
        context = EndpointContext((start[0], start[1]), (end[0], end[1]), duration)
    return coefficients.family.expand(free, context), duration


def test_same_numbers_as_the_straightforward_route(paper: Coefficients, exact: Coefficients) -> None:
    rng = np.random.default_rng(11)
    sizes = np.column_stack([rng.uniform(0.14, 0.36, 400), rng.uniform(0.05, 0.16, 400)])
    worst_t = worst_p = 0.0
    for coefficients in (paper, exact):
        for L, W in sizes.tolist():
            answer = generate(coefficients, L, W, out_of_range="ignore")
            parameters, duration = reference_parameters(coefficients, L, W)
            worst_t = max(worst_t, abs(answer.duration_s - duration) / duration)
            worst_p = max(worst_p, float(np.max(np.abs(np.array(answer.trajectory.parameters) - parameters))))
    assert worst_t <= 1e-12, worst_t
    assert worst_p <= 1e-12, worst_p


def test_lazy_obstacle_and_path_match_the_answer(paper: Coefficients, rounding) -> None:
    answer = generate(paper, 0.27, 0.09)
    assert "path" not in answer.__dict__ and "obstacle" not in answer.__dict__  # nothing built yet
    scene = paper.scene
    obstacle = Obstacle.in_scene(0.27, 0.09, scene)
    assert answer.obstacle == obstacle
    _, bound = rounding.duration(scene, 0.27, 0.09)
    assert abs(answer.path.duration_s - answer.duration_s) <= bound  # the path's T is the NumPy route's
    assert_allclose(answer.path.points_m, desired_path(obstacle, scene).points_m, rtol=0, atol=0)
    assert answer.path is answer.path  # cached


@settings(max_examples=60, deadline=None)
@given(st.floats(0.03, 0.6), st.floats(0.03, 0.5))
def test_any_size_gives_an_answer_or_a_project_error(L: float, W: float) -> None:
    coefficients = load_coefficients("paper")
    try:
        answer = generate(coefficients, L, W, out_of_range="ignore")
    except PipelineError as exc:
        assert "L = " in str(exc) and "W = " in str(exc), str(exc)
        return
    _, duration = reference_parameters(coefficients, L, W)
    assert math.isclose(answer.duration_s, duration, rel_tol=1e-12)


# --------------------------------------------------------------------------------------------
# Sizes the generator refuses, with messages naming L and W.


@pytest.mark.parametrize(
    ("L", "W", "named"),
    [
        ("0.27", 0.09, "L = '0.27'"),
        (0.27, "0.09", "W = '0.09'"),
        (None, 0.09, "L = None"),
        (True, 0.09, "L = True"),
        ([0.27], 0.09, "L = [0.27]"),
        (float("nan"), 0.09, "L = nan m"),
        (0.27, -0.09, "W = -0.09 m"),
        (0.27, float("inf"), "W = inf m"),
        (0.0, 0.09, "L = 0.0 m"),
    ],
)
def test_bad_sizes_are_refused_naming_L_and_W(paper: Coefficients, L, W, named: str) -> None:
    with pytest.raises(InvalidParameterError) as info:
        generate(paper, L, W)
    message = str(info.value)
    assert isinstance(info.value, ObstacleSizeError)
    assert named in message and "L = " in message and "W = " in message, message


def test_tiny_obstacle_names_L_and_W_not_the_corner_radius(paper: Coefficients) -> None:
    with pytest.raises(ObstacleSizeError) as info:
        generate(paper, 0.001, 0.001)
    message = str(info.value)
    assert "L = 0.001 m" in message and "W = 0.001 m" in message
    assert "corner_radius_m" not in message


def test_numpy_numbers_are_accepted(paper: Coefficients) -> None:
    a = generate(paper, np.float64(0.27), np.float32(0.09))
    b = generate(paper, 0.27, float(np.float32(0.09)))
    assert a.trajectory.parameters == b.trajectory.parameters
    assert generate(paper, 0.25, np.int64(1) / 10).duration_s == generate(paper, 0.25, 0.1).duration_s


def test_base_covered_and_unreachable_name_L_and_W(paper: Coefficients) -> None:
    with pytest.raises(ObstacleSizeError, match=r"L = 0\.25 m, W = 0\.6 m.*covers the arm's base"):
        generate(paper, 0.25, 0.6, out_of_range="ignore")
    with pytest.raises(UnreachableObstacleError, match=r"L = 1\.5 m, W = 0\.1 m") as info:
        generate(paper, 1.5, 0.1, out_of_range="ignore")
    assert info.value.point_name == "P1"


# --------------------------------------------------------------------------------------------
# q, dq, ddq on [0, T] only.


def test_times_outside_the_motion_are_refused_or_clamped(paper: Coefficients) -> None:
    answer = generate(paper, 0.25, 0.1)
    T = answer.duration_s
    for method in (answer.q, answer.dq, answer.ddq, answer.trajectory.q, answer.trajectory.dq, answer.trajectory.ddq):
        for bad in (-1e-9, T * (1 + 1e-12), float("nan"), np.array([0.0, T + 1.0]), np.array([np.nan])):
            with pytest.raises(InvalidParameterError):
                method(bad)
        with pytest.raises(InvalidParameterError):
            method(float("nan"), outside="clamp")
        with pytest.raises(InvalidParameterError):
            method(0.5, outside="extrapolate")
        assert_allclose(method(np.array([-3.0, T + 2.0]), outside="clamp"), method(np.array([0.0, T])), rtol=0, atol=0)
        assert method(0.0).shape == (2,) and method(T).shape == (2,)
    # In range, q is Eq. 1 (independent formula).
    a1, w1, p1, g1, a2, w2, p2, g2 = answer.trajectory.parameters
    t = np.linspace(0.0, T, 9)
    assert_allclose(
        answer.q(t), np.column_stack([a1 * np.sin(w1 * t + p1) + g1, a2 * np.sin(w2 * t + p2) + g2]), rtol=0, atol=1e-15
    )
    with pytest.raises(InvalidParameterError):
        JointTrajectory((0.1,) * 8, 2.0).q("soon")


def test_the_plan_of_coefficients_lives_as_long_as_they_do(paper: Coefficients) -> None:
    """Each coefficients object owns one query state (its plan), made on the first query and
    dropped with it: no state outlives its coefficients, a copy or a pickle starts without one."""
    copy = replace(paper, source="a copy")  # another object, its own plan
    assert copy.online_state is None
    answer = generate(copy, 0.25, 0.1)
    state = copy.online_state
    assert state is state_of(copy) and state.coefficients is copy
    assert state.plan is not state_of(paper).plan
    assert pickle.loads(pickle.dumps(copy)).online_state is None
    assert replace(copy, source="another").online_state is None
    alive = weakref.ref(state)
    del copy, state
    gc.collect()
    assert alive() is None
    # The answer made with the dead coefficients' plan stays whole; without a map its bounds are
    # the fields' defaults, also after a pickle.
    for kept in (answer, pickle.loads(pickle.dumps(answer))):
        assert kept.length_m == 0.25 and kept.trajectory == answer.trajectory
        assert kept.certified_clearance_m is None and kept.certificate_source is None and kept.range_status is None
        assert kept.variables == ()
