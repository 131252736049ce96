"""Link-to-obstacle clearance: the exact distance [m] between each link and the rounded box.

Two routes that tests prove equal:

* :class:`CoalClearance`, the canonical one: the arm's collision geometry (the shapes of
  Pinocchio's geometry model, placed by the model's kinematics) and the obstacle's Coal shape,
  one ``coal.ComputeDistance`` call per link geometry and configuration, contacts not requested;
  equal to ``pin.computeDistances`` over the geometry model (:class:`PinocchioCoalClearance`,
  kept as the reference), which tests prove.
* :func:`analytic_link_clearance`, the fast one for the PSO's hot loop: each link is a
  capsule (segment with radius) and the obstacle a rounded rectangle (core rectangle
  inflated by the corner radius), so the clearance is the planar segment-to-rectangle
  distance minus both radii, vectorised over any batch of configurations.

Each route is an object (:class:`ClearanceRoute`: :data:`COAL`, :data:`ANALYTIC`) that gives the
clearance function for an arm and an obstacle and the bound on its error.

Where a link overlaps the obstacle both routes return a value <= 0 (Coal a penetration
depth, the analytic route minus the radii), so "clearance > 0" means the same for both.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import ClassVar

import coal
import numpy as np
import pinocchio as pin

from pipeline.exceptions import InvalidParameterError, RobotModelError
from pipeline.geometry.segment_distance import segment_rectangle_distance
from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle

#: GJK tolerance of every Coal distance request [m].
GJK_TOLERANCE = 1e-10


def _joint_axis(joint: pin.JointModel) -> np.ndarray:
    """Unit axis of a revolute joint in its own frame."""
    name = joint.shortname()
    axes = {"JointModelRX": (1.0, 0.0, 0.0), "JointModelRY": (0.0, 1.0, 0.0), "JointModelRZ": (0.0, 0.0, 1.0)}
    if name in axes:
        return np.array(axes[name])
    if name == "JointModelRevoluteUnaligned":
        axis = np.asarray(joint.extract().axis, dtype=float).copy()
        return axis / np.linalg.norm(axis)
    raise RobotModelError(f"joint {joint.id} is a {name}; the Coal clearance route needs revolute joints")


def _cross_matrix(axis: np.ndarray) -> np.ndarray:
    x, y, z = axis
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


class _ArmGeometry:
    """What every Coal clearance query of one arm shares: the links' Coal shapes and, per link
    geometry, its placement as a linear map of nine features of q, all read from the Pinocchio model.

    With ``J_j`` the placement of joint j in its parent, ``K_j`` the cross-product matrix of its
    unit axis and ``E_j = I + sin(q_j) K_j + (1 - cos(q_j)) K_j^2`` (Rodrigues), a geometry with
    placement ``G`` on joint 1 is at ``J_1 E_1 G``, one on joint 2 at ``J_1 E_1 J_2 E_2 G``: the
    rotation and translation are linear in the features ``a_i b_k`` with ``a = (1, sin q1,
    1 - cos q1)`` and ``b = (1, sin q2, 1 - cos q2)``, so one (m, 9) @ (9, 12) product places a
    geometry for m configurations (rotation row-major in columns 0-8, translation in 9-11).
    """

    def __init__(self, arm: PlanarArm) -> None:
        model = arm.model
        joints = [model.jointPlacements[j] for j in (1, 2)]
        rotations = [np.array(joint.rotation) for joint in joints]
        translations = [np.array(joint.translation) for joint in joints]
        powers = []
        for j in (1, 2):
            cross = _cross_matrix(_joint_axis(model.joints[j]))
            powers.append((np.eye(3), cross, cross @ cross))
        self.shapes, self.links, self.maps, self.joints1, self.maps_joint1 = [], [], [], [], []
        # The distance request, read-only, shared by every CoalClearance of this arm.
        self.request = coal.DistanceRequest()
        # Coal's default GJK tolerance (1e-6) overestimates distances by up to ~1e-6 m;
        # 1e-10 makes it exact to ~1e-15 at no measurable cost.
        self.request.gjk_tolerance = GJK_TOLERANCE
        self.identity = np.eye(3)
        for link, ids in enumerate(arm.link_geometry_ids):
            for geometry_id in ids:
                geometry = arm.collision_model.geometryObjects[geometry_id]
                g_rot, g_tr = np.array(geometry.placement.rotation), np.array(geometry.placement.translation)
                linear = np.zeros((3, 3, 12))  # feature (a_i, b_k) -> (rotation, translation)
                for i, power1 in enumerate(powers[0]):
                    frame1 = rotations[0] @ power1  # J_1 rotation times the a_i term of E_1
                    if geometry.parentJoint == 1:
                        linear[i, 0, :9] = (frame1 @ g_rot).ravel()
                        linear[i, 0, 9:] = frame1 @ g_tr
                    elif geometry.parentJoint == 2:
                        linear[i, 0, 9:] = frame1 @ translations[1]
                        for k, power2 in enumerate(powers[1]):
                            frame2 = frame1 @ rotations[1] @ power2
                            linear[i, k, :9] = (frame2 @ g_rot).ravel()
                            linear[i, k, 9:] += frame2 @ g_tr
                    else:
                        raise RobotModelError(f"{arm.urdf_path}: link geometry on joint {geometry.parentJoint}")
                linear[0, 0, 9:] += translations[0]
                self.shapes.append(geometry.geometry)
                self.links.append(link)
                self.maps.append(linear.reshape(9, 12))
                # On joint 1 only the features with b = 1 (k = 0) carry weight: a (3, 12) map of a.
                self.joints1.append(geometry.parentJoint == 1)
                self.maps_joint1.append(np.ascontiguousarray(linear[:, 0, :]))
        # Per link: are all its geometries on joint 1 (then only the features of q1 are needed)?
        self.link_on_joint1 = [
            all(j for j, k in zip(self.joints1, self.links, strict=True) if k == link) for link in (0, 1)
        ]
        self.link_counts = [self.links.count(link) for link in (0, 1)]
        # The map each geometry's link_distances uses: (3, 12) of a on joint-1-only links, else (9, 12).
        self.link_maps = [
            self.maps_joint1[g] if self.link_on_joint1[link] else self.maps[g] for g, link in enumerate(self.links)
        ]

    def features(self, q: np.ndarray, joint1_only: bool = False) -> np.ndarray:
        """The nine features a_i b_k (m, 9) of configurations q (m, 2), or only a (m, 3) if ``joint1_only``."""
        terms = np.empty((q.shape[0], 2, 3))
        terms[:, :, 0] = 1.0
        np.sin(q, out=terms[:, :, 1])
        np.cos(q, out=terms[:, :, 2])
        np.subtract(1.0, terms[:, :, 2], out=terms[:, :, 2])
        if joint1_only:
            return terms[:, 0, :]
        return (terms[:, 0, :, None] * terms[:, 1, None, :]).reshape(-1, 9)

    def geometry_placements(self, q: np.ndarray, link: int | None = None) -> list[tuple[np.ndarray, np.ndarray] | None]:
        """Per link geometry: rotations (m, 3, 3) and translations (m, 3) in the base frame, for q (m, 2)
        (only the geometries of ``link`` if given, None for the others)."""
        joint1_only = link is not None and all(self.joints1[g] for g in range(len(self.maps)) if self.links[g] == link)
        features = self.features(q, joint1_only)
        placements = []
        for g, (linear, own_link) in enumerate(zip(self.maps, self.links, strict=True)):
            if link is not None and own_link != link:
                placements.append(None)
                continue
            placed = features @ (self.maps_joint1[g] if joint1_only else linear)
            placements.append((placed[:, :9].reshape(-1, 3, 3), placed[:, 9:]))
        return placements


@dataclass(eq=False)
class CoalClearance:
    """Distances from each link's collision geometry to one obstacle by Coal: the canonical route.

    Each link geometry of the arm's Pinocchio geometry model is placed from the model's joint
    placements and axes (vectorised over configurations) and its distance to the obstacle's Coal
    shape is one ``coal.ComputeDistance`` call, with the GJK tolerance of :data:`GJK_TOLERANCE`. This is
    exactly what ``pin.computeDistances`` does for each collision pair; tests prove both equal
    (:class:`PinocchioCoalClearance` keeps that route). Shapes, functors and the request are built
    once per instance; the arm's kinematic data once per arm.

    Attributes:
        arm: The arm.
        obstacle: The obstacle.
        queries: Number of Coal distance queries made so far (one per link geometry and configuration).
    """

    arm: PlanarArm
    obstacle: Obstacle
    queries: int = 0
    _geometry: _ArmGeometry = field(init=False, repr=False)
    _calls: list = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self._geometry = geometry = self.arm.derived(_ArmGeometry)
        # The obstacle's Coal shape and placement, as Obstacle.coal_shape() and .center_m (the same
        # arithmetic in Python floats, without the intermediate arrays).
        obstacle = self.obstacle
        r = obstacle.corner_radius_m
        box = coal.Box(
            2.0 * (obstacle.length_m / 2 - r), 2.0 * (obstacle.width_m / 2 - r), 2.0 * (obstacle.height_m / 2 - r)
        )
        box.setSweptSphereRadius(r)
        obstacle_tf = coal.Transform3s(
            geometry.identity, np.array([obstacle.centre_x_m, obstacle.top_y_m - obstacle.width_m / 2.0, 0.0])
        )
        request, result = geometry.request, coal.DistanceResult()  # a result per instance: no sharing of state
        self._calls = [
            (g, link, coal.ComputeDistance(shape, box), coal.Transform3s(), obstacle_tf, request, result, box)
            for g, (shape, link) in enumerate(zip(self._geometry.shapes, self._geometry.links, strict=True))
        ]

    def link_clearance(self, q: np.ndarray) -> np.ndarray:
        """Clearance of each link [m] for configurations q [rad] of shape (2,) or (m, 2).

        Returns shape (2,) or (m, 2): the minimum over each link's geometries.
        """
        q = np.asarray(q, dtype=float)
        if q.shape == (2,):
            return self._one_configuration(q)
        batch = np.atleast_2d(q)
        placements = self._geometry.geometry_placements(batch)
        out = np.full((batch.shape[0], 2), np.inf)
        for g, link, functor, tf, obstacle_tf, request, result, _ in self._calls:
            distances = []
            rotations, translations = placements[g]
            for rotation, translation in zip(rotations, translations, strict=True):
                tf.setTransform(rotation, translation)
                result.clear()
                distances.append(functor(tf, obstacle_tf, request, result))
            out[:, link] = np.minimum(out[:, link], distances)
        self.queries += batch.shape[0] * len(self._calls)
        return out[0] if q.ndim == 1 else out

    def _one_configuration(self, q: np.ndarray) -> np.ndarray:
        """:meth:`link_clearance` of one configuration (2,), without batch machinery (a planner's checker)."""
        s1, s2 = math.sin(q[0]), math.sin(q[1])
        v1, v2 = 1.0 - math.cos(q[0]), 1.0 - math.cos(q[1])
        features = np.array([1.0, s2, v2, s1, s1 * s2, s1 * v2, v1, v1 * s2, v1 * v2])
        best = [math.inf, math.inf]
        for g, link, functor, tf, obstacle_tf, request, result, _ in self._calls:
            placed = features.dot(self._geometry.maps[g])
            tf.setTransform(placed[:9].reshape(3, 3), placed[9:])
            result.clear()
            distance = functor(tf, obstacle_tf, request, result)
            if distance < best[link]:
                best[link] = distance
        self.queries += len(self._calls)
        return np.array(best)

    def link_distances(self, q: np.ndarray, link: int) -> np.ndarray:
        """Clearance [m] of one link (0 or 1) for configurations q (m, 2) [rad]: shape (m,)."""
        batch = q if type(q) is np.ndarray and q.ndim == 2 else np.atleast_2d(np.asarray(q, dtype=float))
        features = self._geometry.features(batch, self._geometry.link_on_joint1[link])
        out = None
        for g, own_link, functor, tf, obstacle_tf, request, result, _ in self._calls:
            if own_link != link:
                continue
            placed = features @ self._geometry.link_maps[g]
            distances = []
            for rotation, translation in zip(placed[:, :9].reshape(-1, 3, 3), placed[:, 9:], strict=True):
                tf.setTransform(rotation, translation)
                result.clear()
                distances.append(functor(tf, obstacle_tf, request, result))
            out = np.array(distances) if out is None else np.minimum(out, distances)
        self.queries += batch.shape[0] * self._geometry.link_counts[link]
        return out


@dataclass(eq=False)
class PinocchioCoalClearance:
    """The same distances through Pinocchio's geometry model: one ``pin.computeDistances`` per
    configuration. The reference :class:`CoalClearance` is tested against; slower.

    Attributes:
        arm: The arm.
        obstacle: The obstacle.
        queries: Number of Coal distance queries made so far (one per link and configuration).
    """

    arm: PlanarArm
    obstacle: Obstacle
    queries: int = 0
    _geometry_model: pin.GeometryModel = field(init=False, repr=False)
    _geometry_data: pin.GeometryData = field(init=False, repr=False)
    _data: pin.Data = field(init=False, repr=False)
    _pair_link: list[int] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        geometry_model = self.arm.collision_model.copy()
        obstacle_id = geometry_model.addGeometryObject(
            pin.GeometryObject("obstacle", 0, 0, self.obstacle.placement, self.obstacle.coal_shape())
        )
        self._pair_link = []
        for link, ids in enumerate(self.arm.link_geometry_ids):
            for geometry_id in ids:
                geometry_model.addCollisionPair(pin.CollisionPair(geometry_id, obstacle_id))
                self._pair_link.append(link)
        self._geometry_model = geometry_model
        self._geometry_data = pin.GeometryData(geometry_model)
        for request in self._geometry_data.distanceRequests:
            request.gjk_tolerance = GJK_TOLERANCE
        self._data = self.arm.model.createData()

    def link_clearance(self, q: np.ndarray) -> np.ndarray:
        """As :meth:`CoalClearance.link_clearance`."""
        q = np.asarray(q, dtype=float)
        batch = np.atleast_2d(q)
        out = np.full((batch.shape[0], 2), np.inf)
        for row, configuration in enumerate(batch):
            pin.computeDistances(self.arm.model, self._data, self._geometry_model, self._geometry_data, configuration)
            for pair, link in enumerate(self._pair_link):
                distance = self._geometry_data.distanceResults[pair].min_distance
                out[row, link] = min(out[row, link], distance)
        self.queries += batch.shape[0] * len(self._pair_link)
        return out[0] if q.ndim == 1 else out


def link_segments(q: np.ndarray, link_lengths_m: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Elbow and tip positions (..., 2) [m] of a planar arm in the scene frame for q (..., 2) [rad]."""
    l1, l2 = link_lengths_m
    q = np.asarray(q, dtype=float)
    a1 = q[..., 0]
    a12 = a1 + q[..., 1]
    elbow = np.stack([l1 * np.cos(a1), l1 * np.sin(a1)], -1)
    tip = elbow + np.stack([l2 * np.cos(a12), l2 * np.sin(a12)], -1)
    return elbow, tip


def check_fast_route(arm: PlanarArm) -> None:
    """Raise RobotModelError unless the arm suits :func:`analytic_link_clearance`."""
    if not (arm.capsule_links and arm.is_horizontal_xy):
        raise RobotModelError(
            f"{arm.urdf_path}: the analytic clearance route needs each link to be one cylinder "
            "from joint to joint in the base frame's xy plane; use CoalClearance instead"
        )


def analytic_link_clearance(q: np.ndarray, arm: PlanarArm, obstacle: Obstacle) -> np.ndarray:
    """Clearance of each link [m] for q of shape (..., 2): shape (..., 2). Vectorised.

    Equal to :meth:`CoalClearance.link_clearance` wherever the clearance is positive.
    """
    return link_box_clearance(
        q,
        arm.link_lengths_m,
        arm.link_radii_m,
        obstacle.center_m[:2],
        obstacle.core_half_extents_m[:2],
        obstacle.corner_radius_m,
    )


def link_box_clearance(
    q: np.ndarray,
    link_lengths_m: tuple[float, float],
    link_radii_m: tuple[float, float],
    center_m: np.ndarray,
    half_extents_m: np.ndarray,
    corner_radius_m: float,
) -> np.ndarray:
    """Clearance of each capsule link [m] of a planar 2R arm to rounded boxes: shape (..., 2). Vectorised.

    The analytic route (:func:`analytic_link_clearance`) without an arm or obstacle object: each
    configuration may have its own box, as the certifiable regression's points do.

    Args:
        q: Joint angles (..., 2) [rad].
        link_lengths_m: (l1, l2) [m].
        link_radii_m: Radius of each link's capsule [m].
        center_m: Centre (x, y) of each box [m]: (2,) or broadcastable to (..., 2).
        half_extents_m: Half extents (x, y) of each box's core rectangle (before rounding) [m]: (2,)
            or broadcastable to (..., 2).
        corner_radius_m: The boxes' corner radius [m] (the core rectangle inflated by it).
    """
    elbow, tip = link_segments(q, link_lengths_m)
    base = np.zeros_like(elbow)
    d1 = segment_rectangle_distance(base, elbow, center_m, half_extents_m) - link_radii_m[0]
    d2 = segment_rectangle_distance(elbow, tip, center_m, half_extents_m) - link_radii_m[1]
    return np.stack([d1, d2], -1) - corner_radius_m


#: A clearance function: joint configurations (m, 2) [rad] -> per-link clearance (m, 2) [m].
ClearanceFunction = Callable[[np.ndarray], np.ndarray]
#: One link's clearance: configurations (m, 2) [rad] and a link (0 or 1) -> that link's clearance (m,) [m].
LinkClearanceFunction = Callable[[np.ndarray, int], np.ndarray]


def per_link(clearance: ClearanceFunction) -> LinkClearanceFunction:
    """A :data:`LinkClearanceFunction` from a clearance function of both links (computes both)."""

    def one_link(q: np.ndarray, link: int) -> np.ndarray:
        return np.asarray(clearance(q), dtype=float).reshape(-1, 2)[:, link]

    return one_link


#: Error bound [m] on Coal's distances (GJK upper estimate; measured <= 1.2e-6 m, bound 10x that).
COAL_DISTANCE_ERROR_M = 1e-5
#: Error bound [m] on the analytic planar distance (floating-point rounding only).
ANALYTIC_DISTANCE_ERROR_M = 1e-12


@dataclass(frozen=True)
class ClearanceRoute(ABC):
    """A way of computing the per-link clearance, with the bound on its error.

    Class attributes:
        name: The route's name in files and on the command line.
        distance_error_m: Bound on |computed - exact| clearance where it is positive [m].
    """

    name: ClassVar[str]
    distance_error_m: ClassVar[float]

    def check_arm(self, arm: PlanarArm) -> None:  # noqa: B027 - optional hook, a no-op by default
        """Raise RobotModelError if the route cannot serve this arm."""

    @abstractmethod
    def function(self, arm: PlanarArm, obstacle: Obstacle) -> ClearanceFunction:
        """The clearance function for this arm and obstacle."""

    def functions(self, arm: PlanarArm, obstacle: Obstacle) -> tuple[ClearanceFunction, LinkClearanceFunction]:
        """The clearance function of both links and the one-link function, sharing their set-up."""
        function = self.function(arm, obstacle)
        return function, per_link(function)


@dataclass(frozen=True)
class CoalRoute(ClearanceRoute):
    """Pinocchio's geometry model + Coal: the canonical route, any collision geometry."""

    name: ClassVar[str] = "coal"
    distance_error_m: ClassVar[float] = COAL_DISTANCE_ERROR_M

    def function(self, arm: PlanarArm, obstacle: Obstacle) -> ClearanceFunction:
        return CoalClearance(arm, obstacle).link_clearance

    def functions(self, arm: PlanarArm, obstacle: Obstacle) -> tuple[ClearanceFunction, LinkClearanceFunction]:
        clearance = CoalClearance(arm, obstacle)
        return clearance.link_clearance, clearance.link_distances


@dataclass(frozen=True)
class AnalyticRoute(ClearanceRoute):
    """Planar capsule-to-rounded-rectangle distance, vectorised; capsule links in the xy plane only."""

    name: ClassVar[str] = "analytic"
    distance_error_m: ClassVar[float] = ANALYTIC_DISTANCE_ERROR_M

    def check_arm(self, arm: PlanarArm) -> None:
        check_fast_route(arm)

    def function(self, arm: PlanarArm, obstacle: Obstacle) -> ClearanceFunction:
        check_fast_route(arm)

        def clearance(q: np.ndarray) -> np.ndarray:
            return analytic_link_clearance(q, arm, obstacle)

        return clearance


COAL = CoalRoute()
ANALYTIC = AnalyticRoute()
#: Every route, by name.
ROUTES: Mapping[str, ClearanceRoute] = MappingProxyType({route.name: route for route in (COAL, ANALYTIC)})


def route_from_name(name: object) -> ClearanceRoute:
    """The clearance route called ``name`` ("coal" or "analytic").

    Raises:
        InvalidParameterError: no route has that name.
    """
    route = ROUTES.get(name) if isinstance(name, str) else None
    if route is None:
        raise InvalidParameterError("route", name, f"one of {tuple(ROUTES)}")
    return route
