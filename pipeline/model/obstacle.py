"""The rounded rectangular obstacle as a Coal shape.

The footprint is exactly L x W: x in [x_c - L/2, x_c + L/2], y in [d - W, d], with x_c the
obstacle's centre x (the paper's x_c = 0). Coal's swept-sphere
radius r inflates a box in every direction, so the core box is (L - 2r, W - 2r, h - 2r)
and the outer shape has rounded vertical edges (the corners of the footprint).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from pipeline.exceptions import InvalidParameterError
from pipeline.model.scene import Scene
from pipeline.validation import check_finite, check_non_negative, check_positive

if TYPE_CHECKING:
    import coal
    import pinocchio as pin


@dataclass(frozen=True)
class Obstacle:
    """A rounded box standing on the arm's plane.

    Attributes:
        length_m: L, extent along x [m].
        width_m: W, extent along y [m].
        top_y_m: d, the y of the far edge [m].
        corner_radius_m: Radius of the rounded corners [m]; at most min(L, W) / 2.
        height_m: Extent along z, centred on z = 0 [m]; > 2 * corner radius.
        centre_x_m: x_c, the x of the centre [m].
    """

    length_m: float
    width_m: float
    top_y_m: float = 0.56
    corner_radius_m: float = 0.01
    height_m: float = 1.0
    centre_x_m: float = 0.0

    def __post_init__(self) -> None:
        check_positive("L (length_m)", self.length_m)
        check_positive("W (width_m)", self.width_m)
        check_finite("top_y_m", self.top_y_m)
        check_non_negative("corner_radius_m", self.corner_radius_m)
        check_positive("height_m", self.height_m)
        check_finite("centre_x_m", self.centre_x_m)
        limit = min(self.length_m, self.width_m, self.height_m) / 2.0
        if self.corner_radius_m > limit:
            raise InvalidParameterError(
                "corner_radius_m", self.corner_radius_m, f"at most min(L, W, height) / 2 = {limit:.4g} m"
            )

    @classmethod
    def in_scene(cls, length_m: float, width_m: float, scene: Scene) -> Obstacle:
        """The obstacle of size L x W placed as the scene says."""
        return cls(length_m, width_m, scene.top_y_m, scene.corner_radius_m, scene.obstacle_height_m, scene.centre_x_m)

    @property
    def center_m(self) -> np.ndarray:
        """Centre of the box [m]: (x_c, d - W/2, 0)."""
        return np.array([self.centre_x_m, self.top_y_m - self.width_m / 2.0, 0.0])

    @property
    def core_half_extents_m(self) -> np.ndarray:
        """Half extents (x, y, z) of the box before rounding [m]."""
        r = self.corner_radius_m
        return np.array([self.length_m / 2 - r, self.width_m / 2 - r, self.height_m / 2 - r])

    @property
    def placement(self) -> pin.SE3:
        """Pose of the box in the base frame (axis-aligned)."""
        import pinocchio as pin  # the online generator builds obstacles without Pinocchio

        return pin.SE3(np.eye(3), self.center_m)

    def coal_shape(self) -> coal.Box:
        """A new Coal box with swept-sphere radius: the rounded obstacle in its own frame."""
        import coal  # the online generator builds obstacles without Coal

        box = coal.Box(*(2.0 * self.core_half_extents_m))
        box.setSweptSphereRadius(self.corner_radius_m)
        return box

    def footprint_corners_m(self) -> np.ndarray:
        """The four corners (x, y) of the outer L x W footprint [m], counter-clockwise; the x are
        those of the obstacle at x_c = 0 plus x_c."""
        x, y0, y1, c = self.length_m / 2, self.top_y_m - self.width_m, self.top_y_m, self.centre_x_m
        return np.array([[x + c, y0], [x + c, y1], [-x + c, y1], [-x + c, y0]])
