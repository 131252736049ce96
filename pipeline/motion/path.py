"""The paper's desired path: a quartic through five constraint points (Eq. 3), timed by
arc length at constant speed (Eq. 7).

P1 = (x_c + L/2 + 0.12, y1), P2 = (x_c + L/2 + 0.03, d - W - 0.03), P3 = (x_c, d - W - 0.10),
P4 and P5 mirrored about the obstacle's centre line x = x_c (the paper's x_c = 0). The end
effector runs from P1 (largest x) to P5 (smallest x); t = S(x) / v with S the arc length from
P1, and T = S_total / v.

With x_c = 0 the five points are mirror images about the y axis, so the quartic is even:
y = c4 x^4 + c2 x^2 + c0 with c0 = y(P3) and (c4, c2) from a 2 x 2 system in x^2, in closed
form (:func:`symmetric_quartic`). Its length is 2 * integral_0^a sqrt(1 + y'(x)^2) dx
(a = x of P1) by a fixed composite Gauss-Legendre rule with precomputed nodes
(:func:`symmetric_quartic_length_m`: 8 panels of 20 nodes; over every reachable obstacle of the
paper's scene it agrees with a 64-panel, 10-node rule over the whole span to 1e-14 relative).
:class:`QuarticPath` and the batched generator use them; the online generator's compiled core
(``pipeline.online.kernel``) evaluates the same rule, equal to rounding.

Any other five points (x_c != 0) give a general quartic, solved from the 5 x 5 Vandermonde
system; its length is the same fixed rule on each side of the apex P3, from P3 out to P1 and
from P3 out to P5 (:func:`quartic_length_m`). For x_c != 0 the path is the x_c = 0 path moved
by x_c, and the two halves are the mirrored halves of the even quartic: its length agrees
with the closed form's to rounding (a few 1e-16 relative).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from pipeline.exceptions import InvalidParameterError, UnreachableObstacleError
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.validation import check_positive_int

_PANELS = 64
#: Newton's method for x(S) stops once no step exceeds this [m] (a few ulps of the path's x).
_NEWTON_STEP_M = 1e-15
_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(10)


def _half_span_rule(panels: int, nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """Composite Gauss-Legendre rule on [0, 1]: nodes u (n,) and weights (n,) summing to 1."""
    xi, w = np.polynomial.legendre.leggauss(nodes)
    edges = np.linspace(0.0, 1.0, panels + 1)
    mid, half = (edges[1:] + edges[:-1]) / 2.0, (edges[1:] - edges[:-1]) / 2.0
    return (mid[:, None] + half[:, None] * xi).ravel(), (half[:, None] * w).ravel()


_LENGTH_U, _LENGTH_W = _half_span_rule(8, 20)
#: Rows 1, u^2, u^4, u^6 at the length rule's nodes: with k1 = 2 c2 a and k3 = 4 c4 a^3,
#: 1 + y'(a u)^2 = 1 + u^2 (k1 + k3 u^2)^2 = (1, k1^2, 2 k1 k3, k3^2) @ this.
_LENGTH_POWERS = np.stack([np.ones_like(_LENGTH_U), _LENGTH_U**2, _LENGTH_U**4, _LENGTH_U**6])
for _array in (_LENGTH_U, _LENGTH_W, _LENGTH_POWERS):
    _array.setflags(write=False)
#: The arc-length rule of :func:`symmetric_quartic_length_m`, for the online generator's compiled
#: core (``pipeline.online.kernel``): rows 1, u^2, u^4, u^6 at the nodes (4, 160), and the weights (160,).
LENGTH_RULE_POWERS, LENGTH_RULE_WEIGHTS = _LENGTH_POWERS, _LENGTH_W


def symmetric_quartic(
    x_start_m: float, y_start_m: float, x_approach_m: float, y_approach_m: float, y_apex_m: float
) -> tuple[float, float, float]:
    """(c4, c2, c0) of the even quartic through (+-a, y1), (+-b, y2) and (0, y3) [m], closed form.

    With u = x^2: c4 u + c2 = (y - c0) / u at u = a^2 and u = b^2 (a != b, both > 0). Plain
    arithmetic, so NumPy arrays of paths work elementwise (``pipeline.online.batch`` passes them).
    """
    ua, ub = x_start_m * x_start_m, x_approach_m * x_approach_m
    ra, rb = (y_start_m - y_apex_m) / ua, (y_approach_m - y_apex_m) / ub
    c4 = (ra - rb) / (ua - ub)
    return c4, ra - c4 * ua, y_apex_m


def symmetric_quartic_length_m(x_start_m: float, c4: float, c2: float) -> float:
    """Arc length [m] of y = c4 x^4 + c2 x^2 + c0 from x = -a to x = a (a = ``x_start_m`` > 0).

    2 a * sum_j w_j sqrt(1 + y'(a u_j)^2) with the fixed rule of the module docstring.
    """
    a = x_start_m
    k1, k3 = 2.0 * c2 * a, 4.0 * c4 * a * a * a
    speed = np.array([1.0, k1 * k1, 2.0 * k1 * k3, k3 * k3]).dot(_LENGTH_POWERS)
    np.sqrt(speed, out=speed)
    return 2.0 * a * float(speed.dot(_LENGTH_W))


def symmetric_quartic_lengths_m(x_start_m: np.ndarray, c4: np.ndarray, c2: np.ndarray) -> np.ndarray:
    """:func:`symmetric_quartic_length_m` for arrays of paths (the same rule, elementwise) [m].

    The square root is taken in place: a second (n, 160) temporary cost 4x the arithmetic in
    page faults (1.3 ms against 0.31 ms for 1000 paths, the same bits).
    """
    a = np.asarray(x_start_m, dtype=float)
    k1, k3 = 2.0 * c2 * a, 4.0 * c4 * a * a * a
    speed = np.stack([np.ones_like(k1), k1 * k1, 2.0 * k1 * k3, k3 * k3], -1) @ _LENGTH_POWERS
    np.sqrt(speed, out=speed)
    return 2.0 * a * (speed @ _LENGTH_W)


def quartic_length_m(coefficients: np.ndarray, x_start_m: float, x_apex_m: float, x_end_m: float) -> float:
    """Arc length [m] of y = polyval(coefficients, x) from x = ``x_end_m`` to x = ``x_start_m``,
    split at ``x_apex_m``: sum over h = x_start - x_apex and h = x_end - x_apex of
    |h| * sum_j w_j sqrt(1 + y'(x_apex + h u_j)^2), the rule of :func:`symmetric_quartic_length_m`.
    """
    d3, d2, d1, d0 = np.polyder(np.asarray(coefficients, dtype=float)).tolist()
    total = 0.0
    for h in (x_start_m - x_apex_m, x_end_m - x_apex_m):
        x = x_apex_m + h * _LENGTH_U
        slope = ((d3 * x + d2) * x + d1) * x + d0
        speed = 1.0 + slope * slope
        np.sqrt(speed, out=speed)
        total += abs(h) * float(speed.dot(_LENGTH_W))
    return total


def _symmetric_coefficients(points: np.ndarray) -> np.ndarray | None:
    """(c4, c3, c2, c1, c0) in closed form if P1..P5 are mirror images about x = 0, else None."""
    (x1, y1), (x2, y2), (x3, y3), (x4, y4), (x5, y5) = points.tolist()
    if x3 != 0.0 or x4 != -x2 or x5 != -x1 or y4 != y2 or y5 != y1 or not x1 > x2 > 0.0:
        return None
    c4, c2, c0 = symmetric_quartic(x1, y1, x2, y2, y3)
    return np.array([c4, 0.0, c2, 0.0, c0])


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
    _slope_coefficients: tuple[float, ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        points = np.array(self.points_m, dtype=float)
        points.setflags(write=False)
        object.__setattr__(self, "points_m", points)
        if points.shape != (5, 2) or not np.all(np.isfinite(points)):
            raise InvalidParameterError("points_m", self.points_m, "five finite points (x, y) [m]")
        coefficients = _symmetric_coefficients(points)
        if coefficients is None:
            coefficients = np.linalg.solve(np.vander(points[:, 0], 5), points[:, 1])
        coefficients.setflags(write=False)
        object.__setattr__(self, "coefficients", coefficients)
        object.__setattr__(self, "_slope_coefficients", tuple(np.polyder(coefficients).tolist()))

    @cached_property
    def _symmetric(self) -> bool:
        """True if the quartic is even and runs from x = a to x = -a: the closed-form length applies."""
        c, x = self.coefficients, self.points_m[:, 0]
        return bool(c[1] == 0.0 and c[3] == 0.0 and x[-1] == -x[0])

    @cached_property
    def _panels(self) -> tuple[np.ndarray, np.ndarray]:
        """The 64 panel edges in x (from P1 down to P5) and the arc length at each [m], built on
        first use; the last is :attr:`length_m` (the panels' sum agrees with it to rounding)."""
        edges = np.linspace(self.points_m[0, 0], self.points_m[-1, 0], _PANELS + 1)
        panel_lengths = self._integrate(edges[1:], edges[:-1])
        cumulative = np.concatenate([[0.0], np.cumsum(panel_lengths)])
        cumulative[-1] = self.length_m
        return edges, cumulative

    @property
    def start_x_m(self) -> float:
        """x of P1 [m]."""
        return float(self.points_m[0, 0])

    @property
    def end_x_m(self) -> float:
        """x of P5 [m]."""
        return float(self.points_m[-1, 0])

    @cached_property
    def length_m(self) -> float:
        """Total arc length from P1 to P5 [m]: for the symmetric quartic the closed-form rule
        (:func:`symmetric_quartic_length_m`), else the same rule on each side of P3
        (:func:`quartic_length_m`)."""
        if self._symmetric:
            return symmetric_quartic_length_m(self.start_x_m, self.coefficients[0], self.coefficients[2])
        return quartic_length_m(self.coefficients, self.start_x_m, float(self.points_m[2, 0]), self.end_x_m)

    @property
    def duration_s(self) -> float:
        """T = S_total / v [s]."""
        return self.length_m / self.speed_m_s

    def y(self, x_m: np.ndarray) -> np.ndarray:
        """Path height y(x) [m]."""
        return np.polyval(self.coefficients, x_m)

    def slope(self, x_m: np.ndarray) -> np.ndarray:
        """dy/dx [-]."""
        # Horner's rule in np.polyval's order (the same floats), without its per-call set-up.
        x = np.asarray(x_m, dtype=float)
        d3, d2, d1, d0 = self._slope_coefficients
        return ((d3 * x + d2) * x + d1) * x + d0

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
        edges_x, edges_s = self._panels
        return edges_s[index] + self._integrate(edges_x[index], x)

    def x_at_arc_length(self, s_m: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`arc_length` by Newton's method [m]; s is clipped to [0, S_total].

        Newton starts from the linear interpolation of the 64 panel edges and stops when no step
        exceeds :data:`_NEWTON_STEP_M` (three steps on the paper's paths: about 4e-5, 4e-9 and
        1e-16 m), after at most eight.
        """
        s = np.clip(np.asarray(s_m, dtype=float), 0.0, self.length_m)
        edges_x, edges_s = self._panels
        x = np.interp(s, edges_s, edges_x)
        for _ in range(8):
            step = (self.arc_length(x) - s) / self._speed_factor(x)
            x = np.clip(x + step, self.end_x_m, self.start_x_m)
            if not np.any(np.abs(step) > _NEWTON_STEP_M):
                break
        return x

    def time_at_x(self, x_m: np.ndarray) -> np.ndarray:
        """t = S(x) / v [s]."""
        return self.arc_length(x_m) / self.speed_m_s

    def position_at_time(self, t_s: np.ndarray) -> np.ndarray:
        """Desired end-effector position (x, y) [m] at time t [s]; shape (..., 2)."""
        x = self.x_at_arc_length(np.asarray(t_s, dtype=float) * self.speed_m_s)
        return np.stack([x, self.y(x)], -1)

    def uniform_samples(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """n path points uniform in x from P1 to P5 and their times t = S(x) / v, the arc length
        summed segment by segment (10-point Gauss-Legendre on each of at least 64 segments, no
        panel table, no inversion).

        The same points as :meth:`samples` (any n >= 2), with times equal to its own to rounding.

        Returns:
            (times [s] shape (n,), positions [m] shape (n, 2)).
        """
        check_positive_int("n", n, minimum=2)
        x = np.linspace(self.start_x_m, self.end_x_m, n)
        # At least the panel table's 64 segments over the span (each sample gap split evenly).
        split = -(-_PANELS // (n - 1))
        fine = x if split == 1 else np.linspace(self.start_x_m, self.end_x_m, (n - 1) * split + 1)
        lengths = np.empty(fine.size)
        lengths[0] = 0.0
        np.cumsum(self._integrate(fine[:-1], fine[1:]), out=lengths[1:])
        return lengths[::split] / self.speed_m_s, np.stack([x, self.y(x)], -1)

    def samples(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """The paper's n path points, uniform in x from P1 to P5.

        Returns:
            (times [s] shape (n,), positions [m] shape (n, 2)).
        """
        check_positive_int("n", n, minimum=7)
        x = np.linspace(self.start_x_m, self.end_x_m, n)
        return self.time_at_x(x), np.stack([x, self.y(x)], -1)


def constraint_points(obstacle: Obstacle, scene: Scene) -> np.ndarray:
    """P1..P5 of the paper for this obstacle, shape (5, 2) [m]: the x of the obstacle at x_c = 0
    plus its centre x_c (``obstacle.centre_x_m``), so they move with it exactly."""
    half = obstacle.length_m / 2.0
    bottom = obstacle.top_y_m - obstacle.width_m
    x1, x2, c = half + scene.start_dx_m, half + scene.approach_dx_m, obstacle.centre_x_m
    y1, y2 = scene.y1_m, bottom - scene.approach_dy_m
    return np.array([(x1 + c, y1), (x2 + c, y2), (c, bottom - scene.apex_dy_m), (-x2 + c, y2), (-x1 + c, y1)])


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
