"""``python -m pipeline.generate --out FILE.mcap`` (or ``.db3``): a ROS 2 bag read back with rosbags
holds exactly one JointTrajectory on the chosen topic whose every point equals the NPZ export of
the same call (positions, velocities, accelerations, efforts, times), with the URDF's joint names;
``--joint-states`` adds one JointState per sample; an existing output and a missing rosbags are
refused in one line, exit 2, before any work."""

from __future__ import annotations

import importlib
import json
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore
from ruamel.yaml import YAML

from pipeline.model.arm import DEFAULT_URDF

generate_module = importlib.import_module("pipeline.commands.generate")

#: The call every test makes (the paper's coefficients: a fresh clone has no results/ folder).
CALL = ("--L", "0.27", "--W", "0.09", "--coefficients", "paper")
TRAJECTORY_TOPIC = "/joint_trajectory_controller/joint_trajectory"
TRAJECTORY_TYPE = "trajectory_msgs/msg/JointTrajectory"
JOINT_STATE_TYPE = "sensor_msgs/msg/JointState"
MISSING = "python -m pipeline.generate: error: writing a ROS 2 bag needs rosbags: pip install 'twolink-obstacle[ros]'"


def run(capsys, *argv: str) -> tuple[int, str, str]:
    status = generate_module.main([*CALL, *argv])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def read_bag(path: Path) -> list[tuple[str, str, int, object]]:
    """(topic, message type, bag time [ns], message) of every message of the bag, in bag order."""
    typestore = get_typestore(Stores.ROS2_HUMBLE)
    with Reader(path) as reader:
        return [
            (connection.topic, connection.msgtype, stamp, typestore.deserialize_cdr(raw, connection.msgtype))
            for connection, stamp, raw in reader.messages()
        ]


def urdf_revolute_joints(path: Path) -> list[str]:
    """Names of the URDF's revolute joints, read with the XML parser (independent of Pinocchio)."""
    return [
        j.get("name") for j in ET.parse(path).getroot().iter("joint") if j.get("type") in ("revolute", "continuous")
    ]


@pytest.fixture(scope="module")
def npz(tmp_path_factory) -> dict[str, np.ndarray]:
    """The NPZ export of the same call."""
    out = tmp_path_factory.mktemp("npz") / "t.npz"
    assert generate_module.main([*CALL, "--out", str(out)]) == 0
    with np.load(out) as data:
        return {key: data[key] for key in data.files}


def assert_points_match(message, npz: dict[str, np.ndarray]) -> None:
    points = message.points
    assert len(points) == npz["t_s"].size > 100
    for key, field in (
        ("q_rad", "positions"),
        ("dq_rad_s", "velocities"),
        ("ddq_rad_s2", "accelerations"),
        ("tau_n_m", "effort"),
    ):
        assert_allclose(np.array([getattr(p, field) for p in points]), npz[key], rtol=0.0, atol=1e-12, err_msg=field)
    times = np.array([p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec for p in points])
    assert_allclose(times, npz["t_s"], rtol=0.0, atol=1e-9)
    assert all(0 <= p.time_from_start.nanosec < 1_000_000_000 for p in points)


@pytest.mark.parametrize("suffix", [".mcap", ".db3"])
def test_the_bag_holds_one_joint_trajectory_equal_to_the_npz_export(tmp_path: Path, capsys, npz, suffix) -> None:
    out = tmp_path / f"t{suffix}"
    status, stdout, stderr = run(capsys, "--out", str(out))
    assert status == 0, stderr
    assert f"wrote {out} ({npz['t_s'].size} samples" in stdout
    assert out.is_dir() and (out / "metadata.yaml").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == [out.name]  # no temporary folder left beside it
    messages = read_bag(out)
    assert len(messages) == 1
    topic, msgtype, stamp, message = messages[0]
    assert (topic, msgtype, stamp) == (TRAJECTORY_TOPIC, TRAJECTORY_TYPE, 0)
    assert list(message.joint_names) == urdf_revolute_joints(DEFAULT_URDF) == list(npz["joint_names"])
    assert (message.header.stamp.sec, message.header.stamp.nanosec, message.header.frame_id) == (0, 0, "")
    assert_points_match(message, npz)


def test_the_bag_records_the_timing_limits_and_obstacle_as_custom_data(tmp_path: Path, capsys, npz) -> None:
    out = tmp_path / "t.mcap"
    assert run(capsys, "--out", str(out))[0] == 0
    custom = YAML(typ="safe").load((out / "metadata.yaml").read_text())["rosbag2_bagfile_information"]["custom_data"]
    assert custom["timing"] == str(npz["timing"]) == "near-optimal"
    assert float(custom["duration_s"]) == float(npz["duration_s"])
    assert float(custom["path_duration_s"]) == float(npz["path_duration_s"])
    for key in ("velocity_limits_rad_s", "acceleration_limits_rad_s2", "effort_limits_n_m", "jerk_limits_rad_s3"):
        assert json.loads(custom[key]) == npz[key].tolist(), key
    assert json.loads(custom["variables_m"]) == {"L": 0.27, "W": 0.09}


@pytest.mark.parametrize("suffix", [".mcap", ".db3"])
def test_joint_states_one_per_sample_on_their_topic(tmp_path: Path, capsys, npz, suffix) -> None:
    out = tmp_path / f"t{suffix}"
    status, _, stderr = run(capsys, "--out", str(out), "--joint-states", "--topic", "/arm/follow")
    assert status == 0, stderr
    messages = read_bag(out)
    trajectories = [m for m in messages if m[1] == TRAJECTORY_TYPE]
    states = [m for m in messages if m[1] == JOINT_STATE_TYPE]
    assert len(trajectories) == 1 and trajectories[0][0] == "/arm/follow"
    assert_points_match(trajectories[0][3], npz)
    assert len(states) == npz["t_s"].size == len(messages) - 1
    assert {m[0] for m in states} == {"/joint_states"}
    names = urdf_revolute_joints(DEFAULT_URDF)
    assert all(list(m[3].name) == names for m in states)
    stamps = np.array([m[3].header.stamp.sec + 1e-9 * m[3].header.stamp.nanosec for m in states])
    assert_allclose(stamps, npz["t_s"], rtol=0.0, atol=1e-9)
    assert [m[2] for m in states] == [round(t * 1e9) for t in npz["t_s"]]  # bag times [ns] = the sample times
    for key, field in (("q_rad", "position"), ("dq_rad_s", "velocity"), ("tau_n_m", "effort")):
        values = np.array([getattr(m[3], field) for m in states])
        assert_allclose(values, npz[key], rtol=0.0, atol=1e-12, err_msg=field)


@pytest.mark.parametrize("existing", ["file", "folder"])
@pytest.mark.parametrize("suffix", [".mcap", ".db3"])
def test_an_existing_output_is_refused_before_any_work(tmp_path: Path, capsys, suffix, existing) -> None:
    out = tmp_path / f"t{suffix}"
    if existing == "file":
        out.write_text("keep me")
    else:
        out.mkdir()
        (out / "keep.txt").write_text("keep me")
    status, stdout, stderr = run(capsys, "--out", str(out))
    assert status == 2
    assert stdout == ""  # before any work: not even the coefficients line
    assert len(stderr.splitlines()) == 1 and str(out) in stderr and "never replaced" in stderr
    kept = out if existing == "file" else out / "keep.txt"
    assert kept.read_text() == "keep me"
    assert sorted(p.name for p in tmp_path.iterdir()) == [out.name]


@pytest.mark.parametrize("suffix", [".mcap", ".db3"])
def test_a_missing_rosbags_is_refused_in_one_line_naming_the_extra(tmp_path: Path, capsys, monkeypatch, suffix):
    for name in ("rosbags", "rosbags.rosbag2", "rosbags.typesys"):
        monkeypatch.setitem(sys.modules, name, None)  # import rosbags... now raises ImportError
    out = tmp_path / f"t{suffix}"
    status, stdout, stderr = run(capsys, "--out", str(out))
    assert (status, stdout, stderr) == (2, "", MISSING + "\n")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("argv", "named"),
    [
        (["--joint-states"], "--joint-states"),
        (["--topic", "/x"], "--topic"),
        (["--joint-states", "--out", "t.npz"], "--joint-states"),
        (["--topic", "/x", "--out", "t.json"], "--topic"),
        (["--topic", "no_slash", "--out", "t.mcap"], "--topic"),
        (["--topic", "/a//b", "--out", "t.mcap"], "--topic"),
        (["--topic", "/a/1b", "--out", "t.mcap"], "--topic"),
        (["--topic", "/a/", "--out", "t.mcap"], "--topic"),
        (["--ros1", "--out", "t.db3"], "--ros1"),
        (["--out", "t.bag"], "--out"),
    ],
)
def test_bag_options_misused_are_one_line_exit_2_and_nothing_written(
    tmp_path: Path, capsys, monkeypatch, argv: list[str], named: str
) -> None:
    monkeypatch.chdir(tmp_path)
    status, stdout, stderr = run(capsys, *argv)
    assert status == 2 and stdout == ""
    assert len(stderr.splitlines()) == 1 and named in stderr
    assert list(tmp_path.iterdir()) == []


def test_help_names_the_bag_formats_and_options(capsys) -> None:
    with pytest.raises(SystemExit) as exited:
        generate_module.build_parser().parse_args(["--help"])
    assert exited.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    for needle in (".mcap", ".db3", "--topic", "--joint-states", TRAJECTORY_TOPIC, "twolink-obstacle[ros]"):
        assert needle in text, needle
