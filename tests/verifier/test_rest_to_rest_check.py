"""The sweep's rest-to-rest check (verify.acceptance.metrics.rest_to_rest_check): per case the
shortest rest-to-rest timing within the arm's limits, its certified bounds against the samples
and the limits, at rest at both ends; the summary's least room of both timings and the largest
T' / T, on stdout and in the JSON."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import pipeline.motion.execution_certificate as execution_certificate
from pipeline.model.arm import DEFAULT_URDF, PlanarArm, load_planar_arm
from pipeline.model.limits import ArmLimits
from pipeline.model.obstacle import Obstacle
from pipeline.model.scene import Scene
from pipeline.motion.path import desired_path
from pipeline.motion.rest_to_rest import shortest_rest_to_rest
from pipeline.motion.timed_trajectory import TimedTrajectory
from pipeline.motion.timing import RestToRestTiming
from pipeline.motion.trajectory import JointTrajectory
from pipeline.online.execution import dynamics_of
from verify.acceptance.metrics import (
    REST_TO_REST_GRID,
    AcceptanceThresholds,
    MeasureSettings,
    measure_trajectory,
    rest_to_rest_check,
    rest_to_rest_instants,
)
from verify.acceptance.results import JOINT_QUANTITIES, RestToRestCheck
from verify.acceptance.sampling import REST_TO_REST_ROOM
from verify.sweep import main

FAST = ["--samples", "200", "--no-progress"]
#: Table 2, Test 5 of the paper: (A1, w1, phi1, gamma1, A2, w2, phi2, gamma2), L, W.
TEST5 = ((-0.781, 0.996, 0.467, 1.116, 1.449, 0.864, 0.131, 0.543), 0.25, 0.10)


def _urdf_with(tmp_path: Path, name: str, old: str, new: str) -> Path:
    text = DEFAULT_URDF.read_text(encoding="utf-8")
    assert old in text
    path = tmp_path / name
    path.write_text(text.replace(old, new), encoding="utf-8")
    return path


def _test5(scene: Scene) -> tuple[JointTrajectory, object, Obstacle]:
    parameters, length, width = TEST5
    obstacle = Obstacle.in_scene(length, width, scene)
    path = desired_path(obstacle, scene)
    return JointTrajectory(parameters, path.duration_s), path, obstacle


def _sweep(capsys, tmp_path: Path, *argv: str) -> tuple[int, str, dict]:
    out_file = tmp_path / "sweep.json"
    status = main(["--coefficients", "paper", *FAST, "--json", str(out_file), *argv])
    return status, capsys.readouterr().out, json.loads(out_file.read_text())


def _row(out: str, name: str) -> str:
    return next(line for line in out.splitlines() if line.startswith(name))


def _dense_maxima(timed: TimedTrajectory, arm: PlanarArm, instants: np.ndarray) -> dict[str, np.ndarray]:
    """|dq|, |ddq| and |tau| by Pinocchio's RNEA (not the closed form) at ``instants``."""
    q, dq, ddq = timed.states(instants)
    data = arm.model.createData()
    tau = np.array([pin.rnea(arm.model, data, *state) for state in zip(q, dq, ddq, strict=True)])
    return {"speed": np.abs(dq).max(0), "acceleration": np.abs(ddq).max(0), "torque": np.abs(tau).max(0)}


# --------------------------------------------------------------------------------------------


def test_every_case_has_a_consistent_rest_to_rest_check(capsys, tmp_path: Path) -> None:
    status, out, data = _sweep(capsys, tmp_path, "--n", "5", "--seed", "4", "--max-acceleration", "30", "60")
    assert status in (0, 1)
    rooms: dict[str, dict[str, list]] = {"paper": {}, "rest_to_rest": {}}
    for case in data["cases"]:
        rest = case["rest_to_rest"]
        assert case["rest_to_rest_error"] is None and rest["problems"] == []
        assert rest["T_s"] > case["T_s"] and rest["T_ratio"] == pytest.approx(rest["T_s"] / case["T_s"])
        assert rest["T_s"] == pytest.approx(case["T_s"] / rest["speed_scale"] + rest["ramp_s"])
        assert rest["end_speed_rad_s"] <= 1e-12 and rest["end_acceleration_rad_s2"] <= 1e-12
        limits = {
            "speed": case["velocity_limits_rad_s"],
            "acceleration": case["acceleration_limits_rad_s2"],
            "torque": case["effort_limits_n_m"],
        }
        assert limits["acceleration"] == [30.0, 60.0]
        paper_bounds = {
            "speed": case["peak_velocity_rad_s"],
            "acceleration": case["peak_acceleration_rad_s2"],
            "torque": case["torque_bound_n_m"],
        }
        for (name, _), key in zip(JOINT_QUANTITIES, ("rad_s", "rad_s2", "n_m"), strict=True):
            bound, sampled = rest[f"{name}_bound_{key}"], rest[f"sampled_{name}_{key}"]
            assert all(s <= b <= lim for s, b, lim in zip(sampled, bound, limits[name], strict=True))
            room = rest["room"][f"{name}_{key}"]
            assert room == pytest.approx([lim - b for lim, b in zip(limits[name], bound, strict=True)])
            rooms["rest_to_rest"].setdefault(name, []).append(room)
            rooms["paper"].setdefault(name, []).append(
                [lim - b for lim, b in zip(limits[name], paper_bounds[name], strict=True)]
            )
    summary = data["summary"]
    assert summary["n_rest_to_rest"] == summary["n_rest_to_rest_passed"] == 5
    assert summary["rest_to_rest_ratio_max"] == pytest.approx(max(c["rest_to_rest"]["T_ratio"] for c in data["cases"]))
    for timing, by_quantity in rooms.items():
        for (name, _), key in zip(JOINT_QUANTITIES, ("rad_s", "rad_s2", "n_m"), strict=True):
            least = np.min(np.array(by_quantity[name]), axis=0)
            assert summary["least_room"][timing][f"{name}_{key}"] == pytest.approx(least.tolist())
    rest_row, room_row = _row(out, "rest-to-rest"), _row(out, "least room")
    assert "5 / 5 certified within the limits" in rest_row
    assert f"T'/T max {summary['rest_to_rest_ratio_max']:.4f}" in rest_row
    assert room_row.count("acceleration (") == 2 and "unlimited" not in room_row


def test_a_slow_arm_fails_the_paper_timing_and_passes_rest_to_rest(capsys, tmp_path: Path) -> None:
    slow = _urdf_with(tmp_path, "slow.urdf", 'velocity="3.0"', 'velocity="0.3"')
    status, out, data = _sweep(capsys, tmp_path, "--n", "3", "--seed", "5", "--urdf", str(slow))
    assert status == 1
    for case in data["cases"]:
        assert not case["within_velocity_limits"] and any("joint speed peak" in f for f in case["failures"])
        assert not any("rest-to-rest" in f for f in case["failures"])
        rest = case["rest_to_rest"]
        assert rest["problems"] == [] and rest["T_s"] > case["T_s"] and rest["T_ratio"] > 2.0
        assert max(rest["sampled_speed_rad_s"]) <= max(rest["speed_bound_rad_s"]) <= 0.3
    least = data["summary"]["least_room"]
    assert max(least["paper"]["speed_rad_s"]) < 0.0 < min(least["rest_to_rest"]["speed_rad_s"])
    assert least["paper"]["acceleration_rad_s2"] == [None, None]  # no acceleration limit
    assert "3 / 3 certified within the limits" in _row(out, "rest-to-rest")
    assert "paper: speed (-" in _row(out, "least room") and "(acceleration unlimited)" in _row(out, "least room")


def test_the_certified_bounds_hold_against_rnea_at_dense_instants(arm: PlanarArm, scene: Scene) -> None:
    """The bounds lie above Pinocchio's RNEA at 20,001 uniform instants and the check's coarse
    instants; the sampled maxima the check refined (near their bounds) lie within 1e-4 of the
    dense maxima, and where the coarse samples decided, the dense maxima too lie well below the
    bounds (a refinement could not have changed the verdict)."""
    trajectory, _, _ = _test5(scene)
    dynamics, limits = dynamics_of(arm), ArmLimits.from_arm(arm, (40.0, 80.0))
    check = rest_to_rest_check(trajectory, arm, dynamics, limits)
    timing = shortest_rest_to_rest(trajectory, dynamics, limits)
    timed = TimedTrajectory(trajectory, timing)
    instants = np.union1d(np.linspace(0.0, timed.duration_s, 20001), rest_to_rest_instants(timing))
    dense = _dense_maxima(timed, arm, instants)
    for name, (bound, sampled, limit) in check.quantities().items():
        assert np.all(np.asarray(bound) >= dense[name]), name
        bound, sampled = np.asarray(bound), np.asarray(sampled)
        assert np.all(bound >= sampled), name
        decided = sampled < (1.0 - REST_TO_REST_ROOM) * bound  # coarse only: far enough below the bound
        refined = ~decided
        assert np.all(np.abs(sampled - dense[name])[refined] <= 1e-4 * dense[name][refined]), name
        # Where the coarse samples decided, the true maximum too lies well below the bound.
        assert np.all(dense[name][decided] < (1.0 - REST_TO_REST_ROOM / 2) * bound[decided]), name
        assert np.all(np.asarray(bound) <= limit), name
    assert check.at_rest and not check.problems() and check.duration_ratio > 1.0
    ramp, middle, fine = REST_TO_REST_GRID
    coarse = 2 * ramp + middle - 2
    assert check.samples > coarse and (check.samples - coarse) % fine == 0  # some quantities were refined


@pytest.mark.parametrize("quantity", ["speed", "acceleration", "torque"])
def test_a_bound_below_its_samples_fails_the_case(arm: PlanarArm, scene: Scene, monkeypatch, quantity: str) -> None:
    """A certificate whose bound were 0.99 times the values the check samples is caught."""
    trajectory, path, obstacle = _test5(scene)
    certify = execution_certificate.certify_execution
    fields = {
        "speed": "speed_bound_rad_s",
        "acceleration": "acceleration_bound_rad_s2",
        "torque": "torque_bound_n_m",
    }

    def too_low(timed, dynamics, limits=None, **kwargs):
        certificate = certify(timed, dynamics, limits, **kwargs)
        if not isinstance(timed.timing, RestToRestTiming):
            return certificate  # the paper timing's torque check
        sampled = _dense_maxima(timed, arm, rest_to_rest_instants(timed.timing))[quantity]
        return dataclasses.replace(certificate, **{fields[quantity]: 0.99 * sampled})

    honest = measure_trajectory(trajectory, path, obstacle, arm, MeasureSettings(time_samples=200))
    assert not any("rest-to-rest" in f for f in honest.failures)
    monkeypatch.setattr(execution_certificate, "certify_execution", too_low)
    result = measure_trajectory(trajectory, path, obstacle, arm, MeasureSettings(time_samples=200))
    assert any(f.startswith(f"rest-to-rest certified {quantity} bound") for f in result.failures), result.failures
    rest = result.measurement.joints.rest_to_rest
    assert rest.problems() and result.to_json()["rest_to_rest"]["problems"] == rest.problems()


def test_limits_and_rest_are_checked(arm: PlanarArm, scene: Scene) -> None:
    trajectory, _, _ = _test5(scene)
    check = rest_to_rest_check(trajectory, arm, dynamics_of(arm), ArmLimits.from_arm(arm))
    above = dataclasses.replace(check, torque_bound_n_m=(11.0, check.torque_bound_n_m[1]))
    assert above.problems() == [
        f"rest-to-rest torque bound (11, {check.torque_bound_n_m[1]:.4g}) N m exceeds the limits (10, 10)"
    ]
    assert above.room["torque"][0] == pytest.approx(-1.0)
    moving = dataclasses.replace(check, end_speed_rad_s=1e-9)
    assert not moving.at_rest and "not at rest at its ends" in moving.problems()[0]
    assert math.isinf(check.room["acceleration"][0]) and check.to_json()["room"]["acceleration_rad_s2"] == [None, None]
    with pytest.raises(Exception, match="samples"):
        RestToRestCheck(**{**dataclasses.asdict(check), "samples": 1})


def test_no_rest_to_rest_timing_is_a_failure_named(scene: Scene, tmp_path: Path) -> None:
    """Effort limits a timing cannot keep even at a thousandth of the path speed."""
    weak = load_planar_arm(_urdf_with(tmp_path, "weak.urdf", 'effort="10"', 'effort="1e-9"'))
    trajectory, path, obstacle = _test5(scene)
    result = measure_trajectory(trajectory, path, obstacle, weak, MeasureSettings(time_samples=200))
    joints = result.measurement.joints
    assert joints.rest_to_rest is None and "no rest-to-rest timing keeps the limits" in joints.rest_to_rest_error
    assert joints.rest_to_rest_error in result.failures
    assert result.to_json()["rest_to_rest"] is None
    relaxed = MeasureSettings(time_samples=200, thresholds=AcceptanceThresholds(check_joint_limits=False))
    assert not any("rest-to-rest" in f for f in measure_trajectory(trajectory, path, obstacle, weak, relaxed).failures)


def test_the_instants_cover_both_ramps_and_the_middle() -> None:
    timing = RestToRestTiming(3.0, 0.5, 0.2)
    instants = rest_to_rest_instants(timing, (5, 11))
    assert instants.size == 5 + 11 + 5 - 2 and np.all(np.diff(instants) > 0)
    for point in (0.0, 0.2, timing.duration_s - 0.2, timing.duration_s):
        assert np.any(np.isclose(instants, point, rtol=0, atol=1e-15))
    assert np.count_nonzero(instants <= 0.2) == 5
