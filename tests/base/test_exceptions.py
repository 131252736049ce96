"""The exception hierarchy (pipeline.exceptions): every error derives from PipelineError and
survives a pickle round trip as itself, with its message and attributes (worker processes raise
them across process boundaries)."""

from __future__ import annotations

import pickle
import re

import pytest

from pipeline import exceptions as ex

EXAMPLES = [
    ex.PipelineError("plain message"),
    ex.InvalidParameterError("margin_m", -1.0, "a number >= 0"),
    ex.ObstacleSizeError("W", 0.001, "W > 2 corner radii", (0.25, 0.001)),
    ex.ArmMismatchError((0.3, 0.35), (0.01, 0.01), (0.3, 0.3), (0.01, 0.01), "arm.urdf"),
    ex.RobotModelError("arm.urdf: not planar"),
    ex.WorkerPoolError("a worker process ended abruptly"),
    ex.OutputLockedError("results", "results/.build.lock", 1234, "other-host", True),
    ex.SchedulerUnreachableError("tcp://127.0.0.1:1", "Timed out trying to connect after 5 s"),
    ex.ExecutionRefusedError(0.27, 0.09, "paper", ("joint 2 speed bound 1.2350 rad/s > limit 0.3000 rad/s",)),
    ex.TimingRefusedError(("joint 1 jerk bound 210.0000 rad/s^3 > limit 200.0000 rad/s^3",)),
    ex.UnreachableObstacleError("P5", 0.71, (0.05, 0.65), (0.3, 0.12)),
    ex.OutOfFittedRangeError("L", 0.31, (0.2, 0.3)),
    ex.DataFileError("coefficients.json", "changed while the sweep was running (sha256 differs)"),
    ex.OutputExistsError("results/coefficients.json exists"),
    ex.NoCertifiedTrajectoryError(0.25, 0.12, 0.0087, 0.01, "the end pose is within the margin"),
    ex.BuildNotConvergedError(["test 3: endpoint error 6.1 mm > 5 mm"]),
    ex.InfeasibleSceneError(0.3, 0.12, "P5", -0.001, 4, 441),
    ex.NoSceneWindowError((0.2, 0.3), (0.08, 0.12), ("P3 needs d >= 0.5700 m for the reach",), 0.57, None, True),
    ex.RegionMapMismatchError("a" * 64, "b" * 64),
    ex.RegionMapLimitsError("velocity_rad_s", [3.0, 3.0], [0.3, 0.3]),
    ex.MissingDependencyError("rosbags", "ros", "writing a ROS 2 bag"),
]


def test_every_example_is_a_pipeline_error_and_every_error_class_has_an_example() -> None:
    classes = {
        obj
        for obj in vars(ex).values()
        if isinstance(obj, type) and issubclass(obj, Exception) and not issubclass(obj, Warning)
    }
    assert classes == {type(error) for error in EXAMPLES}
    assert all(isinstance(error, ex.PipelineError) for error in EXAMPLES)


@pytest.mark.parametrize("error", EXAMPLES, ids=lambda e: type(e).__name__)
def test_errors_survive_a_pickle_round_trip(error: Exception) -> None:
    again = pickle.loads(pickle.dumps(error))
    assert type(again) is type(error)
    assert str(again) == str(error)
    assert again.args == error.args
    assert vars(again) == vars(error)
    with pytest.raises(type(error), match=re.escape(str(error))):
        raise again
