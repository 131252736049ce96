"""pipeline.io.rosbag_export: a TrajectoryBag written by write_bag and read back with rosbags gives
its samples, names, topics and custom data back; ROS durations split exactly; bad content, bad
topics and an existing path are refused; a failed write leaves nothing behind; without rosbags the
refusal names the extra."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_array_equal
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

from pipeline.exceptions import InvalidParameterError, MissingDependencyError, OutputExistsError
from pipeline.io import rosbag_export
from pipeline.io.rosbag_export import (
    DEFAULT_TRAJECTORY_TOPIC,
    TrajectoryBag,
    check_topic,
    custom_data_text,
    duration_parts,
    require_rosbags,
    write_bag,
)


def example(n: int = 7, **options) -> TrajectoryBag:
    """n samples of two joints, the last time not on the grid (like T')."""
    rng = np.random.default_rng(3)
    times = np.append(np.arange(n - 1) * 0.25, (n - 2) * 0.25 + 0.123456789123)
    return TrajectoryBag(
        times_s=times,
        positions_rad=rng.normal(size=(n, 2)),
        velocities_rad_s=rng.normal(size=(n, 2)),
        accelerations_rad_s2=rng.normal(size=(n, 2)),
        efforts_n_m=rng.normal(size=(n, 2)),
        joint_names=("shoulder", "elbow"),
        **options,
    )


def read_bag(path: Path) -> list[tuple[str, str, int, object]]:
    typestore = get_typestore(Stores.ROS2_HUMBLE)
    with Reader(path) as reader:
        assert reader.ros_distro == "rosbags"  # written by rosbags' writer
        return [
            (connection.topic, connection.msgtype, stamp, typestore.deserialize_cdr(raw, connection.msgtype))
            for connection, stamp, raw in reader.messages()
        ]


@pytest.mark.parametrize(("suffix", "storage"), [(".mcap", "mcap"), (".db3", "sqlite3")])
def test_written_and_read_back(tmp_path: Path, suffix: str, storage: str) -> None:
    bag = example(joint_states=True, topic="/arm/trajectory", custom_data={"timing": "paper", "n": "[1,2]"})
    out = write_bag(tmp_path / f"bag{suffix}", bag)
    assert out == tmp_path / f"bag{suffix}"
    assert sorted(p.name for p in out.iterdir()) == sorted(["metadata.yaml", f"bag{suffix}{suffix}"])
    text = (out / "metadata.yaml").read_text()
    assert f"storage_identifier: {storage}" in text and "version: 8" in text
    assert "timing: paper" in text and "n: '[1,2]'" in text
    messages = read_bag(out)
    assert [m[:3] for m in messages[:1]] == [("/arm/trajectory", "trajectory_msgs/msg/JointTrajectory", 0)]
    trajectory = messages[0][3]
    assert list(trajectory.joint_names) == ["shoulder", "elbow"]
    for field, values in (
        ("positions", bag.positions_rad),
        ("velocities", bag.velocities_rad_s),
        ("accelerations", bag.accelerations_rad_s2),
        ("effort", bag.efforts_n_m),
    ):
        assert_array_equal(np.array([getattr(p, field) for p in trajectory.points]), values)  # float64: exact
    durations = [(p.time_from_start.sec, p.time_from_start.nanosec) for p in trajectory.points]
    assert durations == [duration_parts(t) for t in bag.times_s]
    states = messages[1:]
    assert len(states) == bag.times_s.size
    assert all(m[:2] == ("/joint_states", "sensor_msgs/msg/JointState") for m in states)
    assert [m[2] for m in states] == [round(t * 1e9) for t in bag.times_s]
    assert_array_equal(np.array([m[3].position for m in states]), bag.positions_rad)
    assert_array_equal(np.array([m[3].velocity for m in states]), bag.velocities_rad_s)
    assert_array_equal(np.array([m[3].effort for m in states]), bag.efforts_n_m)


def test_without_joint_states_only_the_trajectory(tmp_path: Path) -> None:
    messages = read_bag(write_bag(tmp_path / "t.mcap", example()))
    assert [(m[0], m[2]) for m in messages] == [(DEFAULT_TRAJECTORY_TOPIC, 0)]


@pytest.mark.parametrize(
    ("t_s", "parts"),
    [(0.0, (0, 0)), (1.5, (1, 500_000_000)), (2.9999999996, (3, 0)), (1.2345678904, (1, 234_567_890)), (7.0, (7, 0))],
)
def test_duration_parts_round_to_the_nanosecond(t_s: float, parts: tuple[int, int]) -> None:
    assert duration_parts(t_s) == parts
    assert all(type(v) is int for v in duration_parts(t_s))


@pytest.mark.parametrize("topic", ["/a", "/joint_trajectory_controller/joint_trajectory", "/_x/y2"])
def test_fully_qualified_topics_pass(topic: str) -> None:
    assert check_topic(topic) == topic


@pytest.mark.parametrize("topic", ["", "a", "/", "/a/", "//a", "/a//b", "/1a", "/a b", "/a-b", "~/a", 3])
def test_other_topics_are_refused_naming_the_option(topic) -> None:
    with pytest.raises(InvalidParameterError, match="--topic"):
        check_topic(topic)


def test_custom_data_text() -> None:
    text = custom_data_text({"timing": "near-optimal", "limits": [3.0, None], "T": 1.5, "inf": float("inf")})
    assert text == {"timing": "near-optimal", "limits": "[3.0,null]", "T": "1.5", "inf": "null"}


@pytest.mark.parametrize(
    ("change", "named"),
    [
        ({"times_s": np.array([0.0, 0.5, 0.5])}, "times_s"),
        ({"times_s": np.array([-0.1, 0.5, 1.0])}, "times_s"),
        ({"times_s": np.array([0.0, np.nan, 1.0])}, "times_s"),
        ({"positions_rad": np.zeros((3, 3))}, "positions_rad"),
        ({"efforts_n_m": np.zeros((2, 2))}, "efforts_n_m"),
        ({"joint_names": ("a",)}, "positions_rad"),
        ({"joint_names": ()}, "joint_names"),
        ({"topic": "no_slash"}, "topic"),
        ({"custom_data": {"x": 1.0}}, "custom_data"),
    ],
)
def test_bad_content_is_refused(change: dict, named: str) -> None:
    fields = {
        "times_s": np.array([0.0, 0.5, 1.0]),
        "positions_rad": np.zeros((3, 2)),
        "velocities_rad_s": np.zeros((3, 2)),
        "accelerations_rad_s2": np.zeros((3, 2)),
        "efforts_n_m": np.zeros((3, 2)),
        "joint_names": ("a", "b"),
    }
    with pytest.raises(InvalidParameterError, match=named):
        TrajectoryBag(**{**fields, **change})


@pytest.mark.parametrize("existing", ["file", "empty folder"])
def test_an_existing_path_is_refused_and_kept(tmp_path: Path, existing: str) -> None:
    out = tmp_path / "t.db3"
    out.write_text("keep") if existing == "file" else out.mkdir()
    with pytest.raises(OutputExistsError, match="never replaced"):
        write_bag(out, example())
    assert (out.read_text() == "keep") if existing == "file" else (list(out.iterdir()) == [])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.db3"]


def test_an_unknown_suffix_is_refused(tmp_path: Path) -> None:
    with pytest.raises(InvalidParameterError, match=r"\.mcap, \.db3"):
        write_bag(tmp_path / "t.bag", example())
    assert list(tmp_path.iterdir()) == []


def test_a_failed_write_leaves_nothing(tmp_path: Path, monkeypatch) -> None:
    def fail(folder: Path) -> None:
        assert (folder / "metadata.yaml").is_file()  # the bag was complete in its temporary folder
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(rosbag_export, "_flush_folder", fail)
    with pytest.raises(OSError, match="No space"):
        write_bag(tmp_path / "t.mcap", example())
    assert list(tmp_path.iterdir()) == []


def test_without_rosbags_the_refusal_names_the_extra(tmp_path: Path, monkeypatch) -> None:
    for name in ("rosbags", "rosbags.rosbag2", "rosbags.typesys"):
        monkeypatch.setitem(sys.modules, name, None)
    message = "writing a ROS 2 bag needs rosbags: pip install 'twolink-obstacle[ros]'"
    with pytest.raises(MissingDependencyError) as refused:
        require_rosbags()
    assert str(refused.value) == message
    assert (refused.value.package, refused.value.extra) == ("rosbags", "ros")
    with pytest.raises(MissingDependencyError):
        write_bag(tmp_path / "t.mcap", example())
    assert list(tmp_path.iterdir()) == []
