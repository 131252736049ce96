"""The paper's desired path: a quartic through five constraint points (Eq. 3), timed by
arc length at constant speed (Eq. 7).

P1 = (L/2 + 0.12, y1), P2 = (L/2 + 0.03, d - W - 0.03), P3 = (0, d - W - 0.10), P4 and P5
mirrored about the y axis. The end effector runs from P1 (x > 0) to P5 (x < 0);
t = S(x) / v with S the arc length from P1, and T = S_total / v.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pipeline.exceptions import InvalidParameterError, UnreachableObstacleError
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.validation import check_positive_int

_PANELS = 64
_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(10)


@dataclass(frozen=True, eq=False)
class QuarticPath:
    """y(x) = c4 x^4 + c3 x^3 + c2 x^2 + c1 x + c0 through five points, timed at speed v.

    Attributes:
        points_m: The five constraint points P1..P5, shape (5, 2) [m].
        speed_m_s: Constant speed along the path [m/s].
        coefficients: (c4, c3, c2, c1, c0), highest power first.
    """

    points_m: np.ndarray
    speed_m_s: float
    coefficients: np.ndarray = field(init=False)
    _edges_x: np.ndarray = field(init=False, repr=False)
    _edges_s: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        points = np.array(self.points_m, dtype=float)
        points.setflags(write=False)
        object.__setattr__(self, "points_m", points)
        vander = np.vander(points[:, 0], 5)
        coefficients = np.linalg.solve(vander, points[:, 1])
        coefficients.setflags(write=False)
        object.__setattr__(self, "coefficients", coefficients)
        edges = np.linspace(points[0, 0], points[-1, 0], _PANELS + 1)
        panel_lengths = self._integrate(edges[1:], edges[:-1])
        object.__setattr__(self, "_edges_x", edges)
        object.__setattr__(self, "_edges_s", np.concatenate([[0.0], np.cumsum(panel_lengths)]))

    @property
    def start_x_m(self) -> float:
        """x of P1 [m]."""
        return float(self.points_m[0, 0])

    @property
    def end_x_m(self) -> float:
        """x of P5 [m]."""
        return float(self.points_m[-1, 0])

    @property
    def length_m(self) -> float:
        """Total arc length from P1 to P5 [m]."""
        return float(self._edges_s[-1])

    @property
    def duration_s(self) -> float:
        """T = S_total / v [s]."""
        return self.length_m / self.speed_m_s

    def y(self, x_m: np.ndarray) -> np.ndarray:
        """Path height y(x) [m]."""
        return np.polyval(self.coefficients, x_m)

    def slope(self, x_m: np.ndarray) -> np.ndarray:
        """dy/dx [-]."""
        return np.polyval(np.polyder(self.coefficients), x_m)

    def _speed_factor(self, x_m: np.ndarray) -> np.ndarray:
        return np.sqrt(1.0 + self.slope(x_m) ** 2)

    def _integrate(self, x_from: np.ndarray, x_to: np.ndarray) -> np.ndarray:
        """Arc length between x_from and x_to (any order) by 10-point Gauss-Legendre [m]."""
        x_from, x_to = np.asarray(x_from, float), np.asarray(x_to, float)
        mid, half = (x_from + x_to) / 2, (x_to - x_from) / 2
        nodes = mid[..., None] + half[..., None] * _GL_NODES
        return np.abs(half) * (self._speed_factor(nodes) @ _GL_WEIGHTS)

    def arc_length(self, x_m: np.ndarray) -> np.ndarray:
        """S(x): arc length from P1 to the path point at x [m] (Eq. 7)."""
        x = np.clip(np.asarray(x_m, dtype=float), self.end_x_m, self.start_x_m)
        # Panels run from P1 (largest x) downward; find the panel edge at or above x.
        step = (self.start_x_m - self.end_x_m) / _PANELS
        index = np.clip(np.floor((self.start_x_m - x) / step).astype(int), 0, _PANELS - 1)
        return self._edges_s[index] + self._integrate(self._edges_x[index], x)

    def x_at_arc_length(self, s_m: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`arc_length` by Newton's method [m]; s is clipped to [0, S_total]."""
        s = np.clip(np.asarray(s_m, dtype=float), 0.0, self.length_m)
        x = np.interp(s, self._edges_s, self._edges_x)
        for _ in range(8):
            x = x + (self.arc_length(x) - s) / self._speed_factor(x)
            x = np.clip(x, self.end_x_m, self.start_x_m)
        return x

    def time_at_x(self, x_m: np.ndarray) -> np.ndarray:
        """t = S(x) / v [s]."""
        return self.arc_length(x_m) / self.speed_m_s

    def position_at_time(self, t_s: np.ndarray) -> np.ndarray:
        """Desired end-effector position (x, y) [m] at time t [s]; shape (..., 2)."""
        x = self.x_at_arc_length(np.asarray(t_s, dtype=float) * self.speed_m_s)
        return np.stack([x, self.y(x)], -1)

    def samples(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """The paper's n path points, uniform in x from P1 to P5.

        Returns:
            (times [s] shape (n,), positions [m] shape (n, 2)).
        """
        check_positive_int("n", n, minimum=7)
        x = np.linspace(self.start_x_m, self.end_x_m, n)
        return self.time_at_x(x), np.stack([x, self.y(x)], -1)


def constraint_points(obstacle: Obstacle, scene: Scene) -> np.ndarray:
    """P1..P5 of the paper for this obstacle, shape (5, 2) [m]."""
    half = obstacle.length_m / 2.0
    bottom = obstacle.top_y_m - obstacle.width_m
    p1 = (half + scene.start_dx_m, scene.y1_m)
    p2 = (half + scene.approach_dx_m, bottom - scene.approach_dy_m)
    p3 = (0.0, bottom - scene.apex_dy_m)
    return np.array([p1, p2, p3, (-p2[0], p2[1]), (-p1[0], p1[1])])


def desired_path(obstacle: Obstacle, scene: Scene, reach_m: tuple[float, float] | None = None) -> QuarticPath:
    """The quartic path around ``obstacle``.

    Args:
        obstacle: The obstacle.
        scene: Scene settings (speed, constraint-point offsets).
        reach_m: (min, max) reachable radius [m]; if given, every constraint point
            must lie inside it.

    Raises:
        UnreachableObstacleError: a constraint point is outside the reach.
        InvalidParameterError: the obstacle covers the arm's base (d - W <= 0 <= d).
    """
    points = constraint_points(obstacle, scene)
    if obstacle.top_y_m - obstacle.width_m <= 0.0 <= obstacle.top_y_m:
        raise InvalidParameterError(
            "W (width_m)",
            obstacle.width_m,
            f"less than d = {obstacle.top_y_m} m: at this width the obstacle covers the arm's base",
        )
    if reach_m is not None:
        for name, point in zip(("P1", "P2", "P3", "P4", "P5"), points, strict=True):
            radius = float(np.hypot(*point))
            if not reach_m[0] <= radius <= reach_m[1]:
                raise UnreachableObstacleError(name, radius, reach_m)
    return QuarticPath(points, scene.speed_m_s)
