"""The arm loader (pipeline.model.arm): kinematics against Eq. 2 and yourdfpy, geometry read from the
model, capsule substitution, the example-robot-data double pendulum, and RobotModelError cases."""

from __future__ import annotations

import os
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import pytest
import yourdfpy
from numpy.testing import assert_allclose

from pipeline.exceptions import PipelineError, RobotModelError
from pipeline.model.arm import DEFAULT_URDF, PlanarArm, load_planar_arm

# The paper's arm, written here independently of the model.
L1, L2 = 0.30, 0.35
RADIUS = 0.005


def eq2(q: np.ndarray, l1: float = L1, l2: float = L2) -> np.ndarray:
    """The paper's Eq. 2: end-effector (x, y) of a planar 2R arm, q of shape (..., 2)."""
    q = np.asarray(q, dtype=float)
    t1, t12 = q[..., 0], q[..., 0] + q[..., 1]
    return np.stack([l1 * np.cos(t1) + l2 * np.cos(t12), l1 * np.sin(t1) + l2 * np.sin(t12)], -1)


def random_configurations(n: int, seed: int) -> np.ndarray:
    """n configurations covering more than one turn of each joint."""
    return np.random.default_rng(seed).uniform(-1.5 * np.pi, 1.5 * np.pi, size=(n, 2))


# --------------------------------------------------------------------------------------------
# Small URDFs for the error cases.

_CYLINDER = (
    '<collision><origin xyz="{half} 0 0" rpy="0 1.5707963267948966 0"/>'
    '<geometry><cylinder radius="0.005" length="{length}"/></geometry></collision>'
)


def chain_urdf(joints: list[tuple[str, str]], origin_rpy: str = "0 0 0", geometry: bool = True) -> str:
    """A serial chain of links 0.30 m (then 0.35 m, 0.25 m, ...) long with the given joints.

    Args:
        joints: (type, axis "x y z") per joint, base to tip.
        origin_rpy: rpy of the first joint's origin.
        geometry: give each link a collision cylinder.
    """
    lengths = [0.30, 0.35, 0.25, 0.20]
    links = ['<link name="base_link"/>']
    parts = []
    parent = "base_link"
    offset = 0.0
    for i, (kind, axis) in enumerate(joints):
        name = f"link{i + 1}"
        body = _CYLINDER.format(half=lengths[i] / 2, length=lengths[i]) if geometry else ""
        links.append(f'<link name="{name}">{body}</link>')
        rpy = origin_rpy if i == 0 else "0 0 0"
        limit = '<limit lower="-3" upper="3" effort="10" velocity="3"/>' if kind != "fixed" else ""
        parts.append(
            f'<joint name="joint{i + 1}" type="{kind}"><parent link="{parent}"/><child link="{name}"/>'
            f'<origin xyz="{offset} 0 0" rpy="{rpy}"/><axis xyz="{axis}"/>{limit}</joint>'
        )
        parent, offset = name, lengths[i]
    links.append('<link name="end_effector"/>')
    parts.append(
        f'<joint name="ee_joint" type="fixed"><parent link="{parent}"/><child link="end_effector"/>'
        f'<origin xyz="{offset} 0 0"/></joint>'
    )
    return '<?xml version="1.0"?>\n<robot name="test_chain">\n' + "\n".join(links + parts) + "\n</robot>\n"


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# --------------------------------------------------------------------------------------------
# The shipped URDF.


def test_shipped_urdf_passes_yourdfpy_validation() -> None:
    robot = yourdfpy.URDF.load(str(DEFAULT_URDF), build_scene_graph=True)
    assert robot.validate() is True
    assert robot.actuated_joint_names == ["joint1", "joint2"]


def test_default_loader_uses_shipped_urdf(arm: PlanarArm) -> None:
    assert arm.urdf_path == DEFAULT_URDF
    assert arm.model.nq == 2 and arm.model.nv == 2
    assert arm.model.frames[arm.ee_frame_id].name == "end_effector"


def test_end_effector_matches_eq2_and_yourdfpy(arm: PlanarArm) -> None:
    robot = yourdfpy.URDF.load(str(DEFAULT_URDF))
    qs = np.vstack([random_configurations(150, seed=1), [[0.0, 0.0], [np.pi, 0.0], [0.0, np.pi]]])
    for q in qs:
        pinocchio_xyz = arm.end_effector_position(q)
        robot.update_cfg(q)
        yourdfpy_xyz = robot.get_transform(frame_to="end_effector", frame_from="base_link")[:3, 3]
        assert_allclose(pinocchio_xyz[:2], eq2(q), rtol=0, atol=1e-9)
        assert_allclose(pinocchio_xyz[2], 0.0, rtol=0, atol=1e-9)
        assert_allclose(pinocchio_xyz, yourdfpy_xyz, rtol=0, atol=1e-9)


def test_end_effector_planar_is_eq2_vectorised(arm: PlanarArm) -> None:
    qs = random_configurations(200, seed=2)
    planar = arm.end_effector_planar(qs)
    assert planar.shape == (200, 2)
    assert_allclose(planar, eq2(qs), rtol=0, atol=1e-12)
    pinocchio_xy = np.array([arm.to_plane(arm.end_effector_position(q)) for q in qs])
    assert_allclose(pinocchio_xy, planar, rtol=0, atol=1e-9)


def test_hand_computed_end_effector_positions(arm: PlanarArm) -> None:
    cases = {
        (0.0, 0.0): (0.65, 0.0),
        (np.pi / 2, 0.0): (0.0, 0.65),
        (0.0, np.pi / 2): (0.30, 0.35),
        (np.pi, np.pi): (-0.30 + 0.35, 0.0),
    }
    for q, xy in cases.items():
        assert_allclose(arm.end_effector_position(np.array(q))[:2], xy, rtol=0, atol=1e-12)


def test_geometry_read_from_model(arm: PlanarArm) -> None:
    assert_allclose(arm.link_lengths_m, (L1, L2), rtol=0, atol=1e-12)
    assert_allclose(arm.link_radii_m, (RADIUS, RADIUS), rtol=0, atol=1e-15)
    assert_allclose(arm.reach_m, (L2 - L1, L1 + L2), rtol=0, atol=1e-12)
    assert_allclose(arm.position_limits_rad, ((-3.14159, 3.14159), (-3.14159, 3.14159)), rtol=0, atol=0)
    assert_allclose(arm.velocity_limits_rad_s, (3.0, 3.0), rtol=0, atol=0)
    assert_allclose(arm.axis, [0, 0, 1], rtol=0, atol=1e-12)
    assert_allclose(arm.origin_m, [0, 0, 0], rtol=0, atol=1e-12)
    assert_allclose(arm.plane_x, [1, 0, 0], rtol=0, atol=1e-12)
    assert_allclose(arm.plane_y, [0, 1, 0], rtol=0, atol=1e-12)
    assert_allclose(arm.elbow_offset_rad, 0.0, rtol=0, atol=1e-12)
    assert arm.is_horizontal_xy


def test_collision_cylinders_replaced_by_capsules(arm: PlanarArm) -> None:
    assert arm.capsule_links
    assert [len(ids) for ids in arm.link_geometry_ids] == [1, 1]
    for link, ids in enumerate(arm.link_geometry_ids):
        geometry = arm.collision_model.geometryObjects[ids[0]]
        assert geometry.parentJoint == link + 1
        assert isinstance(geometry.geometry, coal.Capsule)
        assert_allclose(geometry.geometry.radius, RADIUS, rtol=0, atol=1e-15)
        assert_allclose(2 * geometry.geometry.halfLength, (L1, L2)[link], rtol=0, atol=1e-12)
    # The visual model keeps the URDF's cylinders.
    assert all(isinstance(g.geometry, coal.Cylinder) for g in arm.visual_model.geometryObjects)


def test_capsule_axes_run_joint_to_joint(arm: PlanarArm) -> None:
    """At random q each capsule's axis spans base -> elbow (link 1) and elbow -> tip (link 2)."""
    data = arm.model.createData()
    geometry_data = pin.GeometryData(arm.collision_model)
    for q in random_configurations(20, seed=3):
        pin.updateGeometryPlacements(arm.model, data, arm.collision_model, geometry_data, q)
        elbow = np.array([L1 * np.cos(q[0]), L1 * np.sin(q[0]), 0.0])
        tip = np.append(eq2(q), 0.0)
        for ids, (start, end) in zip(arm.link_geometry_ids, ((np.zeros(3), elbow), (elbow, tip)), strict=True):
            placement = geometry_data.oMg[ids[0]]
            half = placement.rotation[:, 2] * arm.collision_model.geometryObjects[ids[0]].geometry.halfLength
            ends = sorted([placement.translation - half, placement.translation + half], key=lambda p: p @ (end - start))
            assert_allclose(ends, [start, end], rtol=0, atol=1e-9)


# --------------------------------------------------------------------------------------------
# example-robot-data's double pendulum: another planar 2R chain (axes along x, box geometry).


def test_double_pendulum_loads_with_its_lengths(double_pendulum_urdf: Path) -> None:
    pendulum = load_planar_arm(double_pendulum_urdf)
    assert_allclose(pendulum.link_lengths_m, (0.1, 0.2), rtol=0, atol=1e-12)
    assert_allclose(np.abs(pendulum.axis), [1, 0, 0], rtol=0, atol=1e-12)
    # Box links are not capsules: no radius, no fast route.
    assert not pendulum.capsule_links
    assert np.all(np.isnan(pendulum.link_radii_m))
    assert not pendulum.is_horizontal_xy


def test_double_pendulum_planar_kinematics(double_pendulum_urdf: Path) -> None:
    pendulum = load_planar_arm(double_pendulum_urdf)
    robot = yourdfpy.URDF.load(str(double_pendulum_urdf))
    ee_link = pendulum.model.frames[pendulum.ee_frame_id].name
    # The tip of link 2: a frame 0.2 m from joint 2 (joint3 / link3 in the URDF).
    assert ee_link in ("joint3", "link3")
    for q in random_configurations(100, seed=4):
        xyz = pendulum.end_effector_position(q)
        assert_allclose(pendulum.to_plane(xyz), pendulum.end_effector_planar(q), rtol=0, atol=1e-9)
        assert_allclose(pendulum.to_plane(xyz), eq2(q, 0.1, 0.2), rtol=0, atol=1e-9)
        robot.update_cfg(q)
        assert_allclose(xyz, robot.get_transform(frame_to="link3", frame_from="base_link")[:3, 3], atol=1e-9, rtol=0)


# --------------------------------------------------------------------------------------------
# RobotModelError.


def test_chain_helper_builds_a_loadable_arm(tmp_path: Path) -> None:
    """Sanity check of the helper the error cases use: the plain version loads."""
    good = load_planar_arm(write(tmp_path, "good.urdf", chain_urdf([("revolute", "0 0 1")] * 2)))
    assert_allclose(good.link_lengths_m, (0.30, 0.35), rtol=0, atol=1e-12)
    assert good.capsule_links and good.is_horizontal_xy


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(RobotModelError, match="not found"):
        load_planar_arm(tmp_path / "does_not_exist.urdf")
    with pytest.raises(RobotModelError, match="not found"):
        load_planar_arm(tmp_path)  # a directory is not a URDF file


@pytest.mark.parametrize(
    "text",
    [
        '<robot name="x"><link name="a"></robot',
        "this is not xml at all",
        "",
        '<?xml version="1.0"?><robot name="x"><link name="a"/><joint name="j" type="revolute">',
    ],
    ids=["unclosed-tag", "not-xml", "empty", "truncated"],
)
def test_malformed_xml(tmp_path: Path, text: str) -> None:
    with pytest.raises(RobotModelError, match="cannot be parsed"):
        load_planar_arm(write(tmp_path, "bad.urdf", text))


@pytest.mark.parametrize(
    ("joints", "match"),
    [
        ([("revolute", "0 0 1")], "expected exactly 2"),
        ([("revolute", "0 0 1")] * 3, "expected exactly 2"),
        ([("revolute", "0 0 1"), ("prismatic", "0 0 1")], "expected a revolute joint"),
        ([("prismatic", "1 0 0"), ("revolute", "0 0 1")], "expected a revolute joint"),
        ([("revolute", "0 0 1"), ("revolute", "1 0 0")], "not parallel"),
        ([("revolute", "0 1 0"), ("revolute", "0 0 1")], "not parallel"),
    ],
    ids=["1-joint", "3-joint", "prismatic-2", "prismatic-1", "axes-z-x", "axes-y-z"],
)
def test_not_a_planar_2r_chain(tmp_path: Path, joints: list[tuple[str, str]], match: str) -> None:
    with pytest.raises(RobotModelError, match=match):
        load_planar_arm(write(tmp_path, "arm.urdf", chain_urdf(joints)))


def test_link_without_collision_geometry(tmp_path: Path) -> None:
    path = write(tmp_path, "bare.urdf", chain_urdf([("revolute", "0 0 1")] * 2, geometry=False))
    with pytest.raises(RobotModelError, match="collision geometry"):
        load_planar_arm(path)


def test_unknown_end_effector_frame(tmp_path: Path) -> None:
    with pytest.raises(RobotModelError, match="no frame named"):
        load_planar_arm(DEFAULT_URDF, ee_frame="no_such_frame")


def test_robot_model_error_is_a_pipeline_error() -> None:
    assert issubclass(RobotModelError, PipelineError)


# --------------------------------------------------------------------------------------------
# BUG (pipeline/robot.py, _revolute_axis): for a joint Pinocchio models as
# JointModelRevoluteUnaligned (any axis other than +x, +y, +z, including "0 0 -1"), the code
# reads ``joint.axis`` on the generic ``pin.JointModel`` wrapper, which has no such attribute
# (it must be ``joint.extract().axis``). The loader therefore raises AttributeError instead of
# RobotModelError for non-parallel or opposite unaligned axes, and cannot load a valid planar
# arm whose joints turn about -z.


@pytest.mark.parametrize(
    ("axes", "match"),
    [
        (("0 0 1", "0 0.6 0.8"), "not parallel"),
        (("0 0 1", "0 0 -1"), "opposite"),
    ],
    ids=["non-parallel-unaligned", "opposite-senses"],
)
def test_unaligned_axes_raise_robot_model_error(tmp_path: Path, axes: tuple[str, str], match: str) -> None:
    path = write(tmp_path, "arm.urdf", chain_urdf([("revolute", axes[0]), ("revolute", axes[1])]))
    with pytest.raises(RobotModelError, match=match):
        load_planar_arm(path)


def test_planar_arm_about_negative_z_loads(tmp_path: Path) -> None:
    path = write(tmp_path, "arm.urdf", chain_urdf([("revolute", "0 0 -1")] * 2))
    arm = load_planar_arm(path)
    assert_allclose(arm.axis, [0, 0, -1], rtol=0, atol=1e-12)
    assert_allclose(arm.link_lengths_m, (0.30, 0.35), rtol=0, atol=1e-12)
    q = np.array([0.4, -0.9])
    # Turning about -z mirrors Eq. 2 in the base frame.
    assert_allclose(arm.end_effector_position(q)[:2], eq2(q) * [1, -1], rtol=0, atol=1e-9)


def test_a_six_joint_arm_is_refused_for_its_joints_not_its_meshes(ur5_urdf: Path) -> None:
    """example-robot-data's UR5 (meshes not resolvable here) must be refused as 'not a 2-joint
    arm' before any geometry is loaded."""
    with pytest.raises(RobotModelError, match=r"expected exactly 2 actuated joints .* nq = 6"):
        load_planar_arm(ur5_urdf)


# --------------------------------------------------------------------------------------------
# What urdfdom prints, and joints of the wrong kind: one RobotModelError line, nothing else.


def test_a_continuous_joint_is_named_as_such(tmp_path: Path) -> None:
    """Pinocchio models a continuous joint with nq = 2 (cos, sin): the refusal names the joint and
    its kind rather than counting configuration variables."""
    text = chain_urdf([("revolute", "0 0 1")] * 2).replace(
        'name="joint1" type="revolute"', 'name="shoulder" type="continuous"'
    )
    path = write(tmp_path, "continuous.urdf", text)
    with pytest.raises(RobotModelError) as info:
        load_planar_arm(path)
    assert str(info.value) == (
        f"{path}: joint 'shoulder' is continuous (nq = 2 per joint in Pinocchio); "
        "the arm needs 2 revolute joints with limits"
    )


def test_a_prismatic_joint_is_named_with_its_file(tmp_path: Path) -> None:
    path = write(tmp_path, "arm.urdf", chain_urdf([("revolute", "0 0 1"), ("prismatic", "0 0 1")]))
    with pytest.raises(RobotModelError) as info:
        load_planar_arm(path)
    assert str(info.value) == f"{path}: joint 'joint2' is prismatic, expected a revolute joint"


def _without_limits(tmp_path: Path) -> Path:
    text = chain_urdf([("revolute", "0 0 1")] * 2).replace('<limit lower="-3" upper="3" effort="10" velocity="3"/>', "")
    return write(tmp_path, "no_limits.urdf", text)


@pytest.mark.parametrize(
    ("name", "text", "reason"),
    [
        ("no_limits.urdf", None, "Joint [joint1] is of type REVOLUTE but it does not specify limits"),
        ("text.urdf", "this is not xml at all", "not well-formed XML (XML_ERROR_PARSING_TEXT at line 1)"),
    ],
    ids=["no-limit", "not-xml"],
)
def test_urdfdom_output_is_captured_into_the_one_line_error(
    tmp_path: Path, capfd: pytest.CaptureFixture, name: str, text: str | None, reason: str
) -> None:
    """urdfdom writes its own lines on file descriptor 2: the loader captures them, puts the first
    in the error, and gives descriptor 2 back (what is written afterwards still arrives)."""
    path = _without_limits(tmp_path) if text is None else write(tmp_path, name, text)
    capfd.readouterr()
    with pytest.raises(RobotModelError) as info:
        load_planar_arm(path)
    assert str(info.value) == f"{path}: cannot be parsed as URDF: {reason}"
    os.write(2, b"after\n")
    captured = capfd.readouterr()
    assert captured.err == "after\n" and captured.out == ""


def test_a_good_urdf_loads_with_descriptor_2_restored(capfd: pytest.CaptureFixture) -> None:
    capfd.readouterr()
    load_planar_arm(DEFAULT_URDF)
    os.write(2, b"still here\n")
    assert capfd.readouterr().err == "still here\n"
