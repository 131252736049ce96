"""ROS 2 bags (rosbag2) of a sampled trajectory, written with `rosbags
<https://gitlab.com/ternaris/rosbags>`_ (``pip install 'twolink-obstacle[ros]'``).

A bag holds the whole trajectory as one ``trajectory_msgs/msg/JointTrajectory`` message (what a
``joint_trajectory_controller`` takes: every point with positions [rad], velocities [rad/s],
accelerations [rad/s^2], efforts [N m] and ``time_from_start``; header stamp zero, "start now"),
recorded at bag time 0, and optionally the sampled ``sensor_msgs/msg/JointState`` stream on
``/joint_states``, one message per sample, recorded at and stamped with the sample's time.
Messages are those of ROS 2 Humble (the same definitions in later distributions); the
metadata is rosbag2's format version 8, the oldest ``rosbags`` writes.

A rosbag2 bag is a folder (``metadata.yaml`` and one storage file named after the folder): the
suffix of the path picks the storage, ``.mcap`` (MCAP) or ``.db3`` (SQLite 3). The bag is written
into a temporary folder beside the target and renamed into place when complete, so the target is
either absent or a whole bag. An existing path is never replaced.

``rosbags`` is imported only inside the functions that need it: the rest of the project runs
without it.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import tempfile
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

import numpy as np

from pipeline.exceptions import InvalidParameterError, MissingDependencyError, OutputExistsError

__all__ = [
    "BAG_STORAGE",
    "DEFAULT_TRAJECTORY_TOPIC",
    "JOINT_STATES_TOPIC",
    "ROSBAG2_VERSION",
    "TrajectoryBag",
    "check_topic",
    "custom_data_text",
    "duration_parts",
    "require_rosbags",
    "write_bag",
]

#: Storage of a bag, by the suffix of its path: the name of ``rosbags.rosbag2.StoragePlugin``.
BAG_STORAGE = MappingProxyType({".mcap": "MCAP", ".db3": "SQLITE3"})
#: The topic a ``joint_trajectory_controller`` named ``joint_trajectory_controller`` listens on.
DEFAULT_TRAJECTORY_TOPIC = "/joint_trajectory_controller/joint_trajectory"
#: The topic of the sampled joint states.
JOINT_STATES_TOPIC = "/joint_states"
#: The rosbag2 metadata format version written (``rosbags`` writes 8 or 9; 8 is the older).
ROSBAG2_VERSION = 8
#: Message types, as the typestore names them.
TRAJECTORY_TYPE = "trajectory_msgs/msg/JointTrajectory"
JOINT_STATE_TYPE = "sensor_msgs/msg/JointState"
#: A fully qualified ROS 2 topic name: "/" then tokens of letters, digits and "_" (not starting
#: with a digit), separated by single "/".
_TOPIC_PATTERN = re.compile(r"/[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*")
_NANOSECONDS_PER_SECOND = 1_000_000_000


def require_rosbags() -> None:
    """Check that ``rosbags`` can be imported (before any work).

    Raises:
        MissingDependencyError: it is not installed; the message names the ``ros`` extra.
    """
    try:
        import rosbags.rosbag2
        import rosbags.typesys  # noqa: F401
    except ImportError:
        raise MissingDependencyError("rosbags", "ros", "writing a ROS 2 bag") from None


def check_topic(topic: str, option: str = "--topic") -> str:
    """``topic`` if it is a fully qualified ROS 2 topic name (``/a/b_c``), else an error naming ``option``.

    Raises:
        InvalidParameterError: not a fully qualified topic name.
    """
    if not isinstance(topic, str) or _TOPIC_PATTERN.fullmatch(topic) is None:
        raise InvalidParameterError(
            option,
            topic,
            "a fully qualified ROS 2 topic name: '/' then names of letters, digits and '_' (not starting with a "
            "digit) separated by single '/', e.g. " + DEFAULT_TRAJECTORY_TOPIC,
        )
    return topic


def duration_parts(t_s: float) -> tuple[int, int]:
    """A time [s] as ROS's (sec, nanosec), 0 <= nanosec < 1e9, rounded to the nearest nanosecond."""
    return divmod(round(float(t_s) * 1e9), _NANOSECONDS_PER_SECOND)


def custom_data_text(values: Mapping[str, object]) -> dict[str, str]:
    """``values`` as rosbag2 custom data (text only): strings as they are, everything else as
    compact JSON (non-finite numbers as null)."""

    def text(value: object) -> str:
        if isinstance(value, str):
            return value
        if isinstance(value, float) and not math.isfinite(value):
            return "null"
        return json.dumps(value, allow_nan=False, separators=(",", ":"))

    return {str(key): text(value) for key, value in values.items()}


@dataclass(frozen=True)
class TrajectoryBag:
    """What a bag holds: the samples of a trajectory and where they go.

    Attributes:
        times_s: Sample times, (n,), from 0, increasing [s].
        positions_rad: Joint angles, (n, j) [rad].
        velocities_rad_s: Joint speeds, (n, j) [rad/s].
        accelerations_rad_s2: Joint accelerations, (n, j) [rad/s^2].
        efforts_n_m: Joint torques, (n, j) [N m].
        joint_names: The j joint names (the URDF's).
        topic: Topic of the ``JointTrajectory`` message (fully qualified).
        joint_states: Also record the samples as ``JointState`` messages on ``/joint_states``.
        custom_data: Key -> text recorded in the bag's metadata (``custom_data``).
    """

    times_s: np.ndarray
    positions_rad: np.ndarray
    velocities_rad_s: np.ndarray
    accelerations_rad_s2: np.ndarray
    efforts_n_m: np.ndarray
    joint_names: tuple[str, ...]
    topic: str = DEFAULT_TRAJECTORY_TOPIC
    joint_states: bool = False
    custom_data: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        times = np.asarray(self.times_s, dtype=float)
        if times.ndim != 1 or times.size == 0 or not np.all(np.isfinite(times)):
            raise InvalidParameterError("times_s", self.times_s, "a non-empty 1-D array of finite times [s]")
        if times[0] < 0.0 or np.any(np.diff(times) <= 0.0):
            raise InvalidParameterError("times_s", self.times_s, "times from 0 on, strictly increasing [s]")
        names = tuple(self.joint_names)
        if not names or not all(isinstance(name, str) and name for name in names):
            raise InvalidParameterError("joint_names", self.joint_names, "one or more non-empty joint names")
        object.__setattr__(self, "times_s", times)
        object.__setattr__(self, "joint_names", names)
        for key in ("positions_rad", "velocities_rad_s", "accelerations_rad_s2", "efforts_n_m"):
            values = np.asarray(getattr(self, key), dtype=float)
            if values.shape != (times.size, len(names)):
                raise InvalidParameterError(
                    key, values.shape, f"shape {(times.size, len(names))}: one row per time, one column per joint"
                )
            object.__setattr__(self, key, values)
        check_topic(self.topic, "topic")
        if not all(isinstance(k, str) and isinstance(v, str) for k, v in self.custom_data.items()):
            raise InvalidParameterError("custom_data", dict(self.custom_data), "text keys and text values")
        object.__setattr__(self, "custom_data", MappingProxyType(dict(self.custom_data)))


def _messages(bag: TrajectoryBag, typestore) -> Iterator[tuple[str, str, int, object]]:
    """(topic, message type, bag time [ns], message) of every message of ``bag``, in time order."""
    types = typestore.types
    duration, time = types["builtin_interfaces/msg/Duration"], types["builtin_interfaces/msg/Time"]
    header, point = types["std_msgs/msg/Header"], types["trajectory_msgs/msg/JointTrajectoryPoint"]
    names = list(bag.joint_names)
    stamps = [duration_parts(t) for t in bag.times_s]
    points = [
        point(
            positions=bag.positions_rad[i],
            velocities=bag.velocities_rad_s[i],
            accelerations=bag.accelerations_rad_s2[i],
            effort=bag.efforts_n_m[i],
            time_from_start=duration(sec=sec, nanosec=nanosec),
        )
        for i, (sec, nanosec) in enumerate(stamps)
    ]
    start = header(stamp=time(sec=0, nanosec=0), frame_id="")  # zero: the controller starts it on receipt
    yield bag.topic, TRAJECTORY_TYPE, 0, types[TRAJECTORY_TYPE](header=start, joint_names=names, points=points)
    if not bag.joint_states:
        return
    state = types[JOINT_STATE_TYPE]
    for i, (sec, nanosec) in enumerate(stamps):
        message = state(
            header=header(stamp=time(sec=sec, nanosec=nanosec), frame_id=""),
            name=names,
            position=bag.positions_rad[i],
            velocity=bag.velocities_rad_s[i],
            effort=bag.efforts_n_m[i],
        )
        yield JOINT_STATES_TOPIC, JOINT_STATE_TYPE, sec * _NANOSECONDS_PER_SECOND + nanosec, message


def _write_into(path: Path, bag: TrajectoryBag, storage: str) -> None:
    """Write ``bag`` as a new rosbag2 folder ``path`` with the storage plugin named ``storage``."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS2_HUMBLE)
    writer = Writer(path, version=ROSBAG2_VERSION, storage_plugin=StoragePlugin[storage])
    for key, value in bag.custom_data.items():
        writer.set_custom_data(key, value)
    with writer:
        connections = {}
        for topic, msgtype, stamp_ns, message in _messages(bag, typestore):
            if topic not in connections:
                connections[topic] = writer.add_connection(topic, msgtype, typestore=typestore)
            writer.write(connections[topic], stamp_ns, typestore.serialize_cdr(message, msgtype))


def _flush_folder(folder: Path) -> None:
    """fsync every file of ``folder`` and the folder itself."""
    for entry in folder.iterdir():
        with entry.open("rb") as handle:
            os.fsync(handle.fileno())
    descriptor = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(descriptor)
    finally:
        os.close(descriptor)


def write_bag(path: str | Path, bag: TrajectoryBag) -> Path:
    """Write ``bag`` as the rosbag2 folder ``path`` (storage by suffix: ``.mcap`` or ``.db3``):
    built in a temporary folder beside it, flushed to disk, then renamed into place.

    Returns:
        The bag's folder.

    Raises:
        InvalidParameterError: the suffix names no storage.
        OutputExistsError: ``path`` exists (a bag is never replaced).
        MissingDependencyError: ``rosbags`` is not installed.
        OSError: the folder cannot be written (nothing is left behind).
    """
    path = Path(path)
    storage = BAG_STORAGE.get(path.suffix.lower())
    if storage is None:
        raise InvalidParameterError("path", str(path), f"a bag name ending in one of {', '.join(BAG_STORAGE)}")
    require_rosbags()
    if path.exists() or path.is_symlink():
        raise OutputExistsError(f"{path} exists; a ROS 2 bag is a folder and is never replaced: remove it first")
    staging = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent))
    try:
        inner = staging / path.name  # the storage file is named after the folder
        _write_into(inner, bag, storage)
        _flush_folder(inner)
        if path.exists() or path.is_symlink():
            raise OutputExistsError(f"{path} appeared while the bag was written; it is left as it is")
        os.rename(inner, path)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return path
