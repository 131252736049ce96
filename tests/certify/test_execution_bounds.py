"""The region map's execution bounds: per leaf, the angle range, the paper timing's speed,
acceleration and torque bounds and a rest-to-rest timing within the arm's limits, proven for
every obstacle of the leaf. Checked against dense sampling at 10^4 obstacles (closed-form
dynamics, itself equal to Pinocchio's RNEA) and against RNEA directly on a few."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline import load_coefficients
from pipeline.certify.execution_bounds import SIGNIFICANT_DIGITS, ExecutionBounds, outward
from pipeline.certify.map_for_coefficients import summary_lines, with_execution_bounds
from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
from pipeline.certify.region_map import RegionMap, region_map_text
from pipeline.exceptions import InvalidParameterError, RegionMapLimitsError
from pipeline.model.arm import PlanarArm
from pipeline.model.dynamics import identify_dynamics
from pipeline.model.limits import ArmLimits
from pipeline.motion.near_optimal import NEAR_OPTIMAL
from pipeline.motion.rest_to_rest import REST_TO_REST, _widened, rest_to_rest_scales, shortest_rest_to_rest
from pipeline.motion.timed_trajectory import TimedTrajectory
from pipeline.motion.timing import PAPER_TIMING, RestToRestTiming
from pipeline.online.batch import generate_batch
from pipeline.online.batch_execution import execution_batch
from pipeline.online.generator import generate
from pipeline.online.repair import generate_certified

CASES = 10_000
SAMPLES = 400


@pytest.fixture(scope="module")
def paper():
    return load_coefficients("paper")


@pytest.fixture(scope="module")
def limits(arm: PlanarArm) -> ArmLimits:
    return ArmLimits.from_arm(arm, (5.0, 5.0))


@pytest.fixture(scope="module")
def exec_map(paper, arm: PlanarArm, limits: ArmLimits) -> RegionMap:
    coarse = certify_range(paper, RangeCertificateConfig(min_cell=1 / 16, boundary_cell=1 / 8))
    return with_execution_bounds(coarse, paper, identify_dynamics(arm), limits)


def _obstacles(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.uniform(0.2, 0.3, n), rng.uniform(0.08, 0.12, n)


def test_paper_timing_bounds_hold_at_ten_thousand_obstacles(paper, arm: PlanarArm, exec_map: RegionMap) -> None:
    """Angles, |theta'|, |theta''| and the torques of 10^4 obstacles, each sampled at 400 times,
    never exceed their leaf's bounds; the sinusoids are evaluated here from the parameters."""
    L, W = _obstacles(CASES, 11)
    batch = generate_batch(paper, L, W, region_map=exec_map)
    bounds = exec_map.execution
    leaf = batch.leaf
    assert np.all(leaf >= 0)
    p = batch.parameters
    t = np.linspace(0.0, 1.0, SAMPLES)[None, :] * batch.durations_s[:, None]
    q, dq, ddq = [], [], []
    for j in (0, 4):
        A, w, phi, gamma = (p[:, j + k, None] for k in range(4))
        q.append(A * np.sin(w * t + phi) + gamma)
        dq.append(A * w * np.cos(w * t + phi))
        ddq.append(-A * w * w * np.sin(w * t + phi))
    q, dq, ddq = (np.stack(x, -1) for x in (q, dq, ddq))  # (n, S, 2)
    angles = bounds.angle_range_rad[leaf]  # (n, 2, 2)
    assert np.all(q.min(1) >= angles[:, :, 0]) and np.all(q.max(1) <= angles[:, :, 1])
    assert np.all(np.abs(dq).max(1) <= bounds.paper_speed_rad_s[leaf])
    assert np.all(np.abs(ddq).max(1) <= bounds.paper_acceleration_rad_s2[leaf])
    torque = identify_dynamics(arm).torque(q, dq, ddq)
    assert np.all(np.abs(torque).max(1) <= bounds.paper_torque_n_m[leaf])
    # Not vacuous: the speed bounds lie within 5 % of the sampled peaks on these coarse leaves.
    ratio = bounds.paper_speed_rad_s[leaf] / np.abs(dq).max(1)
    assert np.median(ratio) < 1.05


def test_rest_to_rest_bounds_hold_at_ten_thousand_obstacles(
    paper, arm: PlanarArm, limits: ArmLimits, exec_map: RegionMap
) -> None:
    """Each obstacle run with its leaf's (c, r): sampled |dq|, |ddq|, |tau| within the leaf's
    bounds, and the bounds within the limits; it starts and ends at rest."""
    L, W = _obstacles(CASES, 12)
    batch = generate_batch(paper, L, W, region_map=exec_map)
    result = execution_batch(paper, batch, REST_TO_REST, region_map=exec_map)
    dynamics = identify_dynamics(arm)
    assert np.all(result.within_limits)
    assert np.all(result.speed_bound_rad_s <= limits.velocity_rad_s)
    assert np.all(result.acceleration_bound_rad_s2 <= limits.acceleration_rad_s2)
    worst = np.zeros((CASES, 3, 2))
    for i in range(CASES):
        timing = RestToRestTiming(float(batch.durations_s[i]), float(result.speed_scale[i]), float(result.ramp_s[i]))
        assert timing.duration_s == pytest.approx(result.duration_s[i], rel=1e-15)
        timed = TimedTrajectory(batch.trajectory(i), timing)
        q, dq, ddq = timed.states(np.linspace(0.0, timing.duration_s, 200))
        assert np.abs(dq[[0, -1]]).max() <= 1e-12 and np.abs(ddq[[0, -1]]).max() <= 1e-12
        worst[i] = np.abs(dq).max(0), np.abs(ddq).max(0), np.abs(dynamics.torque(q, dq, ddq)).max(0)
    assert np.all(worst[:, 0] <= result.speed_bound_rad_s)
    assert np.all(worst[:, 1] <= result.acceleration_bound_rad_s2)
    assert np.all(worst[:, 2] <= result.torque_bound_n_m)


def test_torque_bounds_hold_against_rnea(paper, arm: PlanarArm, exec_map: RegionMap) -> None:
    """Pinocchio's RNEA itself (not the closed form) at 2,001 samples of 20 obstacles, both timings."""
    model, data = arm.model, arm.model.createData()
    bounds = exec_map.execution
    L, W = _obstacles(20, 13)
    for length, width in zip(L, W, strict=True):
        answer = generate(paper, float(length), float(width), region_map=exec_map)
        leaf = exec_map.leaf_at(float(length), float(width))
        c, r, _, rest, paper_bounds = bounds.leaf(leaf)
        for timing, bound in ((PAPER_TIMING, paper_bounds[2]), (RestToRestTiming(answer.duration_s, c, r), rest[2])):
            timed = TimedTrajectory(answer.trajectory, timing)
            q, dq, ddq = timed.states(np.linspace(0.0, timed.duration_s, 2001))
            full = np.zeros((q.shape[0], model.nq))
            tau = np.array(
                [
                    pin.rnea(model, data, _pad(full[k], q[k]), _pad(full[k], dq[k]), _pad(full[k], ddq[k]))[:2]
                    for k in range(q.shape[0])
                ]
            )
            assert np.all(np.abs(tau).max(0) <= bound)


def _pad(zeros: np.ndarray, values: np.ndarray) -> np.ndarray:
    out = zeros.copy()
    out[:2] = values
    return out


def test_vectorised_scales_equal_the_per_query_timing(paper, arm: PlanarArm, limits: ArmLimits) -> None:
    dynamics = identify_dynamics(arm)
    for length, width in zip(*_obstacles(10, 14), strict=True):
        trajectory = generate(paper, float(length), float(width)).trajectory
        one = shortest_rest_to_rest(trajectory, dynamics, limits)
        V = _widened(np.asarray(trajectory.peak_velocity_rad_s()))
        acc = _widened(np.asarray(trajectory.peak_acceleration_rad_s2()))
        c, r = rest_to_rest_scales(np.array([trajectory.duration_s]), V[None], acc[None], dynamics, limits)
        assert (one.speed_scale, one.ramp_s) == (c[0], r[0])


def test_the_file_keeps_the_bounds_bit_for_bit(exec_map: RegionMap) -> None:
    import json

    text = region_map_text(exec_map)
    again = RegionMap.from_json(json.loads(text))
    assert region_map_text(again) == text
    for key, values in exec_map.execution.columns.items():
        np.testing.assert_array_equal(again.execution.columns[key], values)
    assert again.execution.limits == exec_map.execution.limits
    assert again.execution.dynamics == exec_map.execution.dynamics


def test_a_map_without_execution_bounds_reads_as_before(paper) -> None:
    import json

    plain = certify_range(paper, RangeCertificateConfig(min_cell=1 / 4, boundary_cell=1 / 4))
    document = json.loads(region_map_text(plain))
    assert "execution" not in document
    assert RegionMap.from_json(document).execution is None


@settings(max_examples=300, deadline=None)
@given(st.floats(min_value=-1e3, max_value=1e3, allow_nan=False).filter(lambda x: x != 0.0), st.booleans())
def test_rounding_is_outward_and_small(x: float, down: bool) -> None:
    y = float(outward(np.array([x]), down)[0])
    assert (y <= x) if down else (y >= x)
    assert abs(y - x) <= 2.0 * 10.0 ** (1 - SIGNIFICANT_DIGITS) * abs(x)
    assert len(f"{y:.{SIGNIFICANT_DIGITS}g}") <= SIGNIFICANT_DIGITS + 8 and float(f"{y:.{SIGNIFICANT_DIGITS}g}") == y


def test_another_arms_limits_are_refused_by_the_map(arm: PlanarArm, limits: ArmLimits, exec_map: RegionMap) -> None:
    bounds: ExecutionBounds = exec_map.execution
    dynamics = identify_dynamics(arm)
    bounds.check_arm(limits, dynamics)  # its own arm
    slower = dataclasses.replace(limits, velocity_rad_s=(0.3, 0.3))
    with pytest.raises(RegionMapLimitsError) as info:
        bounds.check_arm(slower, dynamics)
    assert info.value.quantity == "velocity_rad_s" and "0.3" in str(info.value)
    heavier = dataclasses.replace(dynamics, m0=tuple(tuple(2.0 * v for v in row) for row in dynamics.m0))
    with pytest.raises(RegionMapLimitsError, match="inertia"):
        bounds.check_arm(limits, heavier)


def test_generate_certified_reads_the_map_for_its_arm_only(
    paper, arm: PlanarArm, limits: ArmLimits, exec_map: RegionMap
) -> None:
    """The map answers for the arm it was built with; another arm's limits go to the per-query
    certificate, which holds them (and refuses the paper timing at 0.3 rad/s)."""
    answer = generate_certified(paper, 0.25, 0.09, arm, region_map=exec_map, timing=REST_TO_REST, limits=limits)
    assert answer.execution_source == "range"
    leaf = exec_map.leaf_at(0.25, 0.09)
    c, r, angles, rest, _ = exec_map.execution.leaf(leaf)
    assert answer.executed.timing == RestToRestTiming(answer.trajectory.duration_s, c, r)
    np.testing.assert_array_equal(answer.execution.certificate.torque_bound_n_m, rest[2])
    assert answer.execution.certificate.angle_range_rad == angles
    paper_answer = generate_certified(paper, 0.25, 0.09, arm, region_map=exec_map, limits=limits)
    assert paper_answer.execution_source == "range" and paper_answer.duration_s == paper_answer.trajectory.duration_s
    slow = dataclasses.replace(limits, velocity_rad_s=(0.3, 0.3))
    retimed = generate_certified(paper, 0.25, 0.09, arm, region_map=exec_map, timing=REST_TO_REST, limits=slow)
    assert retimed.execution_source == "query"
    assert retimed.duration_s > retimed.trajectory.duration_s
    assert np.all(retimed.execution.certificate.speed_bound_rad_s <= 0.3)


def test_the_build_summary_names_the_share_where_the_paper_timing_breaks_a_limit(
    paper, arm: PlanarArm, exec_map: RegionMap
) -> None:
    """With a 0.9 rad/s speed limit, joint 2's paper peaks (about 1.3 rad/s) break it everywhere;
    the map says so, and that the rest-to-rest timing keeps it everywhere."""
    slow = dataclasses.replace(ArmLimits.from_arm(arm), velocity_rad_s=(3.0, 0.9))
    slow_map = with_execution_bounds(dataclasses.replace(exec_map, execution=None), paper, identify_dynamics(arm), slow)
    summary = slow_map.execution_summary()
    assert summary["paper_breaks_fraction"]["speed"] == pytest.approx(1.0)
    assert summary["paper_keeps_limits_fraction"] == pytest.approx(0.0)
    assert summary["rest_to_rest_fraction"] == pytest.approx(1.0)
    assert summary["rest_to_rest_duration_max_s"] > summary["path_duration_max_s"]
    line = summary_lines(slow_map)[-1]
    assert "speed 100.00 %" in line and "rest-to-rest within them on 100.00 %" in line
    assert math.isfinite(summary["rest_to_rest_duration_max_s"])


def test_bounds_do_not_depend_on_the_workers(paper, arm: PlanarArm, limits: ArmLimits) -> None:
    """Execution bounds of 5,000 random boxes (three chunks of leaves) computed on two worker
    processes equal, bit for bit, those computed in this process, column by column."""
    from pipeline.certify.execution_range import execution_bounds
    from pipeline.certify.range_model import RangeModel

    rng = np.random.default_rng(7)
    n = 5_000
    half = np.column_stack([rng.uniform(1e-4, 5e-3, n), rng.uniform(1e-4, 2e-3, n)])
    lo, size = np.array([0.2, 0.08]), np.array([0.1, 0.04])
    centre = lo + half + rng.uniform(0.0, 1.0, (n, 2)) * (size - 2 * half)  # boxes inside the range
    model, dynamics = RangeModel.from_coefficients(paper), identify_dynamics(arm)
    here = execution_bounds(model, centre, half, dynamics, limits, 1)
    pooled = execution_bounds(model, centre, half, dynamics, limits, 2)
    assert sorted(here.columns) == sorted(pooled.columns)
    for key, values in here.columns.items():
        assert values.shape == (n,)
        np.testing.assert_array_equal(pooled.columns[key], values, err_msg=key)
    assert np.isfinite(here.columns["speed_scale"]).any()


def test_the_batch_refuses_the_near_optimal_timing_and_names_the_per_query_call(paper, exec_map: RegionMap) -> None:
    batch = generate_batch(paper, np.array([0.25]), np.array([0.1]), region_map=exec_map)
    with pytest.raises(InvalidParameterError, match=r"generate_certified\(\.\.\., timing=NEAR_OPTIMAL\)"):
        execution_batch(paper, batch, NEAR_OPTIMAL, region_map=exec_map)
