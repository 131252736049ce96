"""The sweep's sampled checks (verify.acceptance.sampling): the vectorised states are the
pipeline's, the coarse grids resolve the peaks well inside the rooms that let them decide, and a
certified bound above every coarse sample but below the true peak is still caught (by the
refinement), for both timings and against a region map's torque bound."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import pipeline.motion.execution_certificate as execution_certificate
from pipeline import load_coefficients
from pipeline.model.arm import PlanarArm
from pipeline.model.limits import ArmLimits
from pipeline.motion.rest_to_rest import shortest_rest_to_rest
from pipeline.motion.timed_trajectory import TimedTrajectory
from pipeline.motion.timing import PAPER_TIMING, RestToRestTiming
from pipeline.online.execution import dynamics_of
from pipeline.online.generator import generate
from verify.acceptance.cases import SweepRange, sample_cases
from verify.acceptance.metrics import MeasureSettings, joint_checks, measure_trajectory
from verify.acceptance.sampling import (
    PAPER_GRID,
    PAPER_ROOM,
    REST_TO_REST_GRID,
    REST_TO_REST_ROOM,
    path_samples,
    piecewise_grid,
    refined_maxima,
    sinusoid_states,
    timed_states,
    timing_derivatives,
    uniform_grid,
)

PAPER_RANGE = SweepRange((0.2, 0.3), (0.08, 0.12))


@pytest.fixture(scope="module")
def generated() -> list:
    coefficients = load_coefficients("paper")
    return [generate(coefficients, length, width) for length, width in sample_cases(PAPER_RANGE, 24, 5)]


def _parameters(answers: list) -> np.ndarray:
    return np.array([a.trajectory.parameters for a in answers])


def _durations(answers: list) -> np.ndarray:
    return np.array([a.trajectory.duration_s for a in answers])


def _paper_torque(answers: list, arm: PlanarArm):
    parameters, dynamics = _parameters(answers), dynamics_of(arm)

    def evaluate(rows: np.ndarray, t: np.ndarray) -> np.ndarray:
        return np.abs(dynamics.torque(*sinusoid_states(parameters[rows], t)))

    return evaluate


def _rest_to_rest(answers: list, arm: PlanarArm):
    dynamics = dynamics_of(arm)
    timings = [shortest_rest_to_rest(a.trajectory, dynamics, ArmLimits.from_arm(arm)) for a in answers]
    parameters = _parameters(answers)

    def evaluate(rows: np.ndarray, tau: np.ndarray) -> np.ndarray:
        q, dq, ddq = timed_states(parameters[rows], [timings[r] for r in rows], tau)
        return np.concatenate([np.abs(dq), np.abs(ddq), np.abs(dynamics.torque(q, dq, ddq))], axis=-1)

    durations = np.array([t.duration_s for t in timings])
    ramps = np.array([t.ramp_s for t in timings])
    return evaluate, durations, ramps, timings


# --------------------------------------------------------------------------------------------


def test_the_vectorised_states_are_the_pipelines(generated: list, arm: PlanarArm) -> None:
    dynamics, limits = dynamics_of(arm), ArmLimits.from_arm(arm)
    answers = generated[:5]
    t = uniform_grid(_durations(answers), 37)
    q, dq, ddq = sinusoid_states(_parameters(answers), t)
    timings = [shortest_rest_to_rest(a.trajectory, dynamics, limits) for a in answers]
    tau = piecewise_grid(np.array([x.duration_s for x in timings]), np.array([x.ramp_s for x in timings]), 7, 19)
    states = timed_states(_parameters(answers), timings, tau)
    for k, answer in enumerate(answers):
        trajectory = answer.trajectory
        assert np.array_equal(q[k], trajectory.q(t[k])) and np.array_equal(dq[k], trajectory.dq(t[k]))
        assert np.array_equal(ddq[k], trajectory.ddq(t[k]))
        for mine, theirs in zip(states, TimedTrajectory(trajectory, timings[k]).states(tau[k]), strict=True):
            assert np.allclose(mine[k], theirs, rtol=1e-13, atol=1e-13)
    # Another timing goes through its own methods, row by row.
    paper = [PAPER_TIMING.for_path(a.trajectory.duration_s) for a in answers]
    sigma, d1, d2 = timing_derivatives(paper, t)
    assert np.array_equal(sigma, t) and np.all(d1 == 1.0) and np.all(d2 == 0.0)
    assert all(type(x) is RestToRestTiming for x in timings)


def test_the_path_samples_are_the_paths(generated: list) -> None:
    paths = [a.path for a in generated[:4]]
    counts = [2, 7, 65, 340]
    times, points, valid = path_samples(paths, counts)
    assert times.shape == (4, 340) and valid.sum(1).tolist() == counts
    for k, (path, m) in enumerate(zip(paths, counts, strict=True)):
        t, xy = path.uniform_samples(m)
        assert np.allclose(times[k, :m], t, rtol=0, atol=1e-12) and np.allclose(points[k, :m], xy, rtol=0, atol=1e-12)


def test_the_coarse_grids_resolve_the_peaks_well_inside_the_rooms(generated: list, arm: PlanarArm) -> None:
    """The rooms that let a coarse grid decide are at least three times the most any refinement
    lifts a coarse maximum on these cases, and the refined maxima come as close to a very dense
    grid's as the former dense checks did (2001 uniform instants; 41 per ramp and 321 in the middle)."""
    coarse, fine = PAPER_GRID
    evaluate = _paper_torque(generated, arm)
    rows, durations = np.arange(len(generated)), _durations(generated)
    grid = uniform_grid(durations, coarse)
    low = evaluate(rows, grid).max(1)
    refined, _, evaluated = refined_maxima(evaluate, grid, fine)
    dense = evaluate(rows, uniform_grid(durations, 20001)).max(1)
    former = evaluate(rows, uniform_grid(durations, 2001)).max(1)
    assert np.all(refined >= low) and np.all(evaluated > coarse)
    assert np.all(refined - low <= PAPER_ROOM / 3 * refined)
    assert np.max((dense - refined) / dense) <= np.max((dense - former) / dense)

    ramp, middle, fine = REST_TO_REST_GRID
    evaluate, durations, ramps, _ = _rest_to_rest(generated, arm)
    grid = piecewise_grid(durations, ramps, ramp, middle)
    low = evaluate(rows, grid).max(1)
    refined, _, _ = refined_maxima(evaluate, grid, fine)
    dense = evaluate(rows, piecewise_grid(durations, ramps, 801, 8001)).max(1)
    former = evaluate(rows, piecewise_grid(durations, ramps, 41, 321)).max(1)
    assert np.all(refined >= low)
    assert np.all(refined - low <= REST_TO_REST_ROOM / 3 * refined)
    assert np.all(np.max((dense - refined) / dense, axis=0) <= np.max((dense - former) / dense, axis=0))


def test_bounds_far_above_the_coarse_samples_decide_them(generated: list, arm: PlanarArm) -> None:
    coarse, fine = PAPER_GRID
    evaluate = _paper_torque(generated, arm)
    grid = uniform_grid(_durations(generated), coarse)
    low = evaluate(np.arange(len(generated)), grid).max(1)
    far = 2.0 * low
    maxima, _, evaluated = refined_maxima(evaluate, grid, fine, far, PAPER_ROOM)
    assert np.array_equal(maxima, low) and np.all(evaluated == coarse)
    near = far.copy()
    near[3, 1] = low[3, 1] * (1.0 + PAPER_ROOM / 2)  # one quantity of one case left undecided
    maxima, _, evaluated = refined_maxima(evaluate, grid, fine, near, PAPER_ROOM)
    assert evaluated[3] > coarse and np.all(np.delete(evaluated, 3) == coarse)
    assert maxima[3, 1] >= low[3, 1] and np.array_equal(np.delete(maxima, 3, 0), np.delete(low, 3, 0))


def _between(evaluate, grid: np.ndarray, fine: int) -> tuple[np.ndarray, np.ndarray]:
    """Per quantity of the one case of ``grid``, a value above every coarse sample and below the
    refined maximum (where the refinement lifts it: the mask)."""
    low = evaluate(np.array([0]), grid).max(1)[0]
    high = refined_maxima(evaluate, grid, fine)[0][0]
    return low + 0.5 * (high - low), high > low


def test_a_paper_torque_bound_between_the_coarse_samples_and_the_peak_is_caught(
    generated: list, arm: PlanarArm, monkeypatch
) -> None:
    """A certificate whose torque bound lies above every coarse sample but below the peak the
    refinement finds (within the former dense check's resolution of the true peak, above): the
    sampled check without its refinement would pass the case; it fails it."""
    answer = generated[0]
    evaluate = _paper_torque([answer], arm)
    grid = uniform_grid(_durations([answer]), PAPER_GRID[0])
    lying, lifted = _between(evaluate, grid, PAPER_GRID[1])
    assert lifted.any()
    certify = execution_certificate.certify_execution

    def too_low(timed, dynamics, limits=None, **kwargs):
        certificate = certify(timed, dynamics, limits, **kwargs)
        if isinstance(timed.timing, RestToRestTiming):
            return certificate
        return dataclasses.replace(certificate, torque_bound_n_m=tuple(lying))

    settings = MeasureSettings(time_samples=200)
    honest = measure_trajectory(answer.trajectory, answer.path, answer.obstacle, arm, settings)
    assert not any("below a sampled torque" in f for f in honest.failures)
    monkeypatch.setattr(execution_certificate, "certify_execution", too_low)
    result = measure_trajectory(answer.trajectory, answer.path, answer.obstacle, arm, settings)
    assert any(f.startswith("certified torque bound") and "below a sampled torque" in f for f in result.failures)


@pytest.mark.parametrize("quantity", ["speed", "torque"])  # |ddq| peaks on the coarse grid (u = 1/2 of a ramp)
def test_a_rest_to_rest_bound_between_the_coarse_samples_and_the_peak_is_caught(
    generated: list, arm: PlanarArm, monkeypatch, quantity: str
) -> None:
    ramp, middle, fine = REST_TO_REST_GRID
    columns = {"speed": slice(0, 2), "acceleration": slice(2, 4), "torque": slice(4, 6)}[quantity]
    for answer in generated:  # the first case whose coarse samples miss this quantity's peak
        evaluate, durations, ramps, _ = _rest_to_rest([answer], arm)
        lying, lifted = _between(evaluate, piecewise_grid(durations, ramps, ramp, middle), fine)
        if lifted[columns].any():
            break
    assert lifted[columns].any()
    fields = {"speed": "speed_bound_rad_s", "acceleration": "acceleration_bound_rad_s2", "torque": "torque_bound_n_m"}
    certify = execution_certificate.certify_execution

    def too_low(timed, dynamics, limits=None, **kwargs):
        certificate = certify(timed, dynamics, limits, **kwargs)
        if not isinstance(timed.timing, RestToRestTiming):
            return certificate
        honest = np.asarray(getattr(certificate, fields[quantity]), dtype=float)
        bound = np.where(lifted[columns], lying[columns], honest)
        return dataclasses.replace(certificate, **{fields[quantity]: tuple(bound)})

    monkeypatch.setattr(execution_certificate, "certify_execution", too_low)
    result = measure_trajectory(answer.trajectory, answer.path, answer.obstacle, arm, MeasureSettings(time_samples=200))
    assert any(f.startswith(f"rest-to-rest certified {quantity} bound") for f in result.failures), result.failures


def test_a_map_torque_bound_between_the_coarse_samples_and_the_peak_is_caught(generated: list, arm: PlanarArm) -> None:
    """The certified paper-timing torque bounds are loose (the coarse samples decide them); a
    region map's bound above every coarse sample but below the peak, given as the case's ceiling,
    gets the samples refined past it (so the map check flags the case); without it they are not."""
    answer = generated[2]
    evaluate = _paper_torque([answer], arm)
    grid = uniform_grid(_durations([answer]), PAPER_GRID[0])
    lying, lifted = _between(evaluate, grid, PAPER_GRID[1])
    assert lifted.any()
    (plain,) = joint_checks([answer.trajectory], arm)
    assert np.all(np.array(plain.peak_torque_sampled_n_m) <= lying)  # coarse only: the map's lie unseen
    (checked,) = joint_checks([answer.trajectory], arm, None, [tuple(lying)])
    assert np.any(np.array(checked.peak_torque_sampled_n_m) > lying)
    assert checked.torque_bound_n_m == plain.torque_bound_n_m
