"""Drawing one trajectory case into a Meshcat scene.

What is drawn, in the arm's base frame (metres; the arm moves in the z = 0 plane):

* the arm from its URDF through Pinocchio's ``MeshcatVisualizer`` (visual geometry);
* the obstacle as a triangle mesh of the rounded box at its true size (the L x W footprint
  with rounded vertical edges, extruded over the obstacle's height), in its own frame, placed
  by its node's transform at its centre (x_c, d - W/2, 0): an obstacle moved by the scene's
  centre x (``Scene.centre_x_m``) is drawn at its place, with the path around it;
* the desired path (the paper's quartic) and the actual end-effector path as tubes;
* the five constraint points P1..P5 as small spheres;
* the point of minimum link-to-obstacle clearance over the trajectory (Coal's exact
  distance on the collision geometry) as a marker, with its distance in the node name
  and in a text label;
* the trajectory as a Meshcat animation (play / pause / scrub under "Animations").

The camera is orthographic and looks straight down (+y of the world up in the image),
framed on the content, so that :meth:`TopDownCamera.world_to_pixel` maps a point of the
plane to its pixel in a screenshot. :class:`ViewStyle` can hide grid, axes and background
and switch every material to flat unlit colours (``MeshBasicMaterial``), which a pixel
test can then compare exactly.
"""

from __future__ import annotations

import math
import textwrap
from dataclasses import dataclass, field

import coal
import numpy as np
import pinocchio as pin

from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.clearance import CoalClearance
from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle
from pipeline.motion.path import QuarticPath
from pipeline.motion.trajectory import JointTrajectory
from pipeline.validation import check_positive, check_positive_int

from ._meshcat import Animation, MeshcatVisualizer, meshcat, mg, mtf

#: Names of the constraint points, in path order.
POINT_NAMES = ("P1", "P2", "P3", "P4", "P5")


def rgba_to_hex(rgba: np.ndarray) -> int:
    """0xRRGGBB of an (r, g, b[, a]) colour in [0, 1] (as Pinocchio's visualizer rounds it)."""
    r, g, b = (int(float(c) * 255) for c in rgba[:3])
    return (r << 16) | (g << 8) | b


@dataclass(frozen=True)
class Palette:
    """Colours (0xRRGGBB) of the drawn items; the links keep their URDF colours.

    Attributes:
        obstacle: The rounded box.
        desired_path: The paper's quartic path.
        actual_path: The end-effector path of the trajectory.
        constraint_points: P1..P5.
        min_clearance: Marker of the minimum clearance.
        label_backing: Panel behind text labels.
        failure: Failed sweep cases.
    """

    obstacle: int = 0xD62728
    desired_path: int = 0xDC00DC
    actual_path: int = 0xFF8C00
    constraint_points: int = 0x00BCD4
    min_clearance: int = 0x111111
    label_backing: int = 0xF4F4F4
    failure: int = 0x111111


@dataclass(frozen=True)
class ViewStyle:
    """How the scene looks.

    Attributes:
        flat_colors: Unlit ``MeshBasicMaterial`` everywhere (exact colours in a screenshot)
            instead of lit Phong materials.
        show_grid: Meshcat's ground grid.
        show_axes: Meshcat's world axes.
        show_background: Meshcat's gradient background; hidden, the page (white) shows.
        show_labels: Text labels (minimum clearance, titles).
        palette: Colours.
        desired_path_radius_m: Tube radius of the desired path [m].
        actual_path_radius_m: Tube radius of the actual path [m]; drawn above the desired
            one, so a thinner tube leaves the desired path visible on both sides.
        point_radius_m: Radius of the constraint-point spheres [m].
        samples: Points along each path and configurations checked for clearance.
        fps: Animation frames per second [1/s].
        play: Start the animation when the page loads.
        aspect: Width / height of the viewport the camera is framed for [-].
        margin_m: Empty border around the content in the camera frame [m].
        obstacle_opacity: Opacity of the obstacle [0..1]; below 1 a link that enters it
            (negative clearance) stays visible from above.
    """

    flat_colors: bool = False
    show_grid: bool = True
    show_axes: bool = True
    show_background: bool = True
    show_labels: bool = True
    palette: Palette = field(default_factory=Palette)
    desired_path_radius_m: float = 0.0035
    actual_path_radius_m: float = 0.0015
    point_radius_m: float = 0.006
    samples: int = 400
    fps: int = 30
    play: bool = True
    aspect: float = 1.5
    margin_m: float = 0.04
    obstacle_opacity: float = 0.8

    def __post_init__(self) -> None:
        for name in ("desired_path_radius_m", "actual_path_radius_m", "point_radius_m", "aspect", "margin_m"):
            check_positive(name, getattr(self, name))
        check_positive_int("samples", self.samples, minimum=16)
        check_positive_int("fps", self.fps)
        if not 0.0 < self.obstacle_opacity <= 1.0:
            raise InvalidParameterError("obstacle_opacity", self.obstacle_opacity, "a number in (0, 1]")

    @classmethod
    def for_pixels(cls, aspect: float = 1.5, **changes: object) -> ViewStyle:
        """The style of the pixel test (and of ``verify.view --flat``): flat unlit colours, an
        opaque obstacle, no grid, axes or background."""
        return cls(
            flat_colors=True,
            show_grid=False,
            show_axes=False,
            show_background=False,
            obstacle_opacity=1.0,
            aspect=aspect,
            **changes,
        )  # type: ignore[arg-type]

    def material(self, color: int, opacity: float = 1.0) -> mg.Material:
        """A material of this style."""
        kind = mg.MeshBasicMaterial if self.flat_colors else mg.MeshPhongMaterial
        return kind(color=color, opacity=opacity, transparent=opacity < 1.0)


@dataclass(frozen=True)
class TopDownCamera:
    """An orthographic camera above the origin looking down -z, world +y up in the image.

    The frustum is given in world coordinates of the z = 0 plane. Meshcat recomputes
    ``right`` from the window's aspect ratio, so the image is undistorted in any window
    and matches :meth:`world_to_pixel` exactly when width / height = :attr:`aspect`.

    Attributes:
        left_m, right_m, bottom_m, top_m: Visible x and y ranges [m].
        height_m: Height of the camera above the plane [m].
    """

    left_m: float
    right_m: float
    bottom_m: float
    top_m: float
    height_m: float = 3.0

    @classmethod
    def fit(cls, bounds_m: tuple[float, float, float, float], aspect: float, margin_m: float) -> TopDownCamera:
        """The tightest view of ``bounds_m`` = (x_min, x_max, y_min, y_max) [m] with a margin
        [m], widened along one axis to the aspect ratio (width / height)."""
        x0, x1, y0, y1 = bounds_m
        x0, x1, y0, y1 = x0 - margin_m, x1 + margin_m, y0 - margin_m, y1 + margin_m
        width, height = x1 - x0, y1 - y0
        if width / height > aspect:
            extra = width / aspect - height
            y0, y1 = y0 - extra / 2, y1 + extra / 2
        else:
            extra = height * aspect - width
            x0, x1 = x0 - extra / 2, x1 + extra / 2
        return cls(x0, x1, y0, y1)

    @property
    def aspect(self) -> float:
        """Width / height of the view [-]."""
        return (self.right_m - self.left_m) / (self.top_m - self.bottom_m)

    def world_to_pixel(self, xy_m: np.ndarray, width_px: int, height_px: int) -> np.ndarray:
        """(column, row) [px, float] of plane points (..., 2) [m] in a width x height image."""
        xy = np.asarray(xy_m, dtype=float)
        col = (xy[..., 0] - self.left_m) / (self.right_m - self.left_m) * width_px
        row = (self.top_m - xy[..., 1]) / (self.top_m - self.bottom_m) * height_px
        return np.stack([col, row], -1)

    def pixels_per_metre(self, height_px: int) -> float:
        """Scale of the image [px/m]."""
        return height_px / (self.top_m - self.bottom_m)

    def apply(self, vis: meshcat.Visualizer) -> None:
        """Make this the viewer's camera."""
        camera = mg.OrthographicCamera(
            left=self.left_m, right=self.right_m, top=self.top_m, bottom=self.bottom_m, near=0.01, far=100.0
        )
        vis["/Cameras/default/rotated"].set_object(camera)
        # The "rotated" frame maps its y axis to world z: this puts the camera above the origin.
        vis["/Cameras/default/rotated/<object>"].set_property("position", [0.0, self.height_m, 0.0])


@dataclass(frozen=True, eq=False)
class TrajectoryCase:
    """One trajectory to show.

    Attributes:
        arm: The arm.
        obstacle: The obstacle.
        path: The desired path around it.
        trajectory: The joint trajectory over [0, T].
        title: Caption drawn above the case (may be empty).
    """

    arm: PlanarArm
    obstacle: Obstacle
    path: QuarticPath
    trajectory: JointTrajectory
    title: str = ""


@dataclass(frozen=True)
class MinClearance:
    """The smallest link-to-obstacle distance over the sampled trajectory.

    Attributes:
        distance_m: Coal's distance between the link's collision geometry and the obstacle
            [m] (negative: penetration depth).
        time_s: When it occurs [s].
        link: 1 or 2.
        point_on_link_m: Nearest point on the link, (x, y, z) [m].
        point_on_obstacle_m: Nearest point on the obstacle, (x, y, z) [m].
        samples: Number of time samples the minimum is taken over (0: not recorded).
    """

    distance_m: float
    time_s: float
    link: int
    point_on_link_m: np.ndarray
    point_on_obstacle_m: np.ndarray
    samples: int = 0

    @property
    def label(self) -> str:
        """One-line description, distance in mm; says that the minimum is over samples, not certified."""
        over = f" over {self.samples} sampled times" if self.samples else ""
        return f"min clearance {self.distance_m * 1e3:.2f} mm{over} (link {self.link}, t = {self.time_s:.2f} s)"

    @property
    def node_name(self) -> str:
        """Name of the marker's node in the scene tree, with the distance in it."""
        return f"min_clearance_{self.distance_m * 1e3:.2f}_mm_link{self.link}_t{self.time_s:.2f}s"


@dataclass(frozen=True, eq=False)
class DrawnCase:
    """What :func:`draw_case` drew, in world coordinates of the plane (with the offset).

    Attributes:
        node: Meshcat path of the case's group.
        offset_m: (x, y) translation of the case's group [m].
        times_s: Sample times [s], shape (m,).
        q: Joint angles at those times [rad], shape (m, 2).
        desired_m: Desired path samples (x, y) [m], shape (m, 2).
        actual_m: End-effector positions (x, y) [m], shape (m, 2).
        elbow_m: Elbow positions (x, y) [m], shape (m, 2).
        constraint_points_m: P1..P5 (x, y) [m], shape (5, 2).
        obstacle_corners_m: Outer footprint corners (x, y) [m], shape (4, 2).
        clearance: The minimum clearance.
        bounds_m: (x_min, x_max, y_min, y_max) of everything drawn [m].
        initial_q, final_q: Pose shown before and after the animation [rad].
    """

    node: str
    offset_m: np.ndarray
    times_s: np.ndarray
    q: np.ndarray
    desired_m: np.ndarray
    actual_m: np.ndarray
    elbow_m: np.ndarray
    constraint_points_m: np.ndarray
    obstacle_corners_m: np.ndarray
    clearance: MinClearance
    bounds_m: tuple[float, float, float, float]
    initial_q: np.ndarray
    final_q: np.ndarray


# ---------------------------------------------------------------------------- meshes


def rounded_rectangle_outline(obstacle: Obstacle, segments_per_corner: int = 12) -> np.ndarray:
    """Counter-clockwise outline (x, y) [m] of the obstacle's rounded footprint, shape (n, 2).

    Exactly the section of Coal's swept-sphere box in the arm's plane: the core rectangle
    inflated by the corner radius.
    """
    check_positive_int("segments_per_corner", segments_per_corner)
    cx, cy = obstacle.center_m[:2]
    hx, hy = obstacle.core_half_extents_m[:2]
    r = obstacle.corner_radius_m
    if r == 0.0:
        return obstacle.footprint_corners_m()
    points = []
    for (sx, sy), start in zip(((1, 1), (-1, 1), (-1, -1), (1, -1)), (0.0, 0.5, 1.0, 1.5), strict=True):
        angles = np.pi * (start + np.linspace(0.0, 0.5, segments_per_corner + 1))
        points.append(np.stack([cx + sx * hx + r * np.cos(angles), cy + sy * hy + r * np.sin(angles)], -1))
    return np.concatenate(points)


def prism_mesh(outline_m: np.ndarray, z_bottom_m: float, z_top_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (k, 3) [m] and triangles (j, 3) of a convex polygon extruded along z.

    Sides and caps have their own vertices, so that normals computed by the viewer are
    flat on the caps and smooth around the sides.
    """
    outline = np.asarray(outline_m, dtype=float)
    n = len(outline)
    center = outline.mean(axis=0)
    bottom = np.column_stack([outline, np.full(n, z_bottom_m)])
    top = np.column_stack([outline, np.full(n, z_top_m)])
    vertices = np.vstack([bottom, top, bottom, [[*center, z_bottom_m]], top, [[*center, z_top_m]]])
    i = np.arange(n)
    j = (i + 1) % n
    sides = np.concatenate([np.stack([i, j, n + j], -1), np.stack([i, n + j, n + i], -1)])
    bottom_cap = np.stack([np.full(n, 3 * n), 2 * n + j, 2 * n + i], -1)
    top_cap = np.stack([np.full(n, 4 * n + 1), 3 * n + 1 + i, 3 * n + 1 + j], -1)
    return vertices, np.concatenate([sides, bottom_cap, top_cap])


def obstacle_mesh(obstacle: Obstacle, centred: bool = False) -> mg.TriangularMeshGeometry:
    """The obstacle as a triangle mesh at its true size and place.

    Its section in every horizontal plane is the rounded L x W footprint (exact at z = 0,
    where the arm moves); it spans the obstacle's height. Coal's swept-sphere box also
    rounds the top and bottom edges; those are drawn square. With ``centred`` the mesh is in
    the obstacle's own frame (origin at its centre), placed by :func:`obstacle_transform`.
    """
    half_height = obstacle.height_m / 2.0
    outline = rounded_rectangle_outline(obstacle)
    if centred:
        outline = outline - obstacle.center_m[:2]
    vertices, faces = prism_mesh(outline, -half_height, half_height)
    return mg.TriangularMeshGeometry(vertices, faces)


def obstacle_transform(obstacle: Obstacle) -> np.ndarray:
    """The 4x4 transform that places the obstacle's own frame in its case's frame: the
    translation to its centre (x_c, d - W/2, 0) [m], x_c its centre x (``Scene.centre_x_m``)."""
    return mtf.translation_matrix(obstacle.center_m)


def tube_mesh(points_m: np.ndarray, radius_m: float, sides: int = 8) -> mg.TriangularMeshGeometry:
    """A tube of circular section of radius [m] along a polyline (n, 3) [m], open ends.

    Repeated consecutive points are dropped.

    Raises:
        InvalidParameterError: fewer than two distinct points.
    """
    points = np.asarray(points_m, dtype=float)
    if points.ndim != 2 or points.shape[1] != 3:
        raise InvalidParameterError("points_m", points.shape, "a polyline of shape (n, 3)")
    if len(points) > 1:
        points = points[np.r_[True, np.linalg.norm(np.diff(points, axis=0), axis=1) > 1e-12]]
    if len(points) < 2:
        raise InvalidParameterError("points_m", len(points), "at least two distinct points")
    tangents = np.gradient(points, axis=0)
    tangents /= np.linalg.norm(tangents, axis=1, keepdims=True)
    reference = np.where(np.abs(tangents[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    normal = np.cross(tangents, reference)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    binormal = np.cross(tangents, normal)
    angles = 2 * np.pi * np.arange(sides) / sides
    ring = np.cos(angles)[None, :, None] * normal[:, None, :] + np.sin(angles)[None, :, None] * binormal[:, None, :]
    vertices = (points[:, None, :] + radius_m * ring).reshape(-1, 3)
    k = np.arange(len(points) - 1)[:, None] * sides
    s = np.arange(sides)[None, :]
    a, b = k + s, k + (s + 1) % sides
    faces = np.concatenate([np.stack([a, b, b + sides], -1), np.stack([a, b + sides, a + sides], -1)], axis=1)
    return mg.TriangularMeshGeometry(vertices, faces.reshape(-1, 3))


class PlaneGeometry(mg.Geometry):
    """three.js ``PlaneGeometry``: a width x height rectangle in its xy plane, with UVs."""

    def __init__(self, width_m: float, height_m: float) -> None:
        super().__init__()
        self.width_m = width_m
        self.height_m = height_m

    def lower(self, object_data: object) -> dict:
        return {
            "uuid": self.uuid,
            "type": "PlaneGeometry",
            "width": self.width_m,
            "height": self.height_m,
            "widthSegments": 1,
            "heightSegments": 1,
        }


def draw_label(
    vis: meshcat.Visualizer, text: str, center_m: np.ndarray, style: ViewStyle, height_m: float = 0.018
) -> None:
    """A text label (black on a light panel) facing +z, centred at ``center_m`` (x, y, z) [m],
    its letters about ``height_m`` [m] tall; "\\n" separates lines.

    Meshcat's viewer draws ``_text`` textures centred on a 256 px square canvas, shrinking
    the font until the text fits its width; the font size is chosen so that it fits (for
    an average sans-serif letter of 0.58 em), and the plane is scaled to the wanted height.
    The canvas is only 256 px wide, so longer lines are wrapped at 48 characters.
    """
    lines = [wrapped for line in text.split("\n") for wrapped in (textwrap.wrap(line, 48) or [""])]
    pitch = 1.9 * height_m
    for index, line in enumerate(lines):
        node = vis[f"line{index}"]
        font_px = min(64.0, 256.0 / (0.58 * max(len(line), 1)))
        plane_m = height_m * 256.0 / font_px
        texture = mg.GenericTexture(
            {"type": "_text", "text": line, "font_size": int(font_px), "font_face": "sans-serif"}
        )
        # Labels write no depth: a line's transparent square must not hide its neighbours.
        node["text"].set_object(
            PlaneGeometry(plane_m, plane_m),
            mg.MeshBasicMaterial(map=texture, transparent=True, color=0xFFFFFF, depthWrite=False),
        )
        node["text"].set_transform(mtf.translation_matrix([0.0, 0.0, 0.0005]))
        panel_width = min(plane_m, 0.52 * len(line) * height_m + 1.2 * height_m)
        node["panel"].set_object(
            PlaneGeometry(panel_width, pitch),
            mg.MeshBasicMaterial(color=style.palette.label_backing, opacity=0.85, transparent=True, depthWrite=False),
        )
        node["panel"].set_transform(mtf.translation_matrix([0.0, 0.3 * height_m, 0.0]))
        node.set_transform(mtf.translation_matrix([0.0, ((len(lines) - 1) / 2 - index) * pitch, 0.0]))
    vis.set_transform(mtf.translation_matrix(np.asarray(center_m, dtype=float)))


def label_height_m(text: str, height_m: float = 0.018) -> float:
    """Height [m] that :func:`draw_label` takes for ``text``."""
    lines = sum(len(textwrap.wrap(line, 48) or [""]) for line in text.split("\n"))
    return 1.9 * height_m * lines


# ----------------------------------------------------------------------- computation


def min_clearance(case: TrajectoryCase, times_s: np.ndarray) -> MinClearance:
    """The minimum over ``times_s`` and both links of Coal's link-to-obstacle distance,
    with the nearest points."""
    q = case.trajectory.q(np.asarray(times_s, dtype=float))
    distances = CoalClearance(case.arm, case.obstacle).link_clearance(q)
    row, link = np.unravel_index(int(np.argmin(distances)), distances.shape)
    arm = case.arm
    data = arm.model.createData()
    geometry_data = pin.GeometryData(arm.collision_model)
    pin.updateGeometryPlacements(arm.model, data, arm.collision_model, geometry_data, q[row])
    request = coal.DistanceRequest()  # nearest points are always computed (coal >= 3)
    obstacle_shape = case.obstacle.coal_shape()
    obstacle_tf = coal.Transform3s(np.eye(3), case.obstacle.center_m)
    best: tuple[float, np.ndarray, np.ndarray] | None = None
    for geometry_id in arm.link_geometry_ids[link]:
        geometry = arm.collision_model.geometryObjects[geometry_id]
        placement = geometry_data.oMg[geometry_id]
        result = coal.DistanceResult()
        coal.distance(
            geometry.geometry,
            coal.Transform3s(placement.rotation, placement.translation),
            obstacle_shape,
            obstacle_tf,
            request,
            result,
        )
        if best is None or result.min_distance < best[0]:
            best = (result.min_distance, result.getNearestPoint1().copy(), result.getNearestPoint2().copy())
    if best is None:
        raise InvalidParameterError("arm", str(arm.urdf_path), f"collision geometry for link {int(link) + 1}")
    return MinClearance(
        distance_m=float(distances[row, link]),
        time_s=float(times_s[row]),
        link=int(link) + 1,
        point_on_link_m=best[1],
        point_on_obstacle_m=best[2],
        samples=len(times_s),
    )


def _joint_positions(arm: PlanarArm, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Elbow and end-effector positions (m, 3) [m] by Pinocchio's forward kinematics."""
    data = arm.model.createData()
    elbow, tip = np.empty((len(q), 3)), np.empty((len(q), 3))
    for k, configuration in enumerate(q):
        pin.framesForwardKinematics(arm.model, data, configuration)
        elbow[k] = data.oMi[2].translation
        tip[k] = data.oMf[arm.ee_frame_id].translation
    return elbow, tip


def case_bounds(case: TrajectoryCase, samples: int = 200) -> tuple[float, float, float, float]:
    """(x_min, x_max, y_min, y_max) [m] of obstacle, path and the arm over the trajectory."""
    times = np.linspace(0.0, case.trajectory.duration_s, samples)
    q = case.trajectory.q(times)
    elbow, tip = _joint_positions(case.arm, q)
    points = np.vstack(
        [
            case.obstacle.footprint_corners_m(),
            case.path.points_m,
            elbow[:, :2],
            tip[:, :2],
            case.arm.origin_m[None, :2],
        ]
    )
    return (
        float(points[:, 0].min()),
        float(points[:, 0].max()),
        float(points[:, 1].min()),
        float(points[:, 1].max()),
    )


# --------------------------------------------------------------------------- drawing


def setup_view(vis: meshcat.Visualizer, style: ViewStyle, camera: TopDownCamera) -> None:
    """Grid, axes, background and camera as the style says."""
    vis["/Grid"].set_property("visible", style.show_grid)
    vis["/Axes"].set_property("visible", style.show_axes)
    vis["/Background"].set_property("visible", style.show_background)
    camera.apply(vis)


def _sphere(vis: meshcat.Visualizer, center_m: np.ndarray, radius_m: float, material: mg.Material) -> None:
    vis.set_object(mg.Sphere(radius_m), material)
    vis.set_transform(mtf.translation_matrix(np.asarray(center_m, dtype=float)))


def _flat_arm_materials(viz: MeshcatVisualizer, style: ViewStyle) -> None:
    """Redraw each visual geometry with an unlit material of its URDF colour."""
    for geometry in viz.visual_model.geometryObjects:
        shape = viz.loadPrimitive(geometry)
        if shape is None:
            continue
        node = viz.viewer[viz.getViewerNodeName(geometry, pin.GeometryType.VISUAL)]
        node.set_object(shape, style.material(rgba_to_hex(geometry.meshColor)))


def draw_case(
    vis: meshcat.Visualizer,
    case: TrajectoryCase,
    style: ViewStyle,
    animation: Animation | None = None,
    node: str = "trajectory",
    offset_m: tuple[float, float] = (0.0, 0.0),
) -> DrawnCase:
    """Draw one case under ``/meshcat/<node>``, translated by ``offset_m`` (x, y) [m].

    If ``animation`` is given, the arm's motion is added to it as frames at ``style.fps``;
    the caller sends it with ``vis.set_animation`` once every case is drawn (a Meshcat
    scene holds one animation).
    """
    root = vis[node]
    offset = np.array([float(offset_m[0]), float(offset_m[1])])
    root.set_transform(mtf.translation_matrix([offset[0], offset[1], 0.0]))
    palette = style.palette
    duration = case.trajectory.duration_s
    times = np.linspace(0.0, duration, style.samples)
    q = case.trajectory.q(times)
    elbow, tip = _joint_positions(case.arm, q)
    _, desired = case.path.samples(style.samples)

    root["obstacle"].set_object(
        obstacle_mesh(case.obstacle, centred=True), style.material(palette.obstacle, opacity=style.obstacle_opacity)
    )
    root["obstacle"].set_transform(obstacle_transform(case.obstacle))
    _draw_paths(root, case, style, desired, tip)
    clearance = min_clearance(case, times)
    marker = _draw_min_clearance(root, clearance, style)
    bounds = _draw_labels(root, marker, case, clearance, style)

    viz = MeshcatVisualizer(case.arm.model, case.arm.collision_model, case.arm.visual_model)
    viz.initViewer(viewer=root)
    viz.loadViewerModel(rootNodeName="arm")
    if style.flat_colors:
        _flat_arm_materials(viz, style)
    viz.display(q[0])
    if animation is not None:
        _add_frames(viz, root, animation, case.trajectory, style.fps)
        final_q = case.trajectory.q(duration)
    else:
        final_q = q[0]

    return DrawnCase(
        node=node,
        offset_m=offset,
        times_s=times,
        q=q,
        desired_m=desired + offset,
        actual_m=tip[:, :2] + offset,
        elbow_m=elbow[:, :2] + offset,
        constraint_points_m=np.asarray(case.path.points_m) + offset,
        obstacle_corners_m=case.obstacle.footprint_corners_m() + offset,
        clearance=clearance,
        bounds_m=(bounds[0] + offset[0], bounds[1] + offset[0], bounds[2] + offset[1], bounds[3] + offset[1]),
        initial_q=q[0],
        final_q=np.asarray(final_q),
    )


def _draw_paths(
    root: meshcat.Visualizer, case: TrajectoryCase, style: ViewStyle, desired: np.ndarray, tip: np.ndarray
) -> None:
    """The desired and actual end-effector paths and the constraint points P1..P5."""
    palette = style.palette
    # Paths lie just below the arm's plane, the actual one above the desired one: seen from
    # above the arm hides them where it crosses them.
    desired_3d = np.column_stack([desired, np.full(len(desired), -0.010)])
    actual_3d = np.column_stack([tip[:, :2], np.full(len(tip), -0.008)])
    root["desired_path"].set_object(
        tube_mesh(desired_3d, style.desired_path_radius_m), style.material(palette.desired_path)
    )
    try:
        root["actual_path"].set_object(
            tube_mesh(actual_3d, style.actual_path_radius_m), style.material(palette.actual_path)
        )
    except InvalidParameterError:  # the end effector does not move: a dot
        _sphere(root["actual_path"], actual_3d[0], 2 * style.actual_path_radius_m, style.material(palette.actual_path))
    for name, point in zip(POINT_NAMES, case.path.points_m, strict=True):
        _sphere(
            root["constraint_points"][name],
            [point[0], point[1], 0.008],
            style.point_radius_m,
            style.material(palette.constraint_points),
        )


def _draw_min_clearance(root: meshcat.Visualizer, clearance: MinClearance, style: ViewStyle) -> meshcat.Visualizer:
    """The nearest points of the minimum clearance and the gap between them; returns the marker's node."""
    palette = style.palette
    marker = root[clearance.node_name]
    marker_material = style.material(palette.min_clearance)
    _sphere(marker["on_link"], clearance.point_on_link_m + [0, 0, 0.012], 0.005, marker_material)
    _sphere(marker["on_obstacle"], clearance.point_on_obstacle_m + [0, 0, 0.012], 0.003, marker_material)
    gap = np.array([clearance.point_on_link_m, clearance.point_on_obstacle_m]) + [0, 0, 0.012]
    if np.linalg.norm(gap[1] - gap[0]) > 1e-6:  # zero when the link touches the obstacle
        marker["gap"].set_object(tube_mesh(gap, 0.0012, sides=6), marker_material)
    return marker


def _draw_labels(
    root: meshcat.Visualizer,
    marker: meshcat.Visualizer,
    case: TrajectoryCase,
    clearance: MinClearance,
    style: ViewStyle,
) -> tuple[float, float, float, float]:
    """The clearance label and the title, if the style shows labels; returns the content's bounds [m]."""
    bounds = case_bounds(case)
    if style.show_labels:
        # Labels go in strips below and above the content, so they never hide it.
        center_x = (bounds[0] + bounds[1]) / 2
        label = "\u25cf " + clearance.label
        size = label_height_m(label)
        draw_label(marker["label"], label, [center_x, bounds[2] - 0.01 - size / 2, 0.02], style)
        bounds = (bounds[0], bounds[1], bounds[2] - 0.01 - size, bounds[3])
        if case.title:
            size = label_height_m(case.title)
            draw_label(root["title"], case.title, [center_x, bounds[3] + 0.01 + size / 2, 0.02], style)
            bounds = (bounds[0], bounds[1], bounds[2], bounds[3] + 0.01 + size)
    return bounds


def _add_frames(
    viz: MeshcatVisualizer, root: meshcat.Visualizer, animation: Animation, trajectory: JointTrajectory, fps: int
) -> None:
    """Key frames of the arm at ``fps`` from t = 0 to t = T (the last frame exactly at T)."""
    duration = trajectory.duration_s
    frames = math.ceil(duration * fps - 1e-9)
    viewer = viz.viewer
    try:
        for k in range(frames + 1):
            viz.viewer = animation.at_frame(root, k)
            viz.display(trajectory.q(min(k / fps, duration)))
    finally:
        viz.viewer = viewer


def new_animation(style: ViewStyle) -> Animation:
    """An empty animation at the style's frame rate."""
    return Animation(default_framerate=style.fps)


def send_animation(vis: meshcat.Visualizer, animation: Animation, style: ViewStyle) -> None:
    """Send the animation (played once on load if ``style.play``; scrub it under Animations)."""
    vis.set_animation(animation, play=style.play, repetitions=1)
