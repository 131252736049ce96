"""The Meshcat viewer's exported page, rendered in headless Chromium and checked by pixels.

The known trajectory is the paper's Table 2 Test 1 (L = 0.30 m, W = 0.12 m). The page is
exported with a fixed top-down orthographic camera, grid, axes and background hidden and
flat unlit colours; after its animation has played, the screenshot must show the obstacle,
each link (at the final pose, t = T), both paths and the constraint points in their
colours, where the geometry (computed here, independently of the viewer) puts them. Two
negative controls show that the check can fail: a page whose obstacle was moved, and the
good page rendered with WebGL disabled.

Also: the exported page is self-contained and holds the expected scene (decoded from its
Meshcat commands), and the drawn geometry (obstacle mesh, minimum clearance) is exact.
"""

from __future__ import annotations

import base64
import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest
import umsgpack
from numpy.testing import assert_allclose
from PIL import Image

from pipeline.geometry.clearance import analytic_link_clearance, link_segments
from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle
from verify.viewer.browser import BrowserConfig, find_chromium
from verify.viewer.drawing import (
    TopDownCamera,
    TrajectoryCase,
    ViewStyle,
    min_clearance,
    obstacle_mesh,
    rounded_rectangle_outline,
)
from verify.viewer.trajectory_view import paper_test1_case, screenshot_trajectory, trajectory_html

WIDTH_PX, HEIGHT_PX = 900, 600
COLOR_TOLERANCE = 40  # max |channel difference| [0..255] for "this pixel has that colour"
SEARCH_RADIUS_PX = 4  # a path/point is found if its colour is within this many pixels

needs_chromium = pytest.mark.skipif(find_chromium() is None, reason="needs headless Chromium (apt install chromium)")


def rgb(color: int) -> np.ndarray:
    return np.array([(color >> 16) & 0xFF, (color >> 8) & 0xFF, color & 0xFF])


def link_rgb(arm: PlanarArm, link: int) -> np.ndarray:
    """The URDF colour of a link's visual geometry, in 0..255."""
    geometry = next(g for g in arm.visual_model.geometryObjects if g.parentJoint == link)
    return np.asarray(geometry.meshColor[:3]) * 255


def matches(image: np.ndarray, color: np.ndarray) -> np.ndarray:
    """Boolean mask of the pixels of ``image`` (h, w, 3) within tolerance of ``color``."""
    return np.max(np.abs(image.astype(int) - np.asarray(color, dtype=int)), axis=-1) <= COLOR_TOLERANCE


def found_near(mask: np.ndarray, pixels: np.ndarray, radius: int = SEARCH_RADIUS_PX) -> np.ndarray:
    """For each (col, row) pixel, whether ``mask`` is true within ``radius`` pixels."""
    h, w = mask.shape
    out = []
    for col, row in np.rint(pixels).astype(int):
        r0, r1, c0, c1 = max(row - radius, 0), min(row + radius + 1, h), max(col - radius, 0), min(col + radius + 1, w)
        out.append(r0 < r1 and c0 < c1 and bool(mask[r0:r1, c0:c1].any()))
    return np.array(out)


def region_mask(camera: TopDownCamera, x_range: tuple[float, float], y_range: tuple[float, float]) -> np.ndarray:
    """Pixels whose centres fall in the axis-aligned world rectangle x_range x y_range [m]."""
    cols, rows = np.meshgrid(np.arange(WIDTH_PX) + 0.5, np.arange(HEIGHT_PX) + 0.5)
    x = camera.left_m + cols / WIDTH_PX * (camera.right_m - camera.left_m)
    y = camera.top_m - rows / HEIGHT_PX * (camera.top_m - camera.bottom_m)
    return (x >= x_range[0]) & (x <= x_range[1]) & (y >= y_range[0]) & (y <= y_range[1])


def check_render(image: np.ndarray, camera: TopDownCamera, case: TrajectoryCase, style: ViewStyle) -> list[str]:
    """Every way the screenshot differs from the expected scene; empty if it matches.

    Expected geometry is computed from the case, not from what the viewer says it drew;
    only the camera (the mapping world -> pixel) is taken from the viewer.
    """
    failures = []
    palette = style.palette
    obstacle = case.obstacle
    x0, x1 = obstacle.centre_x_m - obstacle.length_m / 2, obstacle.centre_x_m + obstacle.length_m / 2
    y0, y1 = obstacle.top_y_m - obstacle.width_m, obstacle.top_y_m

    # Hidden background and grid: the bottom corners of the page are white.
    corners = np.concatenate([image[-25:, :25].reshape(-1, 3), image[-25:, -25:].reshape(-1, 3)])
    if not (corners >= 235).all():
        failures.append("background: bottom corners are not white")

    # The obstacle fills its footprint (inset 1.5 cm) and nothing 1-2.5 cm outside it.
    color = rgb(palette.obstacle)
    inside = region_mask(camera, (x0 + 0.015, x1 - 0.015), (y0 + 0.015, y1 - 0.015))
    ring = region_mask(camera, (x0 - 0.025, x1 + 0.025), (y0 - 0.025, y1 + 0.025)) & ~region_mask(
        camera, (x0 - 0.01, x1 + 0.01), (y0 - 0.01, y1 + 0.01)
    )
    is_obstacle = matches(image, color)
    if is_obstacle[inside].mean() < 0.97:
        failures.append(f"obstacle: only {is_obstacle[inside].mean():.1%} of its footprint has its colour")
    if is_obstacle[ring].mean() > 0.02:
        failures.append(f"obstacle: {is_obstacle[ring].mean():.1%} of the ring around it has its colour")

    # Each link at the final pose (the animation has played): its colour along its axis.
    q_end = case.trajectory.q(case.trajectory.duration_s)
    elbow, tip = link_segments(q_end, case.arm.link_lengths_m)
    fractions = np.linspace(0.15, 0.85, 30)[:, None]
    for link, (a, b) in enumerate(((np.zeros(2), elbow), (elbow, tip)), start=1):
        pixels = camera.world_to_pixel(a + fractions * (b - a), WIDTH_PX, HEIGHT_PX)
        hit = found_near(matches(image, link_rgb(case.arm, link)), pixels, radius=1)
        if hit.mean() < 0.9:
            failures.append(f"link {link}: its colour at only {hit.mean():.0%} of its axis")

    # Both paths along their length, and the constraint points.
    _, desired = case.path.samples(60)
    times = np.linspace(0.0, case.trajectory.duration_s, 60)
    actual = case.arm.end_effector_planar(case.trajectory.q(times))
    for name, points, color in (
        ("desired path", desired, palette.desired_path),
        ("actual path", actual, palette.actual_path),
    ):
        hit = found_near(matches(image, rgb(color)), camera.world_to_pixel(points, WIDTH_PX, HEIGHT_PX))
        if hit.mean() < 0.85:
            failures.append(f"{name}: its colour near only {hit.mean():.0%} of its points")
    hit = found_near(
        matches(image, rgb(palette.constraint_points)),
        camera.world_to_pixel(case.path.points_m, WIDTH_PX, HEIGHT_PX),
    )
    if not hit.all():
        failures.append(f"constraint points: missing at P{', P'.join(str(i + 1) for i in np.flatnonzero(~hit))}")
    return failures


@pytest.fixture(scope="module")
def case(arm: PlanarArm) -> TrajectoryCase:
    return paper_test1_case(arm)


@pytest.fixture(scope="module")
def style() -> ViewStyle:
    return ViewStyle.for_pixels(aspect=WIDTH_PX / HEIGHT_PX)


def render(case: TrajectoryCase, style: ViewStyle, png: Path, webgl: bool = True) -> tuple[np.ndarray, TopDownCamera]:
    """Export the page of ``case`` and screenshot it (the code path of docs/viewer.png)."""
    view = screenshot_trajectory(case, png, BrowserConfig(width_px=WIDTH_PX, height_px=HEIGHT_PX, webgl=webgl), style)
    image = np.asarray(Image.open(png).convert("RGB"))
    assert image.shape == (HEIGHT_PX, WIDTH_PX, 3)
    return image, view.camera


@pytest.fixture(scope="module")
def good_render(case, style, tmp_path_factory) -> tuple[np.ndarray, TopDownCamera]:
    return render(case, style, tmp_path_factory.mktemp("render") / "good.png")


@needs_chromium
def test_screenshot_shows_the_scene_where_the_geometry_puts_it(good_render, case, style):
    image, camera = good_render
    assert check_render(image, camera, case, style) == []


@needs_chromium
def test_check_fails_when_the_obstacle_is_moved(case, style, tmp_path):
    # The page draws the obstacle 0.10 m farther along y than the case says it is.
    moved = dataclasses.replace(case, obstacle=dataclasses.replace(case.obstacle, top_y_m=case.obstacle.top_y_m + 0.10))
    image, camera = render(moved, style, tmp_path / "moved.png")
    failures = check_render(image, camera, case, style)
    assert any(f.startswith("obstacle:") for f in failures), failures
    # Only the obstacle is wrong: the rest of the check still passes on this page.
    assert all(f.startswith("obstacle:") for f in failures), failures
    # And the moved page matches its own (moved) geometry.
    assert check_render(image, camera, moved, style) == []


@needs_chromium
def test_an_obstacle_moved_along_x_is_drawn_at_its_place(case, style, tmp_path):
    # The obstacle of the case at centre x = 0.03 m: drawn there (its node's transform), not at x = 0.
    moved = dataclasses.replace(case, obstacle=dataclasses.replace(case.obstacle, centre_x_m=0.03))
    image, camera = render(moved, style, tmp_path / "moved_x.png")
    assert check_render(image, camera, moved, style) == []
    failures = check_render(image, camera, case, style)
    assert failures and all(f.startswith("obstacle:") for f in failures), failures


@needs_chromium
def test_check_fails_without_webgl(case, style, tmp_path):
    image, camera = render(case, style, tmp_path / "no_webgl.png", webgl=False)
    failures = check_render(image, camera, case, style)
    for item in ("obstacle:", "link 1:", "link 2:", "desired path:", "actual path:", "constraint points:"):
        assert any(f.startswith(item) for f in failures), (item, failures)


# ------------------------------------------------------------------ page structure


def page_commands(html: str) -> list[dict]:
    """The Meshcat commands inlined in an exported page, decoded."""
    blobs = re.findall(r'fetch\("data:application/octet-binary;base64,([A-Za-z0-9+/=]+)"\)', html)
    return [umsgpack.unpackb(base64.b64decode(blob)) for blob in blobs]


@pytest.fixture(scope="module")
def page(case, style) -> tuple[str, object]:
    return trajectory_html(case, style)


def test_page_is_self_contained(page):
    html, _ = page
    assert len(html) > 500_000  # the viewer script is inlined
    assert "new MeshCat.Viewer" in html
    assert re.search(r"<script[^>]+src=", html) is None
    assert re.search(r"<link[^>]+href=", html) is None


def test_page_holds_the_scene_and_the_animation(page, case):
    html, view = page
    commands = page_commands(html)
    objects = {c["path"] for c in commands if c["type"] == "set_object"}
    base = "/meshcat/trajectory"
    for name in ("obstacle", "desired_path", "actual_path", "arm/visuals/link1_0", "arm/visuals/link2_0"):
        assert f"{base}/{name}" in objects
    for point in ("P1", "P2", "P3", "P4", "P5"):
        assert f"{base}/constraint_points/{point}" in objects
    clearance = view.cases[0].clearance
    assert f"{base}/{clearance.node_name}/on_link" in objects
    assert f"{clearance.distance_m * 1e3:.2f}_mm" in clearance.node_name
    properties = {(c["path"], c["property"]): c["value"] for c in commands if c["type"] == "set_property"}
    assert properties[("/Grid", "visible")] is False
    assert properties[("/Background", "visible")] is False
    cameras = [c for c in commands if c["type"] == "set_object" and c["path"] == "/Cameras/default/rotated"]
    assert cameras[0]["object"]["object"]["type"] == "OrthographicCamera"
    animations = [c for c in commands if c["type"] == "set_animation"]
    assert len(animations) == 1
    tracks = {a["path"]: a["clip"] for a in animations[0]["animations"]}
    assert set(tracks) == {f"{base}/arm/visuals/link1_0", f"{base}/arm/visuals/link2_0"}
    clip = tracks[f"{base}/arm/visuals/link2_0"]
    keys = next(t["keys"] for t in clip["tracks"] if t["name"] == ".position")
    assert keys[-1]["time"] / clip["fps"] == pytest.approx(case.trajectory.duration_s, abs=1.0 / clip["fps"])
    # Link 2's cylinder is centred on the link: its last key is mid-link at t = T.
    elbow, tip = link_segments(case.trajectory.q(case.trajectory.duration_s), case.arm.link_lengths_m)
    assert_allclose(keys[-1]["value"], [*((elbow + tip) / 2), 0.0], atol=1e-6)


# ------------------------------------------------------------------ exact geometry


def test_obstacle_mesh_has_the_true_size_and_place(case):
    obstacle = case.obstacle
    vertices = obstacle_mesh(obstacle).vertices.astype(float)
    assert_allclose(
        vertices.min(axis=0), [-obstacle.length_m / 2, obstacle.top_y_m - obstacle.width_m, -0.5], atol=1e-6
    )
    assert_allclose(vertices.max(axis=0), [obstacle.length_m / 2, obstacle.top_y_m, 0.5], atol=1e-6)
    # The outline lies on the rounded boundary: at the corner radius from the core rectangle.
    outline = rounded_rectangle_outline(obstacle) - obstacle.center_m[:2]
    excess = np.maximum(np.abs(outline) - obstacle.core_half_extents_m[:2], 0.0)
    assert_allclose(np.linalg.norm(excess, axis=1), obstacle.corner_radius_m, atol=1e-12)


def test_moved_obstacle_is_a_different_obstacle(case):
    moved = dataclasses.replace(case.obstacle, top_y_m=case.obstacle.top_y_m + 0.10)
    assert isinstance(moved, Obstacle)
    assert_allclose(moved.center_m - case.obstacle.center_m, [0.0, 0.10, 0.0], atol=1e-12)


def test_min_clearance_is_the_exact_minimum_with_its_nearest_points(case):
    times = np.linspace(0.0, case.trajectory.duration_s, 400)
    found = min_clearance(case, times)
    analytic = analytic_link_clearance(case.trajectory.q(times), case.arm, case.obstacle)
    assert found.distance_m == pytest.approx(analytic.min(), abs=1e-6)
    row, link = np.unravel_index(np.argmin(analytic), analytic.shape)
    assert (found.time_s, found.link) == (pytest.approx(times[row]), link + 1)
    gap = np.linalg.norm(found.point_on_link_m - found.point_on_obstacle_m)
    assert gap == pytest.approx(found.distance_m, abs=1e-6)


# ------------------------------------------------------------------ the sweep view


def sweep_case(L, W, clearance, certified, start, end, passed=True) -> dict:
    return {
        "L": L,
        "W": W,
        "clearance_m": clearance,
        "certified_clearance_m": certified,
        "endpoint_error_start_m": start,
        "endpoint_error_end_m": end,
        "passed": passed,
    }


SWEEP = [
    sweep_case(0.20, 0.08, 0.020, 0.019, 1e-4, 2e-4),
    sweep_case(0.25, 0.10, 0.006, 0.004, 3e-4, 1e-4, passed=False),  # lowest certified clearance
    sweep_case(0.30, 0.12, 0.015, 0.014, 9e-4, 2e-4),  # largest endpoint error
    sweep_case(0.22, 0.11, None, None, None, None, passed=False),  # generation failed
]


def test_worst_cases_are_the_lowest_certified_clearance_and_the_largest_endpoint_error():
    from verify.viewer.sweep_view import worst_cases

    picks = worst_cases(SWEEP)
    assert [(p.tag, p.L_m, p.W_m) for p in picks] == [("A", 0.25, 0.10), ("B", 0.30, 0.12)]
    assert "4.00 mm" in picks[0].reason and "0.90 mm" in picks[1].reason
    same = [sweep_case(0.25, 0.10, 0.006, 0.004, 3e-3, 0.0), *SWEEP[2:]]
    assert [p.tag for p in worst_cases(same)] == ["A+B"]


@pytest.mark.parametrize(
    "cases",
    [[], [{"L": 0.3}], [sweep_case(-0.3, 0.1, 0.01, 0.01, 0.0, 0.0)], [sweep_case(0.3, float("nan"), 0, 0, 0, 0)]],
)
def test_bad_sweep_cases_are_refused(cases):
    from pipeline.exceptions import InvalidParameterError
    from verify.viewer.sweep_view import check_cases

    with pytest.raises(InvalidParameterError):
        check_cases(cases)


def test_clearance_colours_run_from_red_to_green():
    from verify.viewer.sweep_view import clearance_color

    assert clearance_color(-0.001, 0.02) == clearance_color(0.0, 0.02) == 0xD73027
    assert clearance_color(0.02, 0.02) == clearance_color(0.05, 0.02) == 0x1A9850
    assert clearance_color(0.01, 0.02) == 0xFEE08B
    assert clearance_color(float("nan"), 0.02) == 0x969696


def test_sweep_page_maps_every_case_and_animates_the_worst_ones(arm):
    from pipeline import load_coefficients
    from pipeline.exceptions import UnreachableObstacleError
    from verify.viewer.sweep_view import sweep_page

    def regenerate_or_fail(length_m, width_m):
        if length_m == 0.30:
            raise UnreachableObstacleError("P1", 0.7, (0.05, 0.65))
        from pipeline.online.generator import generate

        return generate(load_coefficients("paper"), length_m, width_m)

    html, view = sweep_page(SWEEP, regenerate_or_fail, arm=arm, style=ViewStyle.for_pixels(aspect=2.0))
    commands = page_commands(html)
    objects = {c["path"] for c in commands if c["type"] == "set_object"}
    dots = [p for p in objects if p.startswith("/meshcat/sweep_map/cases/") and p.endswith("/dot")]
    crosses = [p for p in objects if p.startswith("/meshcat/sweep_map/cases/") and p.endswith("/failed/a")]
    assert len(dots) == len(SWEEP) and len(crosses) == 2
    # A regenerated and animated; B could not be regenerated and is labelled instead.
    assert "/meshcat/worst_A/arm/visuals/link2_0" in objects
    assert any(p.startswith("/meshcat/worst_B/line") for p in objects)
    assert not any(p.startswith("/meshcat/worst_B/arm") for p in objects)
    assert [d.node for d in view.cases] == ["worst_A"]
    (animation,) = [c for c in commands if c["type"] == "set_animation"]
    assert {a["path"] for a in animation["animations"]} == {
        "/meshcat/worst_A/arm/visuals/link1_0",
        "/meshcat/worst_A/arm/visuals/link2_0",
    }
    # The worst case sits beside the map, inside the camera's view.
    x0, x1, y0, y1 = view.cases[0].bounds_m
    camera = view.camera
    assert x0 > 0.6 and camera.left_m <= x0 and x1 <= camera.right_m and camera.bottom_m <= y0 and y1 <= camera.top_m


def test_coefficients_regenerate_the_worst_cases_with_the_generator():
    from pipeline import load_coefficients
    from pipeline.online.generator import generate
    from verify.viewer.sweep_view import _regenerator

    coefficients = load_coefficients("paper")
    regenerated = _regenerator(coefficients)(0.36, 0.09)  # beyond the fitted range: no warning
    expected = generate(coefficients, 0.36, 0.09, out_of_range="ignore")
    assert_allclose(regenerated.trajectory.parameters, expected.trajectory.parameters, rtol=0, atol=0)
    assert regenerated.obstacle == expected.obstacle


def test_a_case_result_and_its_json_form_are_the_same_point(arm):
    from pipeline import load_coefficients
    from verify.acceptance.metrics import MeasureSettings, measure_case
    from verify.acceptance.results import failed_case
    from verify.viewer.sweep_view import SweepPoint, sweep_points, worst_cases

    measured = measure_case(load_coefficients("paper"), 0.27, 0.11, arm, MeasureSettings(time_samples=200))
    failed = failed_case(1, 0.9, 0.5, True, "UnreachableObstacleError: out of reach")
    for case in (measured, failed):
        point = SweepPoint.from_case(case)
        json_point = SweepPoint.from_json(case.to_json())
        assert point.L_m == json_point.L_m and point.passed == json_point.passed
        np.testing.assert_array_equal(
            [point.clearance_m, point.certified_clearance_m, point.endpoint_error_m],
            [json_point.clearance_m, json_point.certified_clearance_m, json_point.endpoint_error_m],
        )
    assert worst_cases([measured, failed]) == worst_cases([measured.to_json(), failed.to_json()])
    assert sweep_points(sweep_points([measured])) == sweep_points([measured])


# ------------------------------------------------------------------ the region map in the sweep view


@pytest.fixture
def small_region_map(quadrant_map):
    return quadrant_map([0.012, 0.020, 0.008, 0.009, 0.011, 0.003, 0.015], [0, 0, 1, 1, 0, 2, 0])


def test_region_map_mesh_puts_each_case_inside_its_own_leaf(small_region_map):
    from verify.acceptance.map_leaves import leaf_drawing
    from verify.viewer.sweep_view import MapLayout, _placement, region_map_mesh, sweep_points

    region_map = small_region_map
    placement = _placement(sweep_points(SWEEP), MapLayout(), region_map)
    mesh = region_map_mesh(region_map, placement)
    n = region_map.size
    assert mesh.vertices.shape == (4 * n, 3) and mesh.faces.shape == (2 * n, 3)
    assert_allclose(mesh.color, np.repeat(leaf_drawing(region_map).rgb, 4, axis=0), atol=1e-6)  # float32
    corners = mesh.vertices.reshape(n, 4, 3)
    # The triangles cover the plotting square without overlap: their areas add up to it.
    tri = mesh.vertices[mesh.faces]
    u, v = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    areas = 0.5 * np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])
    inner = placement.size_m - 2 * placement.inset_m
    assert areas.sum() == pytest.approx(inner**2, rel=1e-6)
    rng = np.random.default_rng(5)
    for length, width in zip(rng.uniform(0.2, 0.3, 50), rng.uniform(0.08, 0.12, 50), strict=True):
        leaf = int(region_map.leaf_indices(length, width))
        x, y = placement.xy(length, width)
        box = corners[leaf]
        assert box[:, 0].min() - 1e-6 <= x <= box[:, 0].max() + 1e-6
        assert box[:, 1].min() - 1e-6 <= y <= box[:, 1].max() + 1e-6


def test_sweep_page_draws_the_region_map_under_the_cases(arm, small_region_map):
    from pipeline import load_coefficients
    from verify.viewer.sweep_view import sweep_page

    region_map = small_region_map
    html, _ = sweep_page(
        SWEEP, load_coefficients("paper"), arm=arm, style=ViewStyle.for_pixels(aspect=2.0), region_map=region_map
    )
    commands = page_commands(html)
    objects = {c["path"]: c["object"] for c in commands if c["type"] == "set_object"}
    leaves = objects["/meshcat/sweep_map/region_map/leaves"]
    assert leaves["materials"][0]["vertexColors"] == 2  # three.js: per-vertex colours
    attributes = leaves["geometries"][0]["data"]["attributes"]
    position = np.frombuffer(attributes["position"]["array"].data, dtype=np.float32).reshape(-1, 3)
    assert position.shape == (4 * 7, 3) and "color" in attributes
    assert np.all(position[:, 2] < 0.004)  # under the case dots' centres (4 mm up): seen from above, dots on top
    assert sum(p.startswith("/meshcat/sweep_map/region_map/worst_cell/") for p in objects) == 4
    dots = [p for p in objects if p.startswith("/meshcat/sweep_map/cases/") and p.endswith("/dot")]
    assert len(dots) == len(SWEEP)
    plain, _ = sweep_page(SWEEP, load_coefficients("paper"), arm=arm, style=ViewStyle.for_pixels(aspect=2.0))
    assert "region_map" not in {c["path"].split("/")[3] for c in page_commands(plain) if c["path"].count("/") > 3}
