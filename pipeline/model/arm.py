"""The arm: a URDF loaded into Pinocchio and checked to be a planar two-link chain.

Link lengths, link radii and joint limits are read from the model, never hard-coded.
The collision cylinders of the two links are replaced by Coal capsules of the same
radius and length (urdfdom does not parse ``<capsule>``), so that each link is a
segment with a radius: the geometry the fast clearance route reproduces exactly.
"""

from __future__ import annotations

import os
import re
import sys
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import TypeVar

import coal
import numpy as np
import pinocchio as pin

from pipeline.exceptions import RobotModelError
from pipeline.model.kinematics import forward_kinematics, reach_annulus_m

#: The paper's arm, shipped inside the package (``pipeline/data``; ``urdf/`` of a clone links to it).
DEFAULT_URDF = Path(str(resources.files("pipeline") / "data" / "planar_2link.urdf"))
#: File name of another arm's URDF, copied beside the coefficients by the build (the arm travels with them).
ARM_FILE_NAME = "arm.urdf"

_TOL = 1e-9

_Derived = TypeVar("_Derived")


@dataclass(frozen=True, eq=False)
class PlanarArm:
    """A planar two-revolute-joint arm loaded from a URDF.

    Attributes:
        urdf_path: The URDF the arm was loaded from.
        model: Pinocchio kinematic model (nq = 2).
        collision_model: Collision geometry; link cylinders replaced by capsules.
        visual_model: Visual geometry as in the URDF.
        ee_frame_id: Frame id of the end effector (tip of link 2).
        link_lengths_m: (l1, l2) [m], joint-to-joint and joint-to-tip distances in the plane.
        link_radii_m: Capsule radius of each link [m] (NaN if a link is not a cylinder).
        link_geometry_ids: Collision-geometry indices attached to each link.
        capsule_links: True if each link is one capsule from its joint to the next joint
            (or the tip) in the plane: the fast analytic clearance route applies.
        position_limits_rad: ((lo1, hi1), (lo2, hi2)) [rad].
        velocity_limits_rad_s: (v1, v2) [rad/s].
        axis: Unit joint axis in the base frame (both joints share it).
        origin_m: Position of joint 1 in the base frame [m].
        plane_x, plane_y: Orthonormal basis of the motion plane; plane_x is the direction
            of link 1 at q = 0 and plane_y = axis x plane_x.
        elbow_offset_rad: Angle of link 2 relative to link 1 at q = 0 [rad].
    """

    urdf_path: Path
    model: pin.Model
    collision_model: pin.GeometryModel
    visual_model: pin.GeometryModel
    ee_frame_id: int
    link_lengths_m: tuple[float, float]
    link_radii_m: tuple[float, float]
    link_geometry_ids: tuple[tuple[int, ...], tuple[int, ...]]
    capsule_links: bool
    position_limits_rad: tuple[tuple[float, float], tuple[float, float]]
    velocity_limits_rad_s: tuple[float, float]
    axis: np.ndarray
    origin_m: np.ndarray
    plane_x: np.ndarray
    plane_y: np.ndarray
    elbow_offset_rad: float
    _derived: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def derived(self, build: Callable[[PlanarArm], _Derived]) -> _Derived:
        """``build(self)``, computed on the first call and kept by this arm: what later layers derive
        from an arm once (its Coal shapes, its links' reach, its dynamics), owned by the arm that
        they describe rather than by a module-level cache. ``build`` is the key: pass the same
        function (or class) each time. Not pickled (:meth:`__getstate__`)."""
        value = self._derived.get(build)
        if value is None:
            value = self._derived[build] = build(self)
        return value

    def __getstate__(self) -> dict:
        """Pickled without what :meth:`derived` kept (a worker derives its own)."""
        return {**self.__dict__, "_derived": {}}

    @property
    def reach_m(self) -> tuple[float, float]:
        """Radii of the reachable annulus around joint 1 [m]: (|l1 - l2|, l1 + l2)."""
        return reach_annulus_m(self.link_lengths_m)

    @property
    def is_horizontal_xy(self) -> bool:
        """True if the arm turns about +z in the base frame's z = 0 plane with plane_x = x (the scene frame)."""
        return bool(
            np.allclose(self.axis, [0, 0, 1], atol=1e-9)
            and np.allclose(self.plane_x, [1, 0, 0], atol=1e-9)
            and np.allclose(self.origin_m, 0.0, atol=1e-9)
            and abs(self.elbow_offset_rad) < 1e-9
        )

    def end_effector_position(self, q: np.ndarray) -> np.ndarray:
        """End-effector position [m] in the base frame for joint angles ``q`` [rad], via Pinocchio."""
        data = self.model.createData()
        pin.framesForwardKinematics(self.model, data, np.asarray(q, dtype=float))
        return data.oMf[self.ee_frame_id].translation.copy()

    def end_effector_positions(self, q: np.ndarray) -> np.ndarray:
        """End-effector positions [m] in the base frame, shape (m, 3), for joint angles ``q`` (m, 2)
        [rad], via Pinocchio (one ``Data`` for all of them)."""
        data = self.model.createData()
        out = []
        for row in np.asarray(q, dtype=float).reshape(-1, self.model.nq):
            pin.framesForwardKinematics(self.model, data, row)
            out.append(data.oMf[self.ee_frame_id].translation.copy())
        return np.array(out).reshape(-1, 3)

    def end_effector_planar(self, q: np.ndarray) -> np.ndarray:
        """End-effector (x, y) [m] in the motion plane by the paper's Eq. 2 (closed form)."""
        q = np.asarray(q, dtype=float)
        return forward_kinematics(q + np.array([0.0, self.elbow_offset_rad]), self.link_lengths_m)

    def to_plane(self, points_m: np.ndarray) -> np.ndarray:
        """Coordinates (x, y) [m] in the motion plane of base-frame points [m]."""
        rel = np.asarray(points_m, dtype=float) - self.origin_m
        return np.stack([rel @ self.plane_x, rel @ self.plane_y], -1)


def _revolute_axis(joint: pin.JointModel) -> np.ndarray:
    name = joint.shortname()
    axes = {"JointModelRX": [1, 0, 0], "JointModelRY": [0, 1, 0], "JointModelRZ": [0, 0, 1]}
    if name in axes:
        return np.array(axes[name], dtype=float)
    if name == "JointModelRevoluteUnaligned":
        return np.asarray(joint.extract().axis, dtype=float).copy()
    raise RobotModelError(f"joint {joint.id} is a {name}, expected a revolute joint")


def _in_plane(vector: np.ndarray, axis: np.ndarray) -> np.ndarray:
    return vector - axis * float(vector @ axis)


def _capsule_substitute(
    model: pin.Model, collision_model: pin.GeometryModel, tips_m: list[np.ndarray]
) -> tuple[tuple[float, float], bool]:
    """Replace each link's cylinder by a Coal capsule; return (radii, capsule_links)."""
    radii = [float("nan"), float("nan")]
    aligned = True
    for joint_id in (1, 2):
        objects = [g for g in collision_model.geometryObjects if g.parentJoint == joint_id]
        if len(objects) != 1 or not isinstance(objects[0].geometry, (coal.Cylinder, coal.Capsule)):
            aligned = False
            continue
        geom = objects[0]
        radius = float(geom.geometry.radius)
        length = 2.0 * float(geom.geometry.halfLength)
        geom.geometry = coal.Capsule(radius, length)
        radii[joint_id - 1] = radius
        # The capsule axis (local z) must run from this joint to the next one (or the tip).
        placement = geom.placement
        half = placement.rotation[:, 2] * (length / 2.0)
        ends = sorted([placement.translation - half, placement.translation + half], key=np.linalg.norm)
        if not (np.allclose(ends[0], 0.0, atol=1e-6) and np.allclose(ends[1], tips_m[joint_id - 1], atol=1e-6)):
            aligned = False
    return (radii[0], radii[1]), aligned


@contextmanager
def _native_stderr_captured() -> Iterator[list[str]]:
    """Capture what native code (urdfdom, Pinocchio) writes on file descriptor 2 while the block
    runs: the list yielded receives its lines once the block ends, also when it raises. Python's
    ``sys.stderr`` is flushed first, and descriptor 2 is restored in every case. Output of other
    threads in that time is captured too; without a descriptor 2 to redirect, nothing is captured."""
    lines: list[str] = []
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):
        yield lines
        return
    try:
        with tempfile.TemporaryFile() as sink:
            os.dup2(sink.fileno(), 2)
            try:
                yield lines
            finally:
                os.dup2(saved, 2)
                sink.seek(0)
                lines.extend(sink.read().decode("utf-8", errors="replace").splitlines())
    finally:
        os.close(saved)


def _first_message(printed: list[str], error: BaseException) -> str:
    """The first meaningful line native code printed (its "Error:" prefix and the "at line ... in
    file.cpp" lines dropped), else the exception's own text: one line for a RobotModelError."""
    for line in printed:
        text = " ".join(line.split())
        for prefix in ("Error:", "Warning:"):
            text = text.removeprefix(prefix).strip()
        if text and not text.startswith("at line "):
            xml = re.match(r"Error=(XML_\w+) .*Line number=(\d+)", text)  # TinyXML's report
            return text if xml is None else f"not well-formed XML ({xml[1]} at line {xml[2]})"
    return " ".join(str(error).split())


def _joint_kind(joint: pin.JointModel) -> str:
    """What a Pinocchio joint is in URDF terms: "revolute", "continuous", "prismatic", or the
    Pinocchio joint type for anything else (a floating or planar joint)."""
    name = joint.shortname()
    if name.startswith(("JointModelRUB", "JointModelRevoluteUnbounded")):
        return "continuous"
    if name in ("JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned"):
        return "revolute"
    if name.startswith(("JointModelP", "JointModelPrismatic")) and not name.startswith("JointModelPlanar"):
        return "prismatic"
    return name


def _two_joint_model(path: Path) -> pin.Model:
    """The URDF's kinematic model, checked to have exactly two joints, both revolute (with
    limits: urdfdom refuses a revolute joint without them). What urdfdom prints on a file it
    cannot parse is captured and its first line put in the error.

    Raises:
        RobotModelError: the file is not a URDF, or its joints are not two revolute ones.
    """
    try:
        with _native_stderr_captured() as printed:
            model = pin.buildModelFromUrdf(str(path))
    except (RuntimeError, ValueError) as exc:
        raise RobotModelError(f"{path}: cannot be parsed as URDF: {_first_message(printed, exc)}") from None
    for j in range(1, model.njoints):
        kind = _joint_kind(model.joints[j])
        if kind == "continuous":
            raise RobotModelError(
                f"{path}: joint {model.names[j]!r} is continuous (nq = 2 per joint in Pinocchio); "
                "the arm needs 2 revolute joints with limits"
            )
        if kind != "revolute":
            raise RobotModelError(f"{path}: joint {model.names[j]!r} is {kind}, expected a revolute joint")
    if model.njoints != 3 or model.nq != 2 or model.nv != 2:
        raise RobotModelError(
            f"{path}: expected exactly 2 actuated joints (nq = 2), found nq = {model.nq} in {model.njoints - 1} joints"
        )
    return model


def load_planar_arm(urdf_path: str | Path | None = None, ee_frame: str | None = None) -> PlanarArm:
    """Load a URDF and check that it is a planar two-revolute-joint chain.

    Args:
        urdf_path: URDF file; default :data:`DEFAULT_URDF` (the paper's arm).
        ee_frame: Name of the end-effector frame; default ``"end_effector"`` if present,
            else the frame on joint 2 farthest from it.

    Raises:
        RobotModelError: the file is missing or unparsable, or the model is not two
            revolute joints in series with parallel axes, or a link has no length.
    """
    path = Path(urdf_path) if urdf_path is not None else DEFAULT_URDF
    if not path.is_file():
        raise RobotModelError(f"URDF not found: {path}")
    model = _two_joint_model(path)
    if model.parents[2] != 1:
        raise RobotModelError(f"{path}: joint 2 must be the child of joint 1 (a serial chain)")
    data = model.createData()
    q0 = np.zeros(2)
    pin.forwardKinematics(model, data, q0)
    axes = [data.oMi[j].rotation @ _revolute_axis(model.joints[j]) for j in (1, 2)]
    if abs(abs(float(axes[0] @ axes[1])) - 1.0) > 1e-9:
        raise RobotModelError(f"{path}: joint axes {axes[0]} and {axes[1]} are not parallel: not planar")
    axis = axes[0] / np.linalg.norm(axes[0])
    if float(axes[1] @ axis) < 0:
        raise RobotModelError(f"{path}: joint axes point in opposite directions; expected the same sense")

    try:  # Geometry only once the kinematics are known to be a planar 2R chain.
        with _native_stderr_captured() as printed:
            collision_model = pin.buildGeomFromUrdf(model, str(path), pin.GeometryType.COLLISION)
            visual_model = pin.buildGeomFromUrdf(model, str(path), pin.GeometryType.VISUAL)
    except (RuntimeError, ValueError) as exc:
        raise RobotModelError(f"{path}: geometry cannot be loaded: {_first_message(printed, exc)}") from None

    ee_id = _end_effector_frame(model, ee_frame, path)
    pin.updateFramePlacements(model, data)
    origin = data.oMi[1].translation.copy()
    elbow = data.oMi[2].translation.copy()
    tip = data.oMf[ee_id].translation.copy()
    link1 = _in_plane(elbow - origin, axis)
    link2 = _in_plane(tip - elbow, axis)
    l1, l2 = float(np.linalg.norm(link1)), float(np.linalg.norm(link2))
    if l1 < 1e-6 or l2 < 1e-6:
        raise RobotModelError(f"{path}: link lengths ({l1:.3g}, {l2:.3g}) m; both must be > 0")
    plane_x = link1 / l1
    plane_y = np.cross(axis, plane_x)
    elbow_offset = float(np.arctan2(link2 @ plane_y, link2 @ plane_x))

    # Tips of each link expressed in that link's joint frame (for the capsule check).
    tips = [data.oMi[1].actInv(elbow), data.oMi[2].actInv(tip)]
    radii, capsule_links = _capsule_substitute(model, collision_model, tips)
    geometry_ids = tuple(
        tuple(i for i, g in enumerate(collision_model.geometryObjects) if g.parentJoint == j) for j in (1, 2)
    )
    if not geometry_ids[0] or not geometry_ids[1]:
        raise RobotModelError(f"{path}: each link needs collision geometry; found {geometry_ids}")

    return PlanarArm(
        urdf_path=path,
        model=model,
        collision_model=collision_model,
        visual_model=visual_model,
        ee_frame_id=ee_id,
        link_lengths_m=(l1, l2),
        link_radii_m=radii,
        link_geometry_ids=geometry_ids,  # type: ignore[arg-type]
        capsule_links=capsule_links,
        position_limits_rad=(
            (float(model.lowerPositionLimit[0]), float(model.upperPositionLimit[0])),
            (float(model.lowerPositionLimit[1]), float(model.upperPositionLimit[1])),
        ),
        velocity_limits_rad_s=(float(model.velocityLimit[0]), float(model.velocityLimit[1])),
        axis=axis,
        origin_m=origin,
        plane_x=plane_x,
        plane_y=plane_y,
        elbow_offset_rad=elbow_offset,
    )


def _end_effector_frame(model: pin.Model, name: str | None, path: Path) -> int:
    if name is not None:
        if not model.existFrame(name):
            raise RobotModelError(f"{path}: no frame named {name!r} for the end effector")
        return model.getFrameId(name)
    if model.existFrame("end_effector"):
        return model.getFrameId("end_effector")
    candidates = [i for i, f in enumerate(model.frames) if f.parentJoint == 2]
    if not candidates:
        raise RobotModelError(f"{path}: no frame on joint 2 to serve as end effector")
    return max(candidates, key=lambda i: np.linalg.norm(model.frames[i].placement.translation))
