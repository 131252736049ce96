"""Link-to-obstacle clearance: the exact distance [m] between each link and the rounded box.

Two routes that tests prove equal:

* :class:`CoalClearance`, the canonical one: the arm's collision geometry (Pinocchio
  geometry model) and the obstacle's Coal shape, one ``pin.computeDistances`` per
  configuration, contacts not requested.
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

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import pinocchio as pin

from pipeline.exceptions import InvalidParameterError, RobotModelError
from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle

#: GJK tolerance of every Coal distance request [m].
GJK_TOLERANCE = 1e-10


@dataclass(eq=False)
class CoalClearance:
    """Distances from each link's collision geometry to one obstacle through Pinocchio + Coal.

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
            # Coal's default GJK tolerance (1e-6) overestimates distances by up to ~1e-6 m;
            # 1e-10 makes it exact to ~1e-15 at no measurable cost.
            request.gjk_tolerance = GJK_TOLERANCE
        self._data = self.arm.model.createData()

    def link_clearance(self, q: np.ndarray) -> np.ndarray:
        """Clearance of each link [m] for configurations q [rad] of shape (2,) or (m, 2).

        Returns shape (2,) or (m, 2): the minimum over each link's geometries.
        """
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


def _point_rectangle_distance(p: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Distance from points p (..., 2) to the origin-centred rectangle of half extents ``half``."""
    excess = np.maximum(np.abs(p) - half, 0.0)
    return np.sqrt(np.sum(excess * excess, axis=-1))


def _point_segment_distance(c: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from point(s) c (2,) to segments a -> b (..., 2)."""
    ab = b - a
    length2 = np.sum(ab * ab, axis=-1)
    s = np.clip(np.sum((c - a) * ab, axis=-1) / np.where(length2 > 0, length2, 1.0), 0.0, 1.0)
    closest = a + s[..., None] * ab
    return np.sqrt(np.sum((c - closest) ** 2, axis=-1))


def _segment_hits_rectangle(a: np.ndarray, b: np.ndarray, half: np.ndarray) -> np.ndarray:
    """True where segment a -> b (..., 2) meets the origin-centred rectangle (slab test)."""
    direction = b - a
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / direction
        t1 = (-half - a) * inv
        t2 = (half - a) * inv
    lo = np.where(direction == 0.0, np.where(np.abs(a) <= half, -np.inf, np.inf), np.minimum(t1, t2))
    hi = np.where(direction == 0.0, np.where(np.abs(a) <= half, np.inf, -np.inf), np.maximum(t1, t2))
    enter = np.maximum(np.max(lo, axis=-1), 0.0)
    leave = np.minimum(np.min(hi, axis=-1), 1.0)
    return enter <= leave


def segment_rectangle_distance(a: np.ndarray, b: np.ndarray, center: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Planar distance [m] between segments a -> b (..., 2) and an axis-aligned rectangle.

    Zero where they meet. Otherwise the minimum is attained at a vertex of one of the two
    convex sets: a segment endpoint against the rectangle, or a rectangle corner against
    the segment.
    """
    a = np.asarray(a, dtype=float) - center
    b = np.asarray(b, dtype=float) - center
    half = np.asarray(half, dtype=float)
    best = np.minimum(_point_rectangle_distance(a, half), _point_rectangle_distance(b, half))
    for sx, sy in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
        corner = half * np.array([sx, sy])
        best = np.minimum(best, _point_segment_distance(corner, a, b))
    return np.where(_segment_hits_rectangle(a, b, half), 0.0, best)


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
    elbow, tip = link_segments(q, arm.link_lengths_m)
    center = obstacle.center_m[:2]
    half = obstacle.core_half_extents_m[:2]
    base = np.zeros_like(elbow)
    d1 = segment_rectangle_distance(base, elbow, center, half) - arm.link_radii_m[0]
    d2 = segment_rectangle_distance(elbow, tip, center, half) - arm.link_radii_m[1]
    return np.stack([d1, d2], -1) - obstacle.corner_radius_m


#: A clearance function: joint configurations (m, 2) [rad] -> per-link clearance (m, 2) [m].
ClearanceFunction = Callable[[np.ndarray], np.ndarray]

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


@dataclass(frozen=True)
class CoalRoute(ClearanceRoute):
    """Pinocchio's geometry model + Coal: the canonical route, any collision geometry."""

    name: ClassVar[str] = "coal"
    distance_error_m: ClassVar[float] = COAL_DISTANCE_ERROR_M

    def function(self, arm: PlanarArm, obstacle: Obstacle) -> ClearanceFunction:
        return CoalClearance(arm, obstacle).link_clearance


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
ROUTES: dict[str, ClearanceRoute] = {route.name: route for route in (COAL, ANALYTIC)}


def route_from_name(name: object) -> ClearanceRoute:
    """The clearance route called ``name`` ("coal" or "analytic").

    Raises:
        InvalidParameterError: no route has that name.
    """
    route = ROUTES.get(name) if isinstance(name, str) else None
    if route is None:
        raise InvalidParameterError("route", name, f"one of {tuple(ROUTES)}")
    return route
