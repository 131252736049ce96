"""How far each link's collision geometry reaches, and the speed bound it gives on every link point.

Joint axes are parallel (z). Let ``rho_1`` bound the distance of any point of link 1's collision
geometry from joint axis 1 (a capsule of length ``l1`` and radius ``r1``: ``rho_1 = l1 + r1``),
``e`` the distance between the two joint axes (``l1``) and ``rho_2`` the same bound for link 2
about joint axis 2 (``l2 + r2``). With joint rates ``w_i = dtheta_i/dt``:

* a point p of link 1 moves at ``|w_1| |p|_perp <= |w_1| rho_1``;
* a point p of link 2 moves at ``v = w_1 z x (p - o) + w_2 z x (p - elbow)``, so
  ``|v| <= |w_1| (e + rho_2) + |w_2| rho_2``, and also, writing
  ``v = w_1 z x (elbow - o) + (w_1 + w_2) z x (p - elbow)``, ``|v| <= |w_1| e + |w_1 + w_2| rho_2``.
  The smaller of the two is used.

:func:`link_point_speed_bounds` evaluates both for bounds on ``|w_1|``, ``|w_2|`` and
``|w_1 + w_2|`` over a time interval, inflated by a relative 1e-9 against rounding; every
certificate (sinusoids, polylines) takes its point speeds from here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pipeline.model.arm import PlanarArm
from pipeline.validation import check_non_negative, check_positive

#: Relative inflation of every speed bound against rounding.
SPEED_SLACK = 1.0 + 1e-9


@dataclass(frozen=True)
class LinkReach:
    """Geometry of the speed bound: how far each link's collision geometry reaches.

    Attributes:
        link1_radius_m: rho_1, max distance of a point of link 1's geometry from joint axis 1 [m].
        elbow_distance_m: e, distance between joint axis 1 and joint axis 2 [m].
        link2_radius_m: rho_2, max distance of a point of link 2's geometry from joint axis 2 [m].
    """

    link1_radius_m: float
    elbow_distance_m: float
    link2_radius_m: float

    def __post_init__(self) -> None:
        check_positive("link1_radius_m", self.link1_radius_m)
        check_non_negative("elbow_distance_m", self.elbow_distance_m)
        check_positive("link2_radius_m", self.link2_radius_m)

    @classmethod
    def from_arm(cls, arm: PlanarArm) -> LinkReach:
        """Read the reach off the arm's collision geometry (capsules exactly, other shapes by AABB)."""
        data = arm.model.createData()
        pin.forwardKinematics(arm.model, data, np.zeros(arm.model.nq))
        radii = []
        for joint_id, ids in zip((1, 2), arm.link_geometry_ids, strict=True):
            axis = data.oMi[joint_id].rotation.T @ arm.axis
            radii.append(max(_geometry_reach(arm.collision_model.geometryObjects[i], axis) for i in ids))
        return cls(radii[0], float(arm.link_lengths_m[0]), radii[1])


def _perp(points: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Distance of points (..., 3) from the line through the origin along unit ``axis``."""
    return np.linalg.norm(points - np.outer(points @ axis, axis), axis=-1)


def _geometry_reach(geometry_object: pin.GeometryObject, axis: np.ndarray) -> float:
    """Max distance [m] of a point of the geometry from the joint axis (in the joint frame)."""
    shape = geometry_object.geometry
    placement = geometry_object.placement
    inflation = float(getattr(shape, "getSweptSphereRadius", lambda: 0.0)())
    if type(shape).__name__ == "Capsule":
        half = float(shape.halfLength)
        ends = np.array([placement.act(np.array([0.0, 0.0, s * half])) for s in (-1.0, 1.0)])
        return float(np.max(_perp(ends, axis))) + float(shape.radius) + inflation
    shape.computeLocalAABB()
    lo, hi = np.asarray(shape.aabb_local.min_), np.asarray(shape.aabb_local.max_)
    corners = np.array(
        [[(lo, hi)[i][0], (lo, hi)[j][1], (lo, hi)[k][2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)]
    )
    world = corners @ placement.rotation.T + placement.translation
    return float(np.max(_perp(world, axis))) + inflation


def link_point_speed_bounds(
    rate1_rad_s: np.ndarray, rate2_rad_s: np.ndarray, rate_sum_rad_s: np.ndarray, reach: LinkReach
) -> np.ndarray:
    """Upper bound [m/s] on the speed of every point of each link (module docstring).

    Args:
        rate1_rad_s, rate2_rad_s: Bounds on |dtheta_1/dt| and |dtheta_2/dt| [rad/s], shape (m,).
        rate_sum_rad_s: Bound on |dtheta_1/dt + dtheta_2/dt| [rad/s], shape (m,).
        reach: The links' reach.

    Returns:
        Shape (m, 2): column k bounds the point speeds of link k + 1.
    """
    rho1, e, rho2 = reach.link1_radius_m, reach.elbow_distance_m, reach.link2_radius_m
    v1 = rate1_rad_s * rho1
    v2 = np.minimum(rate1_rad_s * (e + rho2) + rate2_rad_s * rho2, rate1_rad_s * e + rate_sum_rad_s * rho2)
    return np.stack([v1, v2], -1) * SPEED_SLACK
