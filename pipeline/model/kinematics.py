"""Planar 2R kinematics in closed form: the paper's Eq. 2, its inverse, and the reach annulus.

These are the formulas the vectorised routes use; :mod:`pipeline.model.arm` proves them equal
to Pinocchio's kinematics of the URDF (tests cross-check both against yourdfpy).
"""

from __future__ import annotations

import numpy as np

from pipeline.exceptions import UnreachableObstacleError


def reach_annulus_m(link_lengths_m: tuple[float, float]) -> tuple[float, float]:
    """Radii of the annulus the tip can reach around joint 1 [m]: (|l1 - l2|, l1 + l2)."""
    l1, l2 = link_lengths_m
    return abs(l1 - l2), l1 + l2


def forward_kinematics(theta_rad: np.ndarray, link_lengths_m: tuple[float, float]) -> np.ndarray:
    """Tip (x, y) [m] of joint angles (..., 2) [rad] by the paper's Eq. 2: shape (..., 2)."""
    theta = np.asarray(theta_rad, dtype=float)
    l1, l2 = link_lengths_m
    a1, a12 = theta[..., 0], theta[..., 0] + theta[..., 1]
    return np.stack([l1 * np.cos(a1) + l2 * np.cos(a12), l1 * np.sin(a1) + l2 * np.sin(a12)], -1)


def _joint_angles(
    x: np.ndarray | float,
    y: np.ndarray | float,
    cos2: np.ndarray | float,
    link_lengths_m: tuple[float, float],
    elbow: int,
) -> tuple[np.ndarray, np.ndarray]:
    """(theta1, theta2) [rad] of tips (x, y) [m] whose cos(theta2) [-] is ``cos2`` (within [-1, 1]):
    scalars or arrays alike, the one arccos/arctan2 step of both inverse kinematics below."""
    l1, l2 = link_lengths_m
    theta2 = elbow * np.arccos(cos2)
    theta1 = np.arctan2(y, x) - np.arctan2(l2 * np.sin(theta2), l1 + l2 * np.cos(theta2))
    return theta1, theta2


def inverse_kinematics(point_m: np.ndarray, link_lengths_m: tuple[float, float], elbow: int = 1) -> np.ndarray:
    """Joint angles [rad] placing the tip at ``point_m`` (x, y) [m]; ``elbow`` = +1 or -1 picks the branch.

    cos(theta2) is taken from ``hypot(x, y) ** 2`` (not ``x * x + y * y`` as in
    :func:`inverse_kinematics_batch`, which differs in the last bits), so the two agree to
    rounding, not bitwise.

    Raises:
        UnreachableObstacleError: the point is outside the reachable annulus.
    """
    l1, l2 = link_lengths_m
    x, y = float(point_m[0]), float(point_m[1])
    radius = float(np.hypot(x, y))
    cos2 = (radius**2 - l1**2 - l2**2) / (2 * l1 * l2)
    if not -1.0 - 1e-12 <= cos2 <= 1.0 + 1e-12:
        raise UnreachableObstacleError("target", radius, reach_annulus_m(link_lengths_m))
    cos2 = min(1.0, max(-1.0, cos2))
    theta1, theta2 = _joint_angles(x, y, cos2, link_lengths_m, elbow)
    return np.array([float(theta1), float(theta2)])


def inverse_kinematics_batch(points_m: np.ndarray, link_lengths_m: tuple[float, float], elbow: int = 1) -> np.ndarray:
    """Joint angles (..., 2) [rad] placing the tip at each of ``points_m`` (..., 2) (x, y) [m]; vectorised.

    ``elbow`` = +1 or -1 picks the branch (theta2 >= 0 or <= 0). No validation: cos(theta2) is
    clipped to [-1, 1], so a point outside the reachable annulus gets the pose whose tip is
    nearest it on the same ray (stretched, theta2 = 0, beyond l1 + l2; folded, |theta2| = pi,
    inside |l1 - l2|). Use :func:`inverse_kinematics` to have such points raise.
    """
    points = np.asarray(points_m, dtype=float)
    l1, l2 = link_lengths_m
    x, y = points[..., 0], points[..., 1]
    cos2 = np.clip((x * x + y * y - l1 * l1 - l2 * l2) / (2 * l1 * l2), -1.0, 1.0)
    theta1, theta2 = _joint_angles(x, y, cos2, link_lengths_m, elbow)
    return np.stack([theta1, theta2], -1)
