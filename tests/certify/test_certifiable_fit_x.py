"""The certifiable regression over (L, W, x) (pipeline.certify.certifiable_regression with the
obstacle's centre x): its clearance against the generator's answer and Coal on the moved obstacle,
its Jacobian against finite differences, the end poses' room against Coal at the moved P1 and P5,
and one refit lifting the clearance at points with x != 0 while keeping the endpoint constraint."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pipeline import load_coefficients
from pipeline.certify.certifiable_regression import (
    CertifiableFitConfig,
    clearance_at,
    clearance_points,
    refit,
)
from pipeline.certify.end_pose_room import ROOM_ANGLES, ROOM_RINGS, end_pose_room_m
from pipeline.geometry.clearance import COAL_DISTANCE_ERROR_M, CoalClearance
from pipeline.model.arm import PlanarArm
from pipeline.model.kinematics import inverse_kinematics
from pipeline.model.obstacle import Obstacle
from pipeline.motion.trajectory import PARAMETER_NAMES
from pipeline.offline.coefficients import Coefficients
from pipeline.offline.endpoint_regression import EndpointConstraint, endpoint_errors_m, endpoint_targets


@pytest.fixture(scope="module")
def eq9_x(request) -> Coefficients:
    lift = request.getfixturevalue("over_x")
    return lift(load_coefficients("paper"), scale=0.02)


def _matrix(coefficients: Coefficients) -> np.ndarray:
    return np.stack([coefficients.parameters[name] for name in PARAMETER_NAMES], -1).ravel()


def _points(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.column_stack(
        [rng.uniform(0.2, 0.3, n), rng.uniform(0.08, 0.12, n), rng.uniform(-0.03, 0.03, n), rng.uniform(0.0, 1.0, n)]
    )


def test_clearance_is_the_generators_on_the_moved_obstacle(
    eq9_x: Coefficients, arm: PlanarArm, check_clearance_against_generator
) -> None:
    """clearance_at at (L, W, x, s) is the generator's answer's, against its own moved obstacle."""
    check_clearance_against_generator(eq9_x, _points(40, 0), arm)


def test_clearance_jacobian_matches_finite_differences_over_x(eq9_x: Coefficients, check_clearance_jacobian) -> None:
    check_clearance_jacobian(eq9_x, _points(20, 1), np.random.default_rng(2))


def test_end_pose_room_moves_with_the_obstacle(eq9_x: Coefficients, arm: PlanarArm) -> None:
    """The room at P1 and P5 of an obstacle moved by x is Coal's sampled room at the moved tips
    against the moved obstacle; at x = 0 it is the (L, W) room itself."""
    sizes = np.array([[0.2, 0.12, 0.03], [0.25, 0.119, -0.02], [0.27, 0.09, 0.01]])
    room = end_pose_room_m(eq9_x, sizes[:, 0], sizes[:, 1], 0.002, sizes[:, 2])
    radii = np.linspace(0.0, 0.002, ROOM_RINGS)
    angles = np.linspace(0.0, 2 * np.pi, ROOM_ANGLES, endpoint=False)
    for (L, W, x), value in zip(sizes, room, strict=True):
        moved = replace(eq9_x.scene, centre_x_m=float(x))
        coal = CoalClearance(arm, Obstacle.in_scene(L, W, moved))
        ends = []
        for side in (1.0, -1.0):
            end = np.array([x + side * (L / 2 + moved.start_dx_m), moved.y1_m])
            tips = [end + r * np.array([np.cos(a), np.sin(a)]) for r in radii[::2] for a in angles[::3]]
            poses = [inverse_kinematics(tip, arm.link_lengths_m, eq9_x.elbow) for tip in tips]
            ends.append(max(float(coal.link_clearance(q).min()) for q in poses))
        # The sampled rings here are a subset of end_pose_room_m's: its room is at least theirs.
        assert value >= min(ends) - COAL_DISTANCE_ERROR_M
        assert value <= min(ends) + 2e-4
    flat = end_pose_room_m(eq9_x, sizes[:, 0], sizes[:, 1], 0.002)
    assert np.array_equal(flat, end_pose_room_m(eq9_x, sizes[:, 0], sizes[:, 1], 0.002, np.zeros(3)))


def test_refit_over_x_lifts_the_clearance_and_keeps_the_endpoints(eq9_x: Coefficients) -> None:
    """Points near W = 0.117 m with x != 0 where the lifted Eq. 9 passes between 4 mm and the
    margin: one refit over (L, W, x) holds them at the margin, with the endpoint errors at its
    (L, W, x) grid within the fit tolerance."""
    rng = np.random.default_rng(3)
    runs = np.column_stack([rng.uniform(0.2, 0.3, 40), rng.uniform(0.08, 0.12, 40), rng.uniform(-0.03, 0.03, 40)])
    values = dict(zip(PARAMETER_NAMES, (eq9_x.predict_free(*runs[:, :2].T, x=runs[:, 2])).T, strict=True))
    grid = np.array(
        [[L, 0.117, x, s] for L in (0.2, 0.25) for x in np.linspace(-0.03, 0.03, 13) for s in np.linspace(0, 1, 21)]
    )
    near = clearance_at(_matrix(eq9_x), clearance_points(eq9_x, grid), eq9_x)
    points = grid[(near > 0.004) & (near < 0.0105) & (grid[:, 2] != 0.0)]
    assert len(points) >= 4 and np.any(points[:, 2] < 0) and np.any(points[:, 2] > 0)
    data = clearance_points(eq9_x, points)
    constraint = EndpointConstraint(tolerance_m=0.06, grid_points=3, max_iterations=200, ftol=1e-9)
    config = CertifiableFitConfig(endpoint=constraint)
    targets = endpoint_targets(eq9_x.fitted_range_m, eq9_x.scene, eq9_x.link_lengths_m, 3, eq9_x.variables)
    fitted, converged = refit(eq9_x, runs, values, targets, data, 0.0105, config)
    assert converged
    assert fitted.variables == eq9_x.variables
    after = clearance_at(_matrix(fitted), data, fitted)
    assert np.min(after) >= 0.0105 - 1e-6
    errors = endpoint_errors_m(targets.design() @ _matrix(fitted).reshape(-1, 8), targets)
    assert np.max(errors) <= constraint.fit_tolerance_m + 1e-9
