"""A sweep's results in Meshcat: a map of the (L, W) plane and the worst cases animated.

Left, the map: every sampled (L, W) is a dot coloured by its clearance (red at 0 mm or
less, through yellow, to green at the sweep's largest clearance; grey if unknown), failed
cases are crossed out in black, and the worst cases are tagged "A" and "B". Given a region map
(the range certificate), its leaves are drawn under the dots, coloured by status and shaded by
their clearance bound as in the sweep's PNG (:mod:`verify.acceptance.map_leaves`: one mesh with
vertex colours), and its worst leaf is outlined in magenta. To its right,
each worst case (A: lowest certified clearance, B: largest endpoint error; one panel if
they coincide) is regenerated and drawn as in :mod:`verify.viewer.trajectory_view`: arm,
obstacle, both paths, constraint points, minimum clearance, and the motion in the page's
animation (all cases play together).

A sweep case is a :class:`verify.acceptance.results.CaseResult` (what ``verify.sweep`` hands
over), or a mapping with the keys of :data:`CASE_KEYS` (a case of the sweep's ``--json``, read
back from a file): lengths in metres, ``passed`` a bool; a clearance may be None or NaN if
unknown. Either becomes a :class:`SweepPoint`, checked once.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from pipeline.certify.region_map import STATUSES, RegionMap
from pipeline.exceptions import InvalidParameterError, PipelineError
from pipeline.model.arm import PlanarArm, load_planar_arm
from verify.acceptance.map_leaves import leaf_drawing
from verify.acceptance.results import CaseResult

from ._meshcat import meshcat, mg, mtf
from .browser import BrowserConfig
from .drawing import (
    DrawnCase,
    TopDownCamera,
    ViewStyle,
    case_bounds,
    draw_case,
    draw_label,
    label_height_m,
    new_animation,
    send_animation,
    setup_view,
    tube_mesh,
)
from .server import MeshcatServer, ServerConfig, serve_until_interrupted
from .trajectory_view import (
    GeneratedLike,
    RenderedView,
    case_from_generated,
    export_html,
    screenshot_page,
    write_html,
)

#: Keys every sweep case must have.
CASE_KEYS = (
    "L",
    "W",
    "clearance_m",
    "certified_clearance_m",
    "endpoint_error_start_m",
    "endpoint_error_end_m",
    "passed",
)

#: A callable that regenerates the trajectory for (L [m], W [m]), or generator coefficients.
TrajectorySource = Callable[[float, float], GeneratedLike] | object

_RED, _YELLOW, _GREEN, _GREY = (215, 48, 39), (254, 224, 139), (26, 152, 80), (150, 150, 150)


@dataclass(frozen=True)
class MapLayout:
    """Size of the (L, W) map in the scene.

    Attributes:
        size_m: Side of the square plotting area [m].
        dot_radius_m: Radius of a case's dot [m].
        gap_m: Space between the map and the case panels, and between panels [m].
    """

    size_m: float = 0.6
    dot_radius_m: float = 0.012
    gap_m: float = 0.12


@dataclass(frozen=True)
class WorstCase:
    """A case picked for display.

    Attributes:
        tag: "A", "B" or "A+B".
        reason: Why it was picked, with its value.
        L_m, W_m: The obstacle [m].
    """

    tag: str
    reason: str
    L_m: float
    W_m: float


def _number(case: Mapping[str, Any], key: str) -> float:
    value = case.get(key)
    try:
        return float("nan") if value is None else float(value)
    except (TypeError, ValueError):
        raise InvalidParameterError(key, value, "a number or None") from None


def _or_nan(value: float | None) -> float:
    return float("nan") if value is None else float(value)


@dataclass(frozen=True)
class SweepPoint:
    """What the sweep view shows of one case. Unknown numbers are NaN.

    Attributes:
        L_m, W_m: Obstacle size [m] (positive, finite).
        clearance_m: Sampled minimum clearance [m].
        certified_clearance_m: Certified clearance [m].
        endpoint_error_m: The larger endpoint error [m].
        passed: The case passed every check.
    """

    L_m: float
    W_m: float
    clearance_m: float
    certified_clearance_m: float
    endpoint_error_m: float
    passed: bool

    def __post_init__(self) -> None:
        for name in ("L_m", "W_m"):
            value = getattr(self, name)
            if not math.isfinite(value) or value <= 0:
                raise InvalidParameterError(name, value, "a positive finite length [m]")

    @classmethod
    def from_case(cls, case: CaseResult) -> SweepPoint:
        """The point of a measured (or failed) case."""
        return cls(
            case.L_m,
            case.W_m,
            _or_nan(case.clearance_m),
            _or_nan(case.certified_clearance_m),
            _or_nan(case.endpoint_error_m),
            case.passed,
        )

    @classmethod
    def from_json(cls, case: Mapping[str, Any], index: int = 0) -> SweepPoint:
        """The point of a case of the sweep's JSON (keys :data:`CASE_KEYS`).

        Raises:
            InvalidParameterError: a key is missing, a number is not one, or L or W is not a positive length.
        """
        missing = [key for key in CASE_KEYS if key not in case]
        if missing:
            raise InvalidParameterError(f"cases[{index}]", dict(case), f"the keys {CASE_KEYS}; missing {missing}")
        for key in ("L", "W"):
            value = _number(case, key)
            if not math.isfinite(value) or value <= 0:
                raise InvalidParameterError(f"cases[{index}][{key!r}]", case[key], "a positive finite length [m]")
        return cls(
            _number(case, "L"),
            _number(case, "W"),
            _number(case, "clearance_m"),
            _number(case, "certified_clearance_m"),
            float(np.fmax(_number(case, "endpoint_error_start_m"), _number(case, "endpoint_error_end_m"))),
            bool(case["passed"]),
        )


SweepCase = CaseResult | Mapping[str, Any]  # or an already converted SweepPoint


def sweep_points(cases: Sequence[SweepCase]) -> list[SweepPoint]:
    """The cases as :class:`SweepPoint` (already converted points pass through).

    Raises:
        InvalidParameterError: no case, or a malformed JSON case.
    """
    if len(cases) == 0:
        raise InvalidParameterError("cases", list(cases), "at least one sweep case")
    return [
        case
        if isinstance(case, SweepPoint)
        else SweepPoint.from_case(case)
        if isinstance(case, CaseResult)
        else SweepPoint.from_json(case, index)
        for index, case in enumerate(cases)
    ]


def check_cases(cases: Sequence[SweepCase]) -> None:
    """Raise InvalidParameterError unless ``cases`` is non-empty and every case is well formed."""
    sweep_points(cases)


def clearance_color(clearance_m: float, top_m: float) -> int:
    """0xRRGGBB of a clearance [m] on a red (<= 0) - yellow - green (>= top_m) scale; grey
    if unknown (NaN)."""
    if not math.isfinite(clearance_m):
        rgb = _GREY
    else:
        c = min(max(clearance_m / top_m, 0.0), 1.0) if top_m > 0 else 1.0
        low, high, u = (_RED, _YELLOW, 2 * c) if c < 0.5 else (_YELLOW, _GREEN, 2 * c - 1)
        rgb = tuple(round(a + (b - a) * u) for a, b in zip(low, high, strict=True))
    return (rgb[0] << 16) | (rgb[1] << 8) | rgb[2]


def worst_cases(cases: Sequence[SweepCase]) -> list[WorstCase]:
    """A: the lowest certified clearance; B: the largest endpoint error (max of start and
    end). One entry tagged "A+B" if both are the same case; none for a criterion that no
    case has a value for."""
    points = sweep_points(cases)
    picks: list[tuple[str, str, int]] = []
    certified = np.array([p.certified_clearance_m for p in points])
    if np.isfinite(certified).any():
        i = int(np.nanargmin(certified))
        picks.append(("A", f"lowest certified clearance {certified[i] * 1e3:.2f} mm", i))
    errors = np.array([p.endpoint_error_m for p in points])
    if np.isfinite(errors).any():
        i = int(np.nanargmax(errors))
        picks.append(("B", f"largest endpoint error {errors[i] * 1e3:.2f} mm", i))
    if len(picks) == 2 and picks[0][2] == picks[1][2]:
        picks = [("A+B", f"{picks[0][1]}\n{picks[1][1]}", picks[0][2])]
    return [WorstCase(tag, reason, points[i].L_m, points[i].W_m) for tag, reason, i in picks]


def _regenerator(source: TrajectorySource) -> Callable[[float, float], GeneratedLike]:
    if callable(source):
        return source
    from pipeline.online.generator import generate  # the coefficients route; imported only when used

    # The sweep reports extrapolation itself; regenerating its worst cases need not warn again.
    return lambda length_m, width_m: generate(source, length_m, width_m, out_of_range="ignore")


def _cross(vis: meshcat.Visualizer, center_m: np.ndarray, size_m: float, material: mg.Material) -> None:
    for name, angle in (("a", math.pi / 4), ("b", -math.pi / 4)):
        vis[name].set_object(mg.Box([size_m, size_m / 5, 0.002]), material)
        vis[name].set_transform(mtf.translation_matrix(center_m) @ mtf.rotation_matrix(angle, [0, 0, 1]))


@dataclass(frozen=True)
class MapPlacement:
    """Where (L, W) [m] lands in the map's plotting square (lower-left corner at the origin).

    Attributes:
        length_span_m, width_span_m: The (lo, hi) of L and W mapped onto the square [m].
        inset_m: Border between the square's edge and the span [m].
        size_m: Side of the square [m].
    """

    length_span_m: tuple[float, float]
    width_span_m: tuple[float, float]
    inset_m: float
    size_m: float

    def xy(self, length_m: np.ndarray | float, width_m: np.ndarray | float) -> np.ndarray:
        """Scene (x, y) [m] of each (L, W) [m], shape (..., 2)."""
        (l0, l1), (w0, w1) = self.length_span_m, self.width_span_m
        inner = self.size_m - 2 * self.inset_m
        x = self.inset_m + (np.asarray(length_m, dtype=float) - l0) / (l1 - l0) * inner
        y = self.inset_m + (np.asarray(width_m, dtype=float) - w0) / (w1 - w0) * inner
        return np.stack([x, y], axis=-1)


def _placement(points: Sequence[SweepPoint], layout: MapLayout, region_map: RegionMap | None) -> MapPlacement:
    """The spans of the cases (and of the region map's range, if given) on the square."""
    lengths = [p.L_m for p in points] + (list(region_map.range_of("L")) if region_map is not None else [])
    widths = [p.W_m for p in points] + (list(region_map.range_of("W")) if region_map is not None else [])

    def span(values: list[float]) -> tuple[float, float]:
        lo, hi = min(values), max(values)
        return (lo - 0.01, hi + 0.01) if hi - lo < 1e-9 else (lo, hi)

    return MapPlacement(span(lengths), span(widths), 2 * layout.dot_radius_m, layout.size_m)


def region_map_mesh(region_map: RegionMap, placement: MapPlacement, z_m: float = 0.001) -> mg.TriangularMeshGeometry:
    """The map's leaves as one flat mesh at height ``z_m`` [m]: two triangles per leaf, its four
    corners coloured by the leaf's status and clearance bound (vertex colours)."""
    drawing = leaf_drawing(region_map)
    r = drawing.rectangles_m
    corners = np.stack([placement.xy(r[:, a], r[:, b]) for a, b in ((0, 2), (1, 2), (1, 3), (0, 3))], axis=1)
    n = r.shape[0]
    vertices = np.concatenate([corners.reshape(4 * n, 2), np.full((4 * n, 1), z_m)], axis=1)
    first = 4 * np.arange(n)[:, None]
    faces = np.concatenate([first + [0, 1, 2], first + [0, 2, 3]], axis=0)
    return mg.TriangularMeshGeometry(vertices, faces, color=np.repeat(drawing.rgb, 4, axis=0))


def _draw_region_map(vis: meshcat.Visualizer, region_map: RegionMap, placement: MapPlacement, min_half_m: float) -> str:
    """Leaves under the dots, and the worst leaf outlined in magenta above them (the outline at
    least ``2 min_half_m`` [m] across, so that a tiny leaf stays visible); returns the title's map line."""
    vis["leaves"].set_object(
        region_map_mesh(region_map, placement), mg.MeshBasicMaterial(color=0xFFFFFF, vertexColors=True)
    )
    worst = region_map.cell(int(np.argmin(region_map.clearance_bound_m)))
    (l0, l1), (w0, w1) = worst.range_of("L"), worst.range_of("W")
    lo, hi = placement.xy(l0, w0), placement.xy(l1, w1)
    center, half = (lo + hi) / 2, np.maximum((hi - lo) / 2, min_half_m)
    corners = center + half * np.array([[-1, -1], [1, -1], [1, 1], [-1, 1], [-1, -1]])
    ring = np.concatenate([corners, np.full((5, 1), 0.02)], axis=1)
    material = mg.MeshBasicMaterial(color=0xFF00FF)
    for k in range(4):
        vis["worst_cell"][str(k)].set_object(tube_mesh(ring[k : k + 2], 0.002, sides=6), material)
    area = region_map.area
    fractions = ", ".join(
        f"{name.replace('_', '-')} {100 * area[region_map.status == k].sum():.1f} %" for k, name in enumerate(STATUSES)
    )
    return f"region map: {fractions}; worst cell (magenta) {worst.clearance_bound_m * 1e3:.2f} mm"


def draw_map(
    vis: meshcat.Visualizer,
    cases: Sequence[SweepCase],
    worst: Sequence[WorstCase],
    style: ViewStyle,
    layout: MapLayout,
    origin_m: tuple[float, float] = (0.0, 0.0),
    region_map: RegionMap | None = None,
) -> tuple[float, float, float, float]:
    """Draw the (L, W) map with its lower-left plotting corner at ``origin_m`` [m], over the
    region map's leaves if given; return the bounds (x_min, x_max, y_min, y_max) [m] of what was drawn."""
    points = sweep_points(cases)
    root = vis["sweep_map"]
    root.set_transform(mtf.translation_matrix([origin_m[0], origin_m[1], 0.0]))
    size, dot = layout.size_m, layout.dot_radius_m
    placement = _placement(points, layout, region_map)
    lengths = np.array([p.L_m for p in points])
    widths = np.array([p.W_m for p in points])
    clearances = np.array([p.clearance_m for p in points])
    top = float(np.nanmax(clearances)) if np.isfinite(clearances).any() else 0.0
    (l0, l1), (w0, w1) = placement.length_span_m, placement.width_span_m

    def place(length: float, width: float) -> np.ndarray:
        return np.array([*placement.xy(length, width), 0.004])

    frame = np.array([[0, 0, 0], [size, 0, 0], [size, size, 0], [0, size, 0], [0, 0, 0]], dtype=float)
    for k in range(4):
        root["frame"][str(k)].set_object(tube_mesh(frame[k : k + 2], 0.0015, sides=6), style.material(0x333333))
    map_line = None
    if region_map is not None:
        map_line = _draw_region_map(root["region_map"], region_map, placement, 1.5 * dot)
    failure = style.material(style.palette.failure)
    for k, point in enumerate(points):
        node = root["cases"][f"{k:04d}_L{lengths[k]:.4f}_W{widths[k]:.4f}"]
        center = place(lengths[k], widths[k])
        node["dot"].set_object(mg.Sphere(dot), style.material(clearance_color(clearances[k], top)))
        node["dot"].set_transform(mtf.translation_matrix(center))
        if not point.passed:
            _cross(node["failed"], center + [0, 0, dot + 0.003], 2.6 * dot, failure)
    failed = sum(not p.passed for p in points)
    bounds = [0.0, size, 0.0, size]
    if style.show_labels:
        for pick in worst:
            tag_xy = place(pick.L_m, pick.W_m)[:2] + [0.0, 2.6 * dot]
            draw_label(root["tags"][pick.tag], pick.tag, [*tag_xy, 0.02], style, height_m=0.022)
        draw_label(root["x_label"], f"L [m]: {l0:.3f} (left) to {l1:.3f} (right)", [size / 2, -0.035, 0.02], style)
        draw_label(root["y_label"], f"W [m]: {w0:.3f} (bottom) to {w1:.3f} (top)", [0, 0, 0.02], style)
        root["y_label"].set_transform(
            mtf.translation_matrix([-0.035, size / 2, 0.02]) @ mtf.rotation_matrix(math.pi / 2, [0, 0, 1])
        )
        title = (
            f"sweep: {len(cases)} cases, {failed} failed (x)\ncolour: clearance 0 (red) to {top * 1e3:.1f} mm (green)"
        )
        if map_line is not None:
            title += "\n" + map_line
        draw_label(root["title"], title, [size / 2, size + 0.03 + label_height_m(title) / 2, 0.02], style)
        bounds = [-0.06, size, -0.06, size + 0.03 + label_height_m(title)]
    return (bounds[0] + origin_m[0], bounds[1] + origin_m[0], bounds[2] + origin_m[1], bounds[3] + origin_m[1])


def draw_sweep_view(
    vis: meshcat.Visualizer,
    cases: Sequence[SweepCase],
    trajectory_for: TrajectorySource,
    style: ViewStyle,
    arm: PlanarArm | None = None,
    layout: MapLayout | None = None,
    region_map: RegionMap | None = None,
) -> RenderedView:
    """Draw the map (over the region map's leaves, if given) and the worst cases side by side,
    animate them, frame the camera.

    A worst case whose trajectory cannot be regenerated (a PipelineError) is shown as a
    label with the error instead.
    """
    points = sweep_points(cases)  # checked and converted once
    arm = arm if arm is not None else load_planar_arm()
    layout = layout if layout is not None else MapLayout()
    regenerate = _regenerator(trajectory_for)
    worst = worst_cases(points)
    map_bounds = draw_map(vis, points, worst, style, layout, region_map=region_map)
    cursor = map_bounds[1] + layout.gap_m
    y_min, y_max = map_bounds[2], map_bounds[3]
    x_max = map_bounds[1]
    animation = new_animation(style)
    drawn: list[DrawnCase] = []
    for pick in worst:
        title = f"{pick.tag}: L = {pick.L_m:.3f} m, W = {pick.W_m:.3f} m\n{pick.reason}"
        node = f"worst_{pick.tag.replace('+', '_')}"
        try:
            case = case_from_generated(regenerate(pick.L_m, pick.W_m), arm, title)
        except PipelineError as exc:
            draw_label(vis[node], f"{title}\nnot regenerated: {exc}", [cursor + 0.25, 0.3, 0.02], style)
            x_max = cursor + 0.5
            cursor = x_max + layout.gap_m
            continue
        x0 = case_bounds(case)[0]
        drawn_case = draw_case(vis, case, style, animation, node=node, offset_m=(cursor - x0, 0.0))
        drawn.append(drawn_case)
        x_max = drawn_case.bounds_m[1]
        cursor = x_max + layout.gap_m
        y_min, y_max = min(y_min, drawn_case.bounds_m[2]), max(y_max, drawn_case.bounds_m[3])
    camera = TopDownCamera.fit((map_bounds[0], x_max, y_min, y_max), style.aspect, style.margin_m)
    setup_view(vis, style, camera)
    if drawn:
        send_animation(vis, animation, style)
    return RenderedView(camera, tuple(drawn))


def sweep_page(
    cases: Sequence[SweepCase],
    trajectory_for: TrajectorySource,
    *,
    arm: PlanarArm | None = None,
    style: ViewStyle | None = None,
    server_config: ServerConfig | None = None,
    region_map: RegionMap | None = None,
) -> tuple[str, RenderedView]:
    """The self-contained HTML page of the sweep view and what it shows."""
    style = style if style is not None else ViewStyle(aspect=2.0)
    return export_html(
        lambda vis: draw_sweep_view(vis, cases, trajectory_for, style, arm, region_map=region_map), server_config
    )


def sweep_html(
    cases: Sequence[SweepCase],
    trajectory_for: TrajectorySource,
    html_path: str | Path,
    *,
    arm: PlanarArm | None = None,
    style: ViewStyle | None = None,
    region_map: RegionMap | None = None,
) -> RenderedView:
    """Write the sweep view as one self-contained HTML file (opens offline).

    Args:
        cases: The sweep's cases (results, or their JSON form: keys :data:`CASE_KEYS`).
        trajectory_for: ``f(L_m, W_m)`` returning an object with ``.obstacle``, ``.path``
            and ``.trajectory`` (e.g. ``pipeline.online.generator.generate`` bound to
            coefficients), or a ``Coefficients`` object (then ``generate`` is used).
        html_path: Output file; its directory is created.
        arm: The arm; default the project's URDF.
        style: Look of the scene; default lit, camera framed for a 2:1 window.
        region_map: The range certificate to draw under the cases (optional).
    """
    html, view = sweep_page(cases, trajectory_for, arm=arm, style=style, region_map=region_map)
    write_html(html_path, html)
    return view


def show_sweep(
    cases: Sequence[SweepCase],
    trajectory_for: TrajectorySource,
    *,
    arm: PlanarArm | None = None,
    style: ViewStyle | None = None,
    hold_s: float | None = None,
    out: TextIO | None = None,
    region_map: RegionMap | None = None,
) -> RenderedView:
    """Serve the sweep view live on a loopback Meshcat server, print its URL, and wait
    (``hold_s`` seconds, or until Ctrl-C / SIGTERM if None); the server is then stopped.

    Arguments as :func:`sweep_html`.
    """
    style = style if style is not None else ViewStyle(aspect=2.0)
    with MeshcatServer() as server:
        view = draw_sweep_view(server.visualizer(), cases, trajectory_for, style, arm, region_map=region_map)
        serve_until_interrupted(server, hold_s, out)
    return view


def screenshot_sweep(
    cases: Sequence[SweepCase],
    trajectory_for: TrajectorySource,
    png_path: str | Path,
    *,
    arm: PlanarArm | None = None,
    browser: BrowserConfig | None = None,
    style: ViewStyle | None = None,
    region_map: RegionMap | None = None,
) -> RenderedView:
    """Screenshot of the sweep page in headless Chromium, after the animations played."""
    browser = browser if browser is not None else BrowserConfig(width_px=1400, height_px=600)
    regenerate = _regenerator(trajectory_for)
    generated: dict[tuple[float, float], GeneratedLike] = {}
    for pick in worst_cases(cases):
        try:
            generated[(pick.L_m, pick.W_m)] = regenerate(pick.L_m, pick.W_m)
        except PipelineError:
            continue  # draw_sweep_view labels it

    def cached(length_m: float, width_m: float) -> GeneratedLike:
        found = generated.get((length_m, width_m))
        return found if found is not None else regenerate(length_m, width_m)

    longest = max((g.trajectory.duration_s for g in generated.values()), default=0.0)
    return screenshot_page(
        lambda vis, s: draw_sweep_view(vis, cases, cached, s, arm, region_map=region_map),
        png_path,
        browser,
        style or ViewStyle(),
        longest,
    )
