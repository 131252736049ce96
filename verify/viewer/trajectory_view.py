"""One trajectory in Meshcat: live on a loopback server, as a self-contained HTML page, or
as a screenshot of that page in headless Chromium.

The three share :func:`draw_trajectory_view`: the page is Meshcat's own static export of
the live scene (its viewer script inlined, so it opens offline), and the screenshot is that
page rendered by a browser.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Protocol, TextIO

from pipeline.model.arm import PlanarArm, load_planar_arm
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.motion.path import QuarticPath, desired_path
from pipeline.motion.trajectory import JointTrajectory

from ._meshcat import meshcat
from .browser import BrowserConfig, screenshot_html
from .drawing import (
    DrawnCase,
    TopDownCamera,
    TrajectoryCase,
    ViewStyle,
    draw_case,
    new_animation,
    send_animation,
    setup_view,
)
from .server import MeshcatServer, ServerConfig, serve_until_interrupted

#: Table 2, Test 1 of the paper (L = 0.30 m, W = 0.12 m): rad, rad/s.
PAPER_TEST1_PARAMETERS: dict[str, float] = {
    "A1": -0.816,
    "w1": 0.953,
    "phi1": 0.378,
    "gamma1": 1.068,
    "A2": 1.633,
    "w2": 0.768,
    "phi2": 0.131,
    "gamma2": 0.445,
}
#: (L, W) of Table 2, Test 1 [m].
PAPER_TEST1_SIZE_M: tuple[float, float] = (0.30, 0.12)


class GeneratedLike(Protocol):
    """What :func:`case_from_generated` needs of ``pipeline.online.generator.GeneratedTrajectory``."""

    obstacle: Obstacle
    path: QuarticPath
    trajectory: JointTrajectory


@dataclass(frozen=True, eq=False)
class RenderedView:
    """What was drawn and how the camera frames it.

    Attributes:
        camera: The top-down camera (maps plane points to screenshot pixels).
        cases: Each drawn trajectory case.
    """

    camera: TopDownCamera
    cases: tuple[DrawnCase, ...]


def paper_test1_case(arm: PlanarArm | None = None, scene: Scene | None = None) -> TrajectoryCase:
    """Table 2, Test 1 of the paper: the obstacle L = 0.30 m, W = 0.12 m and its published
    trajectory, with T the duration of the desired path at the scene's speed."""
    arm = arm if arm is not None else load_planar_arm()
    scene = scene if scene is not None else Scene()
    obstacle = Obstacle.in_scene(*PAPER_TEST1_SIZE_M, scene)
    path = desired_path(obstacle, scene)
    trajectory = JointTrajectory.from_mapping(PAPER_TEST1_PARAMETERS, path.duration_s)
    return TrajectoryCase(arm, obstacle, path, trajectory, title="")


def case_from_generated(generated: GeneratedLike, arm: PlanarArm, title: str = "") -> TrajectoryCase:
    """A case from the generator's output (anything with .obstacle, .path, .trajectory)."""
    return TrajectoryCase(arm, generated.obstacle, generated.path, generated.trajectory, title)


def draw_trajectory_view(vis: meshcat.Visualizer, case: TrajectoryCase, style: ViewStyle) -> RenderedView:
    """Draw one case with its animation and a top-down camera framed on it."""
    animation = new_animation(style)
    drawn = draw_case(vis, case, style, animation)
    camera = TopDownCamera.fit(drawn.bounds_m, style.aspect, style.margin_m)
    setup_view(vis, style, camera)
    send_animation(vis, animation, style)
    return RenderedView(camera, (drawn,))


def export_html(
    draw: Callable[[meshcat.Visualizer], RenderedView], server_config: ServerConfig | None = None
) -> tuple[str, RenderedView]:
    """Run ``draw`` on a fresh loopback server and return Meshcat's static HTML of the scene.

    The server is stopped before returning.
    """
    with MeshcatServer(server_config) as server:
        vis = server.visualizer()
        view = draw(vis)
        html = vis.static_html()
    return html, view


def trajectory_html(
    case: TrajectoryCase, style: ViewStyle | None = None, server_config: ServerConfig | None = None
) -> tuple[str, RenderedView]:
    """The self-contained HTML page of one case (viewer script inlined) and what it shows."""
    style = style if style is not None else ViewStyle()
    return export_html(lambda vis: draw_trajectory_view(vis, case, style), server_config)


def write_html(path: str | Path, html: str) -> Path:
    """Write a page (UTF-8), creating the parent directory."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(html, encoding="utf-8")
    return path


def screenshot_page(
    draw: Callable[[meshcat.Visualizer, ViewStyle], RenderedView],
    png_path: str | Path,
    browser: BrowserConfig | None = None,
    style: ViewStyle | None = None,
    duration_s: float = 0.0,
) -> RenderedView:
    """Export a scene to HTML and screenshot it in headless Chromium.

    Args:
        draw: Draws the scene for a style.
        png_path: Where the PNG goes.
        browser: Browser settings; the virtual-time budget is raised to outlast the
            animation (``duration_s`` [s] plus 2 s).
        style: Defaults to :meth:`ViewStyle.for_pixels`; its aspect is set to the image's.
        duration_s: Length of the page's animation [s].
    """
    browser = browser if browser is not None else BrowserConfig()
    budget = max(browser.virtual_time_budget_ms, int(duration_s * 1000) + 2000)
    browser = replace(browser, virtual_time_budget_ms=budget)
    style = replace(style if style is not None else ViewStyle.for_pixels(), aspect=browser.aspect)
    html, view = export_html(lambda vis: draw(vis, style))
    with tempfile.TemporaryDirectory(prefix="viewer-page-") as folder:
        page = write_html(Path(folder) / "view.html", html)
        screenshot_html(page, png_path, browser)
    return view


def screenshot_trajectory(
    case: TrajectoryCase,
    png_path: str | Path,
    browser: BrowserConfig | None = None,
    style: ViewStyle | None = None,
) -> RenderedView:
    """Screenshot of one case's page after its animation has played (arm at t = T)."""
    return screenshot_page(
        lambda vis, s: draw_trajectory_view(vis, case, s), png_path, browser, style, case.trajectory.duration_s
    )


def show_trajectory(
    case: TrajectoryCase,
    style: ViewStyle | None = None,
    hold_s: float | None = None,
    out: TextIO | None = None,
    server_config: ServerConfig | None = None,
) -> RenderedView:
    """Serve one case live on a loopback Meshcat server, print its URL, and wait.

    Returns after ``hold_s`` seconds, or on Ctrl-C / SIGTERM if ``hold_s`` is None; the
    server is stopped either way.
    """
    style = style if style is not None else ViewStyle()
    with MeshcatServer(server_config) as server:
        view = draw_trajectory_view(server.visualizer(), case, style)
        serve_until_interrupted(server, hold_s, out)
    return view
