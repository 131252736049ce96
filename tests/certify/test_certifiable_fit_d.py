"""The certifiable regression over (L, W, x, d) (pipeline.certify.certifiable_regression with the
obstacle's far edge d): its clearance against the generator's answer and Coal on the moved
obstacle, its Jacobian against finite differences, and the end poses' room against the same room
computed in a scene whose far edge is d (P1 and P5 at y1 = d)."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from pipeline import load_coefficients
from pipeline.certify.end_pose_room import configuration_clearance, end_pose_room_m
from pipeline.geometry.clearance import COAL_DISTANCE_ERROR_M, CoalClearance
from pipeline.model.arm import PlanarArm
from pipeline.motion.trajectory import PARAMETER_NAMES
from pipeline.offline.coefficients import Coefficients
from pipeline.online.generator import generate


@pytest.fixture(scope="module")
def eq9_xd(request) -> Coefficients:
    lift = request.getfixturevalue("over_xd")
    return lift(load_coefficients("paper"), scale=0.02, d_scale=0.2)


def _points(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.column_stack(
        [
            rng.uniform(0.2, 0.3, n),
            rng.uniform(0.08, 0.12, n),
            rng.uniform(-0.03, 0.03, n),
            rng.uniform(0.55, 0.57, n),
            rng.uniform(0.0, 1.0, n),
        ]
    )


def _matrix(coefficients: Coefficients) -> np.ndarray:
    return np.stack([coefficients.parameters[name] for name in PARAMETER_NAMES], -1).ravel()


def test_clearance_is_the_generators_on_the_moved_obstacle(
    eq9_xd: Coefficients, arm: PlanarArm, check_clearance_against_generator
) -> None:
    """clearance_at at (L, W, x, d, s) is the generator's answer's, against its own moved obstacle."""
    check_clearance_against_generator(eq9_xd, _points(30, 0), arm)


def test_clearance_jacobian_matches_finite_differences_over_d(eq9_xd: Coefficients, check_clearance_jacobian) -> None:
    check_clearance_jacobian(eq9_xd, _points(15, 1), np.random.default_rng(2))


def test_end_pose_room_moves_with_the_far_edge(eq9_xd: Coefficients) -> None:
    """The room of an obstacle whose far edge is moved to d equals the room in a scene whose far
    edge (and so y1, P1 and P5) is d, bit for bit; at the scene's d it is the unmoved room."""
    sizes = np.array([[0.2, 0.12, 0.03, 0.55], [0.25, 0.119, -0.02, 0.565], [0.27, 0.09, 0.01, 0.57]])
    room = end_pose_room_m(eq9_xd, sizes[:, 0], sizes[:, 1], 0.002, sizes[:, 2], top_y_m=sizes[:, 3])
    for (L, W, x, d), value in zip(sizes, room, strict=True):
        moved = SimpleNamespace(
            scene=replace(eq9_xd.scene, top_y_m=float(d)),
            link_lengths_m=eq9_xd.link_lengths_m,
            link_radii_m=eq9_xd.link_radii_m,
            elbow=eq9_xd.elbow,
        )
        assert value == end_pose_room_m(moved, np.array([L]), np.array([W]), 0.002, np.array([x]))[0]
    assert not np.array_equal(room, end_pose_room_m(eq9_xd, sizes[:, 0], sizes[:, 1], 0.002, sizes[:, 2]))
    unmoved = np.full(3, eq9_xd.scene.top_y_m)
    assert np.array_equal(
        end_pose_room_m(eq9_xd, sizes[:, 0], sizes[:, 1], 0.002, sizes[:, 2]),
        end_pose_room_m(eq9_xd, sizes[:, 0], sizes[:, 1], 0.002, sizes[:, 2], top_y_m=unmoved),
    )


def test_a_fixed_start_height_keeps_the_end_points(eq9_xd: Coefficients) -> None:
    """With y1 fixed (``start_y_m``), moving d moves the obstacle but not P1 and P5: the room
    equals the one computed in the scene with that d and the same fixed y1."""
    fixed = SimpleNamespace(
        scene=replace(eq9_xd.scene, start_y_m=0.5),
        link_lengths_m=eq9_xd.link_lengths_m,
        link_radii_m=eq9_xd.link_radii_m,
        elbow=eq9_xd.elbow,
    )
    room = end_pose_room_m(fixed, np.array([0.25]), np.array([0.1]), 0.002, top_y_m=np.array([0.57]))[0]
    scene = replace(fixed.scene, top_y_m=0.57)
    assert room == end_pose_room_m(SimpleNamespace(**{**vars(fixed), "scene": scene}), [0.25], [0.1], 0.002)[0]


def test_configuration_clearance_against_coal_with_d(eq9_xd: Coefficients, arm: PlanarArm) -> None:
    rng = np.random.default_rng(4)
    theta = rng.uniform(-np.pi, np.pi, (20, 2))
    sizes = _points(20, 5)
    values = configuration_clearance(theta, sizes, eq9_xd, sizes[:, 2], sizes[:, 3])
    for q, (L, W, x, d, _), value in zip(theta, sizes, values, strict=True):
        answer = generate(eq9_xd, L, W, x=x, d=d, region_map=None)
        assert value == pytest.approx(
            float(CoalClearance(arm, answer.obstacle).link_clearance(q).min()), abs=COAL_DISTANCE_ERROR_M
        )
