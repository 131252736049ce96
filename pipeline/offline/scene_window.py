"""The window of the obstacle's far edge d (``Scene.top_y_m``) an arm can be built for.

A build refuses, before any work, a range of obstacles where a constraint point P1..P5 lies
outside the arm's reach annulus or where the arm's pose at P1 or P5 (inverse kinematics on the
family's elbow branch) collides with the obstacle, both checked on the 21 x 21 grid of (L, W)
(times the levels of x when x varies) of :func:`pipeline.offline.convergence.grid_problems`.
For an arm of other link lengths the paper's d = 0.56 m rarely passes; :func:`scene_window`
finds, from the arm alone, the interval of d over which every obstacle of the range passes, and
more: the end poses keep the scene's margin (not only a positive clearance), since where they
do not, no trajectory of the family ending within the endpoint tolerance keeps the margin.

**One obstacle at one d** is judged by the build's own functions (:func:`_check`):
:func:`pipeline.offline.fitness.fitness_problem` (its path checks P1..P5 against the reach and
that the obstacle leaves the base free, d - W > 0; its endpoint context is the inverse
kinematics of P1 and P5) and the end poses' clearance exactly as
:func:`pipeline.offline.convergence.end_pose_collisions` computes it. Nothing here re-derives
kinematics or clearance.

**The window over a grid** is found on an active set of its obstacles (:func:`_window_over`):

1. scan d downwards from above every reach (P3 out of reach) to the widest W (the obstacle
   would cover the base) in steps of ``scan_step_m`` on the active set, and take the widest run
   of passing values (several runs can exist: the reach of P3 leaves a gap where it passes the
   base);
2. bisect both edges of that run to ``tolerance_m``: the inside value passes, the outside one
   fails, and the failure there (the worst one over the active set) is the edge's reason;
3. check both inside edges and the recommended value on every obstacle of the grid; an
   obstacle that fails there joins the active set and the search repeats inside the run.

A value that fails on part of the grid fails on the grid, so the outside of each edge is
proven; the inside edges and the recommended value are checked on the whole grid. Between the
scan's samples the window is checked on the active set only (the constraints are monotone or
piecewise monotone in d, and a run narrower than one scan step is not found).

**The recommended value** is the middle of the window, rounded to the first of ``rounding_m``
(5 mm, then 1 mm, then 0.1 mm) that keeps it inside. The two edges are different failures:
below, the end poses come too near the obstacle (or P3 too near the base); above, the arm
stretches to reach P1 and P5, where the family's elbow keeps away from the straight arm
(``FitnessConfig.min_elbow_angle_rad``) and the optima would miss the endpoints. The middle
leaves the most room against both, and room in d against the end poses' clearance is what the
DOE optima need, which miss P1 and P5 by a few millimetres to keep the margin.

**When no d fits** over the range asked for, or only a window narrower than ``min_width_m``
(1 cm), and ``shrink`` is on, the L range is shrunk (sub-ranges on a lattice of a tenth of its
width, widest first), then the W range, until a window at least that wide is found; each
candidate is screened on obstacles of its grid before its grid is searched. Narrow windows are
valid but poor builds: the DOE optima then have little room between the margin at the end
poses and the stretched arm at P1 (an arm of 0.30 and 0.28 m has a 5.1 mm window over the
default range, and its build at d = 0.510 m does not converge; over L in [0.20, 0.25] m the
window is 17 mm wide and the build at d = 0.515 m keeps the margin on all of the range).
Without a wider shrunk window the narrow one is returned, marked (:attr:`SceneWindow.narrow`).

A shrunk range keeps at least half of the range asked for (``shrink_min_steps``): an arm that
fits only a sliver of it is too small for the scene's offsets of P1..P5, and the build there
fails for want of more than d (an arm of 0.25 and 0.20 m fits L in [0.20, 0.22] m with d in a
window 2.5 mm wide, but its DOE optima reach the family's bound |A2| = 3 rad and the regression
does not converge), so the reason is worth more than a range. When none fits either,
:class:`pipeline.exceptions.NoSceneWindowError` names the constraints that close the window
over the range asked for: two reach constraints that contradict each other ("P3 needs
d >= 0.52 m for the reach, P1 needs d <= 0.31 m"), a point no d brings into reach, or the end
pose that keeps less than the margin wherever the reach allows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from pipeline.exceptions import InvalidParameterError, NoSceneWindowError, UnreachableObstacleError
from pipeline.geometry.clearance import AnalyticRoute, link_box_clearance
from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.motion.families import PAPER, TrajectoryFamily
from pipeline.motion.path import constraint_points, desired_path
from pipeline.offline.convergence import GRID_POINTS
from pipeline.offline.fitness import FitnessConfig
from pipeline.validation import check_non_negative, check_positive, check_positive_int

__all__ = ["BASE", "END_POSE", "REACH", "Failure", "SceneWindow", "WindowSettings", "scene_window"]

#: Kinds of :class:`Failure`.
REACH, END_POSE, BASE = "reach", "end pose", "base"
#: Names of the constraint points, in order.
POINT_NAMES = ("P1", "P2", "P3", "P4", "P5")

#: One obstacle: (L, W, x) [m].
Size = tuple[float, float, float]


@dataclass(frozen=True)
class WindowSettings:
    """How :func:`scene_window` searches.

    Attributes:
        end_pose_clearance_m: Clearance the poses at P1 and P5 must keep [m]; None: the scene's
            margin. 0 asks only what the build's pre-check asks (no collision).
        grid_points: Obstacle sizes per axis of the (L, W) grid, as the build's pre-check (21).
        centre_x_points: Levels of x when x varies, as the build's pre-check (5).
        scan_step_m: Step of the scan over d [m]; a window narrower than this may be missed.
        tolerance_m: Width of the bracket of each edge after bisection [m].
        rounding_m: Steps the recommended value is rounded to, the first that stays inside [m].
        min_width_m: The narrowest window worth a build [m]: a narrower one over the range asked
            for makes the search try shrunk ranges too (module docstring).
        shrink: Try shrunk L, then W ranges when no d fits the range asked for, or only a window
            narrower than ``min_width_m``.
        shrink_lattice: The shrunk ranges' ends lie on this many equal steps of the range [count].
        shrink_min_steps: Fewest steps of that lattice a shrunk range keeps [count] (half of it).
    """

    end_pose_clearance_m: float | None = None
    grid_points: int = GRID_POINTS
    centre_x_points: int = 5
    scan_step_m: float = 0.002
    tolerance_m: float = 1e-4
    rounding_m: tuple[float, ...] = (0.005, 0.001, 0.0001)
    min_width_m: float = 0.01
    shrink: bool = True
    shrink_lattice: int = 10
    shrink_min_steps: int = 5

    def __post_init__(self) -> None:
        if self.end_pose_clearance_m is not None:
            check_non_negative("end_pose_clearance_m", self.end_pose_clearance_m)
        check_positive_int("grid_points", self.grid_points, minimum=2)
        check_positive_int("centre_x_points", self.centre_x_points, minimum=2)
        check_positive("scan_step_m", self.scan_step_m)
        check_positive("tolerance_m", self.tolerance_m)
        if not self.tolerance_m < self.scan_step_m:
            raise InvalidParameterError("tolerance_m", self.tolerance_m, f"less than scan_step_m = {self.scan_step_m}")
        for step in self.rounding_m:
            check_positive("rounding_m", step)
        check_non_negative("min_width_m", self.min_width_m)
        if not isinstance(self.shrink, bool):
            raise InvalidParameterError("shrink", self.shrink, "True or False")
        check_positive_int("shrink_lattice", self.shrink_lattice, minimum=2)
        check_positive_int("shrink_min_steps", self.shrink_min_steps)
        if self.shrink_min_steps > self.shrink_lattice:
            raise InvalidParameterError("shrink_min_steps", self.shrink_min_steps, f"<= {self.shrink_lattice}")


@dataclass(frozen=True)
class Failure:
    """Why one obstacle refuses one d.

    Attributes:
        kind: :data:`REACH` (a constraint point outside the reach annulus), :data:`END_POSE` (the
            pose at P1 or P5 keeps less than the required clearance) or :data:`BASE` (the
            obstacle covers the arm's base, d - W <= 0).
        point_name: "P1".."P5" ("" for BASE).
        d_m: The obstacle's far edge d [m].
        length_m, width_m, centre_x_m: The obstacle, L, W and its centre x [m].
        value_m: The point's distance from the base (REACH), the pose's clearance (END_POSE) or
            d - W (BASE) [m].
        limit_m: The reach annulus (min, max) (REACH), (required clearance, inf) (END_POSE) or
            (0, inf) (BASE) [m].
    """

    kind: str
    point_name: str
    d_m: float
    length_m: float
    width_m: float
    centre_x_m: float
    value_m: float
    limit_m: tuple[float, float]

    @property
    def excess_m(self) -> float:
        """How far the value lies outside its limits [m] (>= 0 for a failure)."""
        return max(self.limit_m[0] - self.value_m, self.value_m - self.limit_m[1])

    @property
    def too_far(self) -> bool:
        """True for a point beyond the arm's reach (fixed by lowering d when y1 = d)."""
        return self.kind == REACH and self.value_m > self.limit_m[1]

    @property
    def where(self) -> str:
        """``L = 0.300 m, W = 0.080 m[, x = ...], d = 0.6459 m``."""
        x = f", x = {self.centre_x_m:.3f} m" if self.centre_x_m != 0.0 else ""
        return f"L = {self.length_m:.3f} m, W = {self.width_m:.3f} m{x}, d = {self.d_m:.4f} m"

    def __str__(self) -> str:
        if self.kind == REACH:
            low, high = self.limit_m
            return (
                f"{self.point_name} at {self.value_m:.4f} m from the base is outside the arm's reach "
                f"[{low:.4f}, {high:.4f}] m ({self.where})"
            )
        if self.kind == END_POSE:
            if self.value_m <= 0.0:
                return (
                    f"the arm's pose at {self.point_name} collides with the obstacle (clearance "
                    f"{self.value_m * 1e3:.2f} mm; {self.where})"
                )
            return (
                f"the arm's pose at {self.point_name} keeps {self.value_m * 1e3:.2f} mm from the obstacle, less than "
                f"{self.limit_m[0] * 1e3:.2f} mm ({self.where})"
            )
        return f"the obstacle covers the arm's base ({self.where})"


@dataclass(frozen=True)
class SceneWindow:
    """The interval of d over which every obstacle of a range passes the build's pre-checks with
    end poses that keep the required clearance, and the value to use.

    Attributes:
        low_m, high_m: The window's edges [m]; both pass on the whole grid.
        low_reason, high_reason: What fails just below ``low_m`` and just above ``high_m``, at
            the value ``reason.d_m`` within ``tolerance_m`` of the edge.
        recommended_m: The value to use [m] (the middle, rounded; checked on the whole grid).
        recommended_clearance_m: The least clearance of the end poses over the grid there [m].
        length_range_m, width_range_m: The (L, W) range the window holds over [m].
        centre_x_range_m: The range of x it holds over too [m], or None (x fixed).
        shrunk: True if that range is narrower than the one asked for.
        requested_length_range_m, requested_width_range_m: The range asked for [m].
        requested_window_m: The window over the range asked for when the range is shrunk (it
            was narrower than ``min_width_m``) [m], or None (none, or not shrunk).
        end_pose_clearance_m: The clearance the end poses keep inside the window [m].
        min_width_m: The narrowest window worth a build [m] (:attr:`narrow` below it).
        tolerance_m: Bracket of each edge: the failing value of its reason lies within it [m].
    """

    low_m: float
    high_m: float
    low_reason: Failure
    high_reason: Failure
    recommended_m: float
    recommended_clearance_m: float
    length_range_m: tuple[float, float]
    width_range_m: tuple[float, float]
    centre_x_range_m: tuple[float, float] | None
    shrunk: bool
    requested_length_range_m: tuple[float, float]
    requested_width_range_m: tuple[float, float]
    requested_window_m: tuple[float, float] | None
    end_pose_clearance_m: float
    min_width_m: float = 0.01
    tolerance_m: float = 1e-4

    @property
    def width_m(self) -> float:
        """high_m - low_m [m]."""
        return self.high_m - self.low_m

    @property
    def narrow(self) -> bool:
        """True if the window is narrower than ``min_width_m`` (no shrunk range gave a wider one)."""
        return self.width_m < self.min_width_m

    def __post_init__(self) -> None:
        for name in ("low_m", "high_m", "recommended_m", "end_pose_clearance_m", "tolerance_m"):
            if not math.isfinite(getattr(self, name)):
                raise InvalidParameterError(name, getattr(self, name), "a finite value [m]")
        if not self.low_m <= self.recommended_m <= self.high_m:
            raise InvalidParameterError(
                "recommended_m", self.recommended_m, f"within the window [{self.low_m}, {self.high_m}] m"
            )

    def lines(self) -> list[str]:
        """The window in words: range, edges with their reasons, recommended value."""
        (l0, l1), (w0, w1) = self.length_range_m, self.width_range_m
        over = f"L in [{l0:.3f}, {l1:.3f}] m, W in [{w0:.3f}, {w1:.3f}] m"
        if self.centre_x_range_m is not None:
            over += f", x in [{self.centre_x_range_m[0]:.3f}, {self.centre_x_range_m[1]:.3f}] m"
        lines = []
        if self.shrunk:
            (r0, r1), (s0, s1) = self.requested_length_range_m, self.requested_width_range_m
            asked = f"L in [{r0:.3f}, {r1:.3f}] m, W in [{s0:.3f}, {s1:.3f}] m"
            if self.centre_x_range_m is not None:
                asked += f", x in [{self.centre_x_range_m[0]:.3f}, {self.centre_x_range_m[1]:.3f}] m"
            if self.requested_window_m is None:
                lines.append(f"no d fits {asked}: the range is shrunk")
            else:
                low, high = self.requested_window_m
                lines.append(
                    f"the window of d over {asked}, [{low:.4f}, {high:.4f}] m, is only {(high - low) * 1e3:.1f} mm "
                    f"wide (< {self.min_width_m * 1e3:g} mm): the range is shrunk"
                )
        lines += [
            f"window of d (the obstacle's far edge y) over {over}: [{self.low_m:.4f}, {self.high_m:.4f}] m",
            f"  below {self.low_m:.4f} m: {self.low_reason}",
            f"  above {self.high_m:.4f} m: {self.high_reason}",
            f"recommended d = {self.recommended_m:.3f} m (the middle, rounded); the end poses keep at least "
            f"{self.recommended_clearance_m * 1e3:.2f} mm there (required {self.end_pose_clearance_m * 1e3:.2f} mm)",
        ]
        if self.narrow:
            lines.append(
                f"caution: the window is only {self.width_m * 1e3:.1f} mm wide (< {self.min_width_m * 1e3:g} mm): the "
                "DOE optima then have little room between the margin at the end poses and the stretched arm at P1, "
                "and the build may not converge; a narrower L or W range (--L-range, --W-range) widens the window"
            )
        return lines


@dataclass(frozen=True, eq=False)
class _Search:
    """The fixed inputs of one search."""

    arm: PlanarArm
    scene: Scene
    fitness: FitnessConfig
    family: TrajectoryFamily
    required_m: float
    settings: WindowSettings


@dataclass(frozen=True)
class _Found:
    """A window found on a grid."""

    low_m: float
    high_m: float
    low_reason: Failure
    high_reason: Failure
    recommended_m: float
    recommended_clearance_m: float


def _reach(search: _Search, size: Size, d_m: float) -> tuple[Failure | None, tuple[Obstacle, np.ndarray] | None]:
    """The build's path check of obstacle ``size`` at far edge ``d_m`` (as
    :func:`pipeline.offline.fitness.fitness_problem` makes it: P1..P5 within the reach, the base
    left free, the inverse kinematics of P1 and P5 on the family's elbow branch): the failure, or
    the obstacle and its end poses' joint angles (2, 2) [rad]."""
    L, W, x = size
    scene = search.scene.with_checked(centre_x_m=float(x), top_y_m=float(d_m))
    obstacle = Obstacle.in_scene(L, W, scene)
    try:
        path = desired_path(obstacle, scene, search.arm.reach_m)
        context = search.family.endpoint_context(path, search.arm.link_lengths_m, search.fitness.elbow)
    except UnreachableObstacleError as exc:
        return Failure(REACH, exc.point_name, d_m, L, W, x, exc.radius_m, tuple(exc.reach_m)), None
    except InvalidParameterError:
        if not d_m - W <= 0.0 <= d_m:
            raise
        return Failure(BASE, "", d_m, L, W, x, d_m - W, (0.0, math.inf)), None
    return None, (obstacle, np.array([context.theta_start_rad, context.theta_end_rad]))


def _end_pose_clearances(search: _Search, reached: list[tuple[Obstacle, np.ndarray]]) -> np.ndarray:
    """The least link clearance [m] of the poses at P1 and P5 of each obstacle, shape (n, 2): the
    fitness's clearance route, as :func:`pipeline.offline.convergence.end_pose_collisions` takes
    it; the analytic route in one call over all the obstacles (its function accepts a box per
    configuration), another route obstacle by obstacle."""
    if not reached:
        return np.empty((0, 2))
    q = np.stack([angles for _, angles in reached])
    route, arm = search.fitness.clearance_route, search.arm
    if isinstance(route, AnalyticRoute):
        centres = np.stack([obstacle.center_m[:2] for obstacle, _ in reached])[:, None, :]
        halves = np.stack([obstacle.core_half_extents_m[:2] for obstacle, _ in reached])[:, None, :]
        radius = search.scene.corner_radius_m
        clearance = link_box_clearance(q, arm.link_lengths_m, arm.link_radii_m, centres, halves, radius)
    else:
        clearance = np.stack([route.function(arm, obstacle)(angles) for obstacle, angles in reached])
    return clearance.min(axis=-1)


def _verdicts(search: _Search, sizes: list[Size], d_m: float, first_only: bool = False) -> tuple[list[Failure], float]:
    """The failures of the obstacles ``sizes`` at ``d_m`` and the least end-pose clearance of
    those that pass [m] (inf if none). ``first_only``: stop at the first reach failure and move
    that obstacle to the front of ``sizes`` (the next value near this one likely fails on it too)."""
    failures, reached, owners = [], [], []
    for index, size in enumerate(sizes):
        failure, item = _reach(search, size, d_m)
        if failure is None:
            reached.append(item)
            owners.append(size)
        elif first_only:
            sizes.insert(0, sizes.pop(index))
            return [failure], math.nan
        else:
            failures.append(failure)
    least = math.inf
    for size, pair in zip(owners, _end_pose_clearances(search, reached), strict=True):
        index = int(np.argmin(pair))
        value = float(pair[index])
        if value <= 0.0 or value < search.required_m:  # the build refuses <= 0
            failures.append(Failure(END_POSE, ("P1", "P5")[index], d_m, *size, value, (search.required_m, math.inf)))
        else:
            least = min(least, value)
    return failures, least


def _worst(failures: list[Failure]) -> Failure | None:
    return max(failures, key=lambda f: f.excess_m) if failures else None


def _first_failure(search: _Search, sizes: list[Size], d_m: float) -> Failure | None:
    """A failure of ``sizes`` at ``d_m`` (cheapest first), or None."""
    failures, _ = _verdicts(search, sizes, d_m, first_only=True)
    return failures[0] if failures else None


#: A run of a scan: (the failing value above, the passing values (descending), the failing value below) [m].
Run = tuple[float, list[float], float]


def _runs(search: _Search, sizes: list[Size], low_m: float, high_m: float, step_m: float | None = None) -> list[Run]:
    """The runs of passing values of a scan of (low_m, high_m) downwards in steps of about
    ``step_m`` (default: the settings'), both ends taken as failing."""
    step = search.settings.scan_step_m if step_m is None else step_m
    count = max(1, math.ceil((high_m - low_m) / step))
    runs, passing, above = [], [], high_m
    for k in range(1, count + 1):
        d = high_m - (high_m - low_m) * k / count
        if k < count and _first_failure(search, sizes, d) is None:
            passing.append(d)
            continue
        if passing:
            runs.append((above, passing, d))
            passing = []
        above = d
    return runs


def _width(run: Run) -> float:
    return run[1][0] - run[1][-1]


def _edge(search: _Search, sizes: list[Size], inside: float, outside: float) -> tuple[float, Failure]:
    """Bisect between a passing and a failing d [m] to the tolerance: the passing end, and the
    worst failure of ``sizes`` at the failing end."""
    while abs(outside - inside) > search.settings.tolerance_m:
        middle = 0.5 * (inside + outside)
        if _first_failure(search, sizes, middle) is None:
            inside = middle
        else:
            outside = middle
    worst = _worst(_verdicts(search, sizes, outside)[0])
    assert worst is not None  # outside failed on one of sizes
    return inside, worst


def _rounded_middle(low_m: float, high_m: float, steps: tuple[float, ...]) -> float:
    """The middle of [low_m, high_m], rounded to the first step that keeps it inside (else as is)."""
    middle = 0.5 * (low_m + high_m)
    for step in steps:
        candidates = [round(k * step, 10) for k in (math.floor(middle / step), math.ceil(middle / step))]
        inside = [c for c in candidates if low_m <= c <= high_m]
        if inside:
            return min(inside, key=lambda c: abs(c - middle))
    return middle


def _axes(search: _Search, lengths: tuple, widths: tuple, xs: tuple | None) -> tuple[np.ndarray, ...]:
    """The levels of L, W and x of the build's pre-check grid over a range [m]."""
    points = search.settings.grid_points
    x_levels = np.array([search.scene.centre_x_m]) if xs is None else np.linspace(*xs, search.settings.centre_x_points)
    return np.linspace(*lengths, points), np.linspace(*widths, points), x_levels


def _grid(axes: tuple[np.ndarray, ...], picks: tuple[list[int], ...] | None = None) -> list[Size]:
    """The obstacles of the grid on ``axes`` (x outermost, then W, then L, as the build's
    groups), or those at the indices ``picks`` of each axis (sorted, unique)."""
    if picks is not None:
        axes = tuple(axis[sorted(set(p % len(axis) for p in pick))] for axis, pick in zip(axes, picks, strict=True))
    lengths, widths, x_levels = axes
    return [(float(L), float(W), float(x)) for x in x_levels for W in widths for L in lengths]


def _screen(axes: tuple[np.ndarray, ...]) -> list[Size]:
    """Corners and centre of a grid (points of it), the obstacles a range is screened on."""
    centre = [len(axis) // 2 for axis in axes]
    corners = _grid(axes, ([0, -1], [0, -1], [0, centre[2], -1]))
    return list(dict.fromkeys(corners + _grid(axes, ([centre[0]], [centre[1]], [0, centre[2], -1]))))


def _seed(axes: tuple[np.ndarray, ...]) -> list[Size]:
    """The first active set: the corners and centre, then the 3 x 3 (x 3) levels of the grid."""
    middle = [[0, len(axis) // 2, -1] for axis in axes]
    return list(dict.fromkeys(_screen(axes) + _grid(axes, tuple(middle))))


def _recommended(search: _Search, sizes: list[Size], low_m: float, high_m: float, passing: list[float]) -> float:
    """The middle of [low_m, high_m] rounded (:func:`_rounded_middle`) if it passes on ``sizes``,
    else the passing value of the scan nearest to the middle."""
    rounded = _rounded_middle(low_m, high_m, search.settings.rounding_m)
    if _first_failure(search, sizes, rounded) is None:
        return rounded
    return min(passing, key=lambda d: abs(d - 0.5 * (low_m + high_m)))


def _window_over(search: _Search, axes: tuple[np.ndarray, ...], active: list[Size]) -> _Found | None:
    """The widest window of the grid's obstacles, searched on an active set that grows by the
    obstacles the whole grid's checks find failing (module docstring); None if none fits."""
    grid = _grid(axes)
    active = list(dict.fromkeys(active))
    low = float(axes[1].max())  # the widest obstacle covers the base here
    high = search.arm.reach_m[1] + low + search.scene.apex_dy_m + search.settings.scan_step_m
    while True:  # each round adds an obstacle of the finite grid
        runs = _runs(search, active, low, high)
        if not runs:
            return None
        above, passing, below = max(runs, key=_width)
        high_m, high_reason = _edge(search, active, passing[0], above)
        low_m, low_reason = _edge(search, active, passing[-1], below)
        recommended = _recommended(search, active, low_m, high_m, passing)
        missed, least = [], math.inf
        for d in (low_m, recommended, high_m):  # each passes on the active set
            failures, clearance = _verdicts(search, grid, d)
            worst = _worst(failures)
            if worst is not None:
                missed.append((worst.length_m, worst.width_m, worst.centre_x_m))
            if d == recommended:
                least = clearance
        if not missed:
            return _Found(low_m, high_m, low_reason, high_reason, recommended, least)
        active += list(dict.fromkeys(missed))
        low, high = below, above


def _sub_ranges(range_m: tuple[float, float], settings: WindowSettings) -> list[list[tuple[float, float]]]:
    """The shrunk ranges of ``range_m`` on its lattice, grouped by width, widest group first."""
    edges = [float(round(v, 12)) for v in np.linspace(*range_m, settings.shrink_lattice + 1)]
    last = settings.shrink_lattice
    return [
        [(edges[i], edges[i + steps]) for i in range(last - steps + 1)]
        for steps in range(last - 1, settings.shrink_min_steps - 1, -1)
    ]


def _passing(search: _Search, sizes: list[Size], values: list[float]) -> dict[Size, np.ndarray]:
    """Which of ``values`` of d each obstacle passes on its own (a boolean array per obstacle)."""
    passes = {size: np.ones(len(values), dtype=bool) for size in sizes}
    for k, d in enumerate(values):
        for failure in _verdicts(search, sizes, d)[0]:
            passes[(failure.length_m, failure.width_m, failure.centre_x_m)][k] = False
    return passes


def _shrunk(search: _Search, lengths: tuple, widths: tuple, xs: tuple | None) -> tuple[_Found, tuple, tuple] | None:
    """The window at least ``min_width_m`` wide over the widest shrunk L range (the W range as
    asked), else over the widest shrunk W range (the L range as asked): the window and the
    (L, W) range, or None.

    Each candidate range is screened first on obstacles of its grid: its two shrunk ends, each
    with the least, middle and greatest value of the other range (and of x), judged once per
    lattice level at the scan's values; only a candidate whose obstacles share enough passing
    values for that width is searched, those sharing the most first within a width."""
    settings, step = search.settings, search.settings.scan_step_m
    needed = max(1, math.floor(settings.min_width_m / step) - 1)  # shared samples of such a window
    high = search.arm.reach_m[1] + widths[1] + search.scene.apex_dy_m + step
    values = [float(v) for v in np.arange(widths[0] + step, high, step)]
    axes = _axes(search, lengths, widths, xs)
    x_levels = list(dict.fromkeys(float(v) for v in axes[2][[0, len(axes[2]) // 2, -1]]))
    for shrink_length in (True, False):
        fixed = axes[1] if shrink_length else axes[0]
        others = list(dict.fromkeys(float(v) for v in fixed[[0, len(fixed) // 2, -1]]))
        groups = _sub_ranges(lengths if shrink_length else widths, settings)
        levels = sorted({end for group in groups for sub in group for end in sub})

        def size(level: float, other: float, x: float) -> Size:
            return (level, other, x) if shrink_length else (other, level, x)  # noqa: B023

        passes = _passing(search, [size(v, o, x) for v in levels for o in others for x in x_levels], values)
        for group in groups:
            screened = []
            for sub in group:
                members = [passes[size(v, o, x)] for v in sub for o in others for x in x_levels]
                shared = int(np.logical_and.reduce(members).sum())
                if shared >= needed:
                    screened.append((shared, sub))
            for _, sub in sorted(screened, key=lambda item: -item[0]):
                ranges = (sub, widths) if shrink_length else (lengths, sub)
                candidate = _axes(search, *ranges, xs)
                found = _window_over(search, candidate, _seed(candidate))
                if found is not None and found.high_m - found.low_m >= settings.min_width_m:
                    return found, *ranges
    return None


def _reach_failures(search: _Search, size: Size, d_m: float) -> list[Failure]:
    """Every constraint point of the obstacle outside the reach at ``d_m`` (the test of
    :func:`pipeline.motion.path.desired_path`, which stops at the first), or the base covered."""
    L, W, x = size
    if d_m - W <= 0.0 <= d_m:
        return [Failure(BASE, "", d_m, L, W, x, d_m - W, (0.0, math.inf))]
    scene = replace(search.scene, top_y_m=float(d_m), centre_x_m=float(x))
    low, high = search.arm.reach_m
    radii = [float(np.hypot(*point)) for point in constraint_points(Obstacle.in_scene(L, W, scene), scene)]
    return [
        Failure(REACH, name, d_m, L, W, x, radius, (low, high))
        for name, radius in zip(POINT_NAMES, radii, strict=True)
        if not low <= radius <= high
    ]


def _bound(search: _Search, sizes: list[Size], failure: Failure, values: list[float]) -> tuple[float | None, Failure]:
    """How far d must move for ``failure``'s constraint (its point's reach, or the base) to pass on
    every obstacle of ``sizes``: the first value of ``values`` (ordered away from the failure)
    where it passes, bisected to the tolerance, or None if none does; and the failure nearest it."""

    def fails(d: float) -> Failure | None:
        same = [
            f
            for size in sizes
            for f in _reach_failures(search, size, d)
            if f.kind == failure.kind and f.point_name == failure.point_name
        ]
        return _worst(same)

    outside, last = failure.d_m, failure
    for d in values:
        found = fails(d)
        if found is None:
            inside = d
            break
        outside, last = d, found
    else:
        return None, min((fails(d) for d in values), key=lambda f: f.excess_m, default=last)
    while abs(inside - outside) > search.settings.tolerance_m:
        middle = 0.5 * (inside + outside)
        found = fails(middle)
        if found is None:
            inside = middle
        else:
            outside, last = middle, found
    return inside, last


def _bound_text(failure: Failure, bound: float | None) -> str:
    """One constraint's requirement on d in words (``bound`` None: no d meets it)."""
    where = f"L = {failure.length_m:.3f} m, W = {failure.width_m:.3f} m"
    if failure.centre_x_m != 0.0:
        where += f", x = {failure.centre_x_m:.3f} m"
    if bound is None:
        return f"no d brings {failure.point_name} of every obstacle into the arm's reach (at best: {failure})"
    if failure.kind == BASE:
        return f"the obstacle needs d >= {bound:.4f} m to leave the arm's base free ({where})"
    relation = "<=" if failure.too_far else ">="
    return f"{failure.point_name} needs d {relation} {bound:.4f} m for the reach ({where})"


def _reach_refusal(search: _Search, sizes: list[Size], values: list[float], failures: dict) -> tuple:
    """Reasons when the reach alone leaves no d: at the value nearest to passing, the binding
    constraint of each direction and how far d must move for it. Returns (reasons, the least d
    the constraints below need or None, the most d the constraints above allow or None)."""
    everywhere = set.intersection(*({(f.kind, f.point_name) for f in failures[d]} for d in values))
    if everywhere:  # one named (P5 mirrors P1)
        kind, name = min(everywhere)
        same = [_worst([f for f in failures[d] if (f.kind, f.point_name) == (kind, name)]) for d in values]
        return (_bound_text(min(same, key=lambda f: f.excess_m), None),), None, None
    closest = min(values, key=lambda d: max(f.excess_m for f in failures[d]))
    reasons, lowest, highest = [], None, None
    for too_far in (False, True):
        side = [f for f in failures[closest] if f.too_far == too_far]
        if not side:
            continue
        # A point beyond the reach needs a lower d (y1 = d); one too near the base, a higher d.
        away = [d for d in reversed(values) if d < closest] if too_far else [d for d in values if d > closest]
        bounds = [(*_bound(search, sizes, f, away), f) for f in {(f.kind, f.point_name): f for f in side}.values()]
        unmet = [b for b in bounds if b[0] is None]
        if unmet:
            bound, failure, _ = unmet[0]
        else:
            bound, failure, _ = (min if too_far else max)(bounds, key=lambda b: b[0])
        reasons.append(_bound_text(failure, bound))
        if too_far:
            highest = bound
        else:
            lowest = bound
    return tuple(reasons), lowest, highest


def _best_failure(search: _Search, axes: tuple[np.ndarray, ...], values: list[float]) -> Failure | None:
    """The mildest of the worst failures at ``values`` on the first of the grid's corners and
    centre, its 3 x 3 levels and the whole grid that fails at every one of them (None if none
    does: the passing values are isolated); ties go to the highest d."""
    for obstacles in (_screen(axes), _seed(axes), _grid(axes)):
        best = None
        for d in reversed(values):
            worst = _worst(_verdicts(search, obstacles, d)[0])
            if worst is None:
                best = None
                break
            if best is None or worst.excess_m < best.excess_m:
                best = worst
        if best is not None:
            return best
    return None


def _refusal(search: _Search, axes: tuple[np.ndarray, ...], shrink_tried: bool) -> NoSceneWindowError:
    """Why no d fits the grid on ``axes``, judged on its corners and centre: the reach
    constraints that contradict each other, or, where the reach leaves a run of d, the best the
    end poses do there."""
    sizes = _screen(axes)
    step = search.settings.scan_step_m
    low = float(axes[1].max())
    high = search.arm.reach_m[1] + low + search.scene.apex_dy_m + step
    values = [float(v) for v in np.arange(low + step, high + step / 2, step)]
    failures = {d: [f for size in sizes for f in _reach_failures(search, size, d)] for d in values}
    ranges = (tuple(float(v) for v in axes[0][[0, -1]]), tuple(float(v) for v in axes[1][[0, -1]]))
    runs, start = [], None  # (first, last) index of each run of values the reach allows
    for index, d in enumerate(values):
        if not failures[d] and start is None:
            start = index
        if start is not None and (failures[d] or index == len(values) - 1):
            runs.append((start, index - 1 if failures[d] else index))
            start = None
    if not runs:
        return NoSceneWindowError(*ranges, *_reach_refusal(search, sizes, values, failures), shrink_tried)
    first, last = max(runs, key=lambda run: run[1] - run[0])
    bottom, top = values[first], values[last]
    sides = [(first - 1, "below"), (last + 1, "above")]
    named = [
        f"{_worst(failures[values[i]]).point_name or 'the base'} {side}" for i, side in sides if 0 <= i < len(values)
    ]
    best = _best_failure(search, axes, values[first : last + 1])
    reason = f"the reach allows d in [{bottom:.4f}, {top:.4f}] m ({' and '.join(named)} it), and " + (
        f"everywhere there (at best) {best}"
        if best is not None
        else f"the passing values there are isolated (narrower than the scan's {step * 1e3:g} mm)"
    )
    return NoSceneWindowError(*ranges, (reason,), bottom, top, shrink_tried)


def _checked_range(name: str, value: object) -> tuple[float, float]:
    """``value`` as (min, max) [m] with 0 < min < max, both finite."""
    try:
        low, high = (float(v) for v in value)  # type: ignore[union-attr]
    except (TypeError, ValueError):
        raise InvalidParameterError(name, value, "(min, max) [m]") from None
    if not (math.isfinite(low) and math.isfinite(high) and 0.0 < low < high):
        raise InvalidParameterError(name, value, "finite 0 < min < max [m]")
    return low, high


def scene_window(
    arm: PlanarArm,
    scene: Scene,
    length_range_m: tuple[float, float],
    width_range_m: tuple[float, float],
    centre_x_range_m: tuple[float, float] | None = None,
    *,
    fitness: FitnessConfig | None = None,
    family: TrajectoryFamily = PAPER,
    settings: WindowSettings | None = None,
) -> SceneWindow:
    """The window of the obstacle's far edge d [m] over which every obstacle of the range passes
    the build's pre-checks with end poses that keep the required clearance, and the d to use.

    Args:
        arm: The arm.
        scene: The scene; every field but ``top_y_m`` (and ``centre_x_m`` when x varies) stays.
        length_range_m, width_range_m: The (L, W) range of the build [m].
        centre_x_range_m: The range of the obstacle's centre x when the build varies it [m], else None.
        fitness: The build's objective settings (its elbow branch and clearance route).
        family: The build's trajectory family.
        settings: How to search (:class:`WindowSettings`).

    Raises:
        InvalidParameterError: a range that is not 0 < min < max (x: min < max).
        NoSceneWindowError: no d fits the range, nor a shrunk one (with ``settings.shrink``).
    """
    settings = WindowSettings() if settings is None else settings
    lengths = _checked_range("L range", length_range_m)
    widths = _checked_range("W range", width_range_m)
    xs = None
    if centre_x_range_m is not None:
        xs = tuple(float(v) for v in centre_x_range_m)
        if len(xs) != 2 or not (math.isfinite(xs[0]) and math.isfinite(xs[1]) and xs[0] < xs[1]):
            raise InvalidParameterError("x range", centre_x_range_m, "finite min < max [m]")
    required = scene.margin_m if settings.end_pose_clearance_m is None else settings.end_pose_clearance_m
    search = _Search(arm, scene, FitnessConfig() if fitness is None else fitness, family, required, settings)
    search.fitness.clearance_route.check_arm(arm)  # as fitness_problem does
    axes = _axes(search, lengths, widths, xs)
    found, used, asked = _window_over(search, axes, _seed(axes)), (lengths, widths), None
    if settings.shrink and (found is None or found.high_m - found.low_m < settings.min_width_m):
        shrunk = _shrunk(search, lengths, widths, xs)
        if shrunk is not None:
            asked = None if found is None else (found.low_m, found.high_m)
            found, used = shrunk[0], shrunk[1:]
    if found is None:
        raise _refusal(search, axes, settings.shrink)
    return SceneWindow(
        found.low_m,
        found.high_m,
        found.low_reason,
        found.high_reason,
        found.recommended_m,
        found.recommended_clearance_m,
        used[0],
        used[1],
        xs,
        used != (lengths, widths),
        lengths,
        widths,
        asked,
        required,
        settings.min_width_m,
        settings.tolerance_m,
    )
