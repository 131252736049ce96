"""One timing for a box of obstacles (:mod:`pipeline.motion.path_box`) against independent checks.

Boxes are cells of 1/64 of the paper's fitted range per side, their parameters enclosed by
:func:`pipeline.certify.execution_range.leaf_parameters`; each is timed by
:func:`pipeline.motion.near_optimal.near_optimal_box_timing` with tight limits (5 rad/s^2,
100 rad/s^3 per joint, the paper's speed and effort limits). Then:

* every certified bound holds for obstacles anywhere in the cell (corners, centre, random points):
  each obstacle's own path (the generator's answer) is run under the box's timing, ``T sigma``,
  and its angles, speeds, accelerations, jerks (chain rule, written here in NumPy from the stored
  cubic segments, not the pipeline's trajectory code) and torques (closed form, checked against
  Pinocchio's RNEA) are sampled at 20,001 instants and at both sides of every breakpoint. A bound
  that only covers the box's centre path, or a box enclosure missing part of the cell, fails here;
* the timing starts and ends at rest on the whole path and its acceleration is continuous;
* the stored float32 profile rebuilds the certified timing bit for bit;
* a box of one path is that path: the same enclosures and constraints as the one-path route;
* :class:`PathBox` refuses bad input;
* the box's T' stays within 3 % of the per-query near-optimal T' of its members (engineering).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

import pipeline
from pipeline.certify.execution_range import leaf_parameters
from pipeline.certify.range_model import RangeModel
from pipeline.exceptions import InvalidParameterError, TimingRefusedError
from pipeline.motion.execution_certificate import certify_execution
from pipeline.motion.near_optimal import (
    NearOptimalSettings,
    NearOptimalTiming,
    near_optimal_box_timing,
    near_optimal_timing,
    profile_timing,
)
from pipeline.motion.path_box import PathBox, TimedPathBox, normalised_parameters
from pipeline.motion.path_constraints import compiled_piece_constraints, enclose_path, piece_constraints
from pipeline.motion.trajectory import JointTrajectory

#: Cells per side of the fitted range.
CELLS_PER_AXIS = 64
#: How the box timings are built (the region map's cell settings).
BOX_SETTINGS = NearOptimalSettings(pieces=100)
#: Cells tried for the fixed cases (corners of the range, its middle, a few inside).
FIXED_CELLS = ((0, 0), (63, 63), (0, 63), (63, 0), (31, 32), (10, 20), (47, 5), (22, 58))
#: Instants of the dense sample (the breakpoints are added).
SAMPLES = 20_001
#: Relative slack of a sampled value against a certified bound (floating point of the sample).
RTOL = 1e-9


@dataclass(frozen=True)
class Setting:
    generator: object
    model: RangeModel
    dynamics: object
    limits: object


@dataclass(frozen=True)
class Cell:
    """A cell of the grid, its box, and its certified timing (None: refused)."""

    index: tuple[int, int]
    centre: np.ndarray
    half: np.ndarray
    duration_range_s: tuple[float, float]
    box: PathBox
    result: NearOptimalTiming | None
    refusal: str = ""


@pytest.fixture(scope="module")
def setting() -> Setting:
    generator = pipeline.load("paper")
    state = generator.coefficients.online_state
    limits = replace(state.limits, acceleration_rad_s2=(5.0, 5.0), jerk_rad_s3=(100.0, 100.0))
    return Setting(generator, RangeModel.from_coefficients(generator.coefficients), state.dynamics, limits)


def _cell(setting: Setting, index: tuple[int, int]) -> Cell:
    """The cell ``index`` of the grid, its box (as :mod:`pipeline.certify.near_optimal_cells` builds
    a cell's, with the generator's answer at the cell's centre as the centre path) and its timing."""
    model = setting.model
    size = model.range_size / CELLS_PER_AXIS
    centre = model.range_lo + (np.asarray(index) + 0.5) * size
    half = size / 2.0
    params, duration = leaf_parameters(model, centre[None], half[None])
    lower, upper = [p.lo[0] for p in params], [p.hi[0] for p in params]
    duration_range = (float(duration.lo[0]), float(duration.hi[0]))
    answer = setting.generator(*centre).trajectory
    box = PathBox.of_intervals(lower, upper, duration_range, answer.parameters, answer.duration_s)
    try:
        result = near_optimal_box_timing(box, setting.dynamics, setting.limits, BOX_SETTINGS)
    except TimingRefusedError as error:
        return Cell(tuple(index), centre, half, duration_range, box, None, str(error))
    return Cell(tuple(index), centre, half, duration_range, box, result)


@pytest.fixture(scope="module")
def fixed_cells(setting) -> list[Cell]:
    return [_cell(setting, index) for index in FIXED_CELLS]


@pytest.fixture(scope="module")
def certified(fixed_cells) -> list[Cell]:
    cells = [c for c in fixed_cells if c.result is not None]
    assert cells, [c.refusal for c in fixed_cells]
    return cells


def _obstacles(cell: Cell, fractions) -> np.ndarray:
    """Obstacles (L, W) of the cell at ``fractions`` (m, 2) of its sides (0: lower face, 1: upper)."""
    return cell.centre + (2.0 * np.asarray(fractions, dtype=float) - 1.0) * cell.half


def _corners_centre_random(cell: Cell, random: int) -> np.ndarray:
    rng = np.random.default_rng(1000 * cell.index[0] + cell.index[1])
    fractions = [(0.0, 0.0), (0.0, 1.0), (1.0, 0.0), (1.0, 1.0), (0.5, 0.5), *rng.uniform(0.0, 1.0, (random, 2))]
    return _obstacles(cell, fractions)


# --- the motion of one path under the box timing, written out here ------------------------------


def _segment_values(timing, j: np.ndarray, h: np.ndarray):
    """sigma, sigma', sigma'', sigma''' of the stored cubic segments ``j`` at local times ``h``."""
    c0, c1, c2 = timing.start[j, 0], timing.start[j, 1], timing.start[j, 2]
    k = timing.jerk[j]
    return (
        c0 + h * c1 + h**2 * c2 / 2.0 + h**3 * k / 6.0,
        c1 + h * c2 + h**2 * k / 2.0,
        c2 + h * k,
        k,
    )


def _dense_timing(timing):
    """sigma and its derivatives at :data:`SAMPLES` instants of [0, T'] and on both sides of every
    breakpoint (the one-sided values exactly: the segment before it at its end, the one after it
    at its start)."""
    knots = timing.breakpoints_s
    m = timing.jerk.size
    tau = np.linspace(0.0, timing.duration_s, SAMPLES)
    j = np.clip(np.searchsorted(knots, tau, side="right") - 1, 0, m - 1)
    j = np.concatenate([j, np.arange(m), np.arange(m)])
    h = np.concatenate([tau - knots[j[:SAMPLES]], np.zeros(m), np.diff(knots)])
    return _segment_values(timing, j, h)


def _member_motion(parameters, duration_s: float, sigma) -> dict[str, np.ndarray]:
    """q, dq, ddq and the jerk of the path ``theta_i(s) = A_i sin(w_i s + phi_i) + gamma_i`` executed
    as s = T sigma(tau) (chain rule), from sigma's values ``sigma`` (4 arrays, sigma in [0, 1])."""
    p = np.asarray(parameters, dtype=float)
    A, w, phi, gamma = p[[0, 4]], p[[1, 5]], p[[2, 6]], p[[3, 7]]
    s, ds, dds, ddds = (duration_s * v[:, None] for v in np.broadcast_arrays(*sigma))
    phase = w * s + phi
    sin, cos = np.sin(phase), np.cos(phase)
    d1, d2, d3 = A * w * cos, -A * w**2 * sin, -A * w**3 * cos
    return {
        "q": A * sin + gamma,
        "dq": d1 * ds,
        "ddq": d2 * ds**2 + d1 * dds,
        "jerk": d3 * ds**3 + 3.0 * d2 * ds * dds + d1 * ddds,
    }


def _check_member(cell: Cell, setting: Setting, arm, obstacle, sigma) -> None:
    """Runs the obstacle's own path under the cell's timing and checks every certified bound."""
    answer = setting.generator(*obstacle).trajectory
    lower, upper = cell.box.lower, cell.box.upper
    normalised = normalised_parameters(answer.parameters, answer.duration_s)
    where = f"cell {cell.index}, obstacle (L, W) = {tuple(float(v) for v in obstacle)}"
    # The premise: the obstacle's path is a path of the box (else the bounds need not cover it).
    assert np.all((lower <= normalised) & (normalised <= upper)), (where, lower, normalised, upper)
    assert cell.duration_range_s[0] <= answer.duration_s <= cell.duration_range_s[1], (where, answer.duration_s)
    motion = _member_motion(answer.parameters, answer.duration_s, sigma)
    motion["tau"] = setting.dynamics.torque(motion["q"], motion["dq"], motion["ddq"])
    data = arm.model.createData()
    every = slice(None, None, 97)
    rnea = np.array(
        [
            pin.rnea(arm.model, data, *x)
            for x in zip(motion["q"][every], motion["dq"][every], motion["ddq"][every], strict=True)
        ]
    )
    np.testing.assert_allclose(motion["tau"][every], rnea, rtol=0, atol=1e-9, err_msg=where)
    certificate, limits = cell.result.certificate, setting.limits
    for key, bound, limit in (
        ("dq", certificate.speed_bound_rad_s, limits.velocity_rad_s),
        ("ddq", certificate.acceleration_bound_rad_s2, limits.acceleration_rad_s2),
        ("jerk", certificate.jerk_bound_rad_s3, limits.jerk_rad_s3),
        ("tau", certificate.torque_bound_n_m, limits.effort_n_m),
    ):
        peak = np.abs(motion[key]).max(0)
        assert np.all(peak <= np.asarray(bound) * (1.0 + RTOL)), f"{where}: {key} sampled {peak} > bound {bound}"
        assert np.all(peak <= np.asarray(limit)), f"{where}: {key} sampled {peak} > limit {limit}"
    q = motion["q"]
    for i, ((lo, hi), (limit_lo, limit_hi)) in enumerate(
        zip(certificate.angle_range_rad, limits.position_rad, strict=True)
    ):
        assert lo <= q[:, i].min() and q[:, i].max() <= hi, (where, i, (q[:, i].min(), q[:, i].max()), (lo, hi))
        assert limit_lo <= q[:, i].min() and q[:, i].max() <= limit_hi, (where, i)


def _check_certificate(cell: Cell, setting: Setting) -> None:
    result = cell.result
    assert isinstance(result.executed, TimedPathBox)
    assert result.executed.box is cell.box
    assert not result.certificate.violations(setting.limits)
    assert result.certificate.duration_s == result.executed.duration_s
    assert result.executed.timing.path_duration_s == 1.0


# --- 1. soundness -----------------------------------------------------------------------------------


def test_most_cells_tried_are_certified(fixed_cells) -> None:
    """The paper's coefficients give a certified box timing for most cells (the other tests use those)."""
    refused = {c.index: c.refusal for c in fixed_cells if c.result is None}
    assert len(refused) <= len(fixed_cells) // 4, refused


def test_box_bounds_hold_for_every_obstacle_of_the_cell(arm, setting, certified) -> None:
    """Each obstacle of the cell (its corners, centre and random points) runs its own path under
    the box's timing; every sampled |dq|, |ddq|, |jerk|, |tau| and angle lies within the box's
    certified bounds and the limits. Fails if a bound covered only the centre path, if the box's
    enclosures missed part of the cell, or if the certificate's interval arithmetic were unsound."""
    for cell in certified:
        _check_certificate(cell, setting)
        sigma = _dense_timing(cell.result.executed.timing)
        for obstacle in _corners_centre_random(cell, random=6):
            _check_member(cell, setting, arm, obstacle, sigma)


def test_tight_box_bounds_hold_for_every_obstacle_of_the_cell(arm, setting, certified) -> None:
    """certify_execution of the TimedPathBox without limits (tight bounds, bisected against the
    centre's samples) still bounds every obstacle of the cell, not only the centre path."""
    for cell in certified[:3]:
        tight = certify_execution(cell.result.executed, setting.dynamics, None)
        tight_cell = replace(cell, result=replace(cell.result, certificate=tight))
        sigma = _dense_timing(cell.result.executed.timing)
        for obstacle in _corners_centre_random(cell, random=3):
            _check_member(tight_cell, setting, arm, obstacle, sigma)


@settings(max_examples=10, deadline=None)
@given(
    index=st.tuples(st.integers(0, CELLS_PER_AXIS - 1), st.integers(0, CELLS_PER_AXIS - 1)),
    fractions=st.lists(st.tuples(st.floats(0.0, 1.0), st.floats(0.0, 1.0)), min_size=3, max_size=3),
)
def test_box_bounds_hold_for_obstacles_of_a_drawn_cell(arm, setting, index, fractions) -> None:
    """As above, for a drawn cell and drawn obstacles in it."""
    cell = _cell(setting, index)
    assume(cell.result is not None)
    _check_certificate(cell, setting)
    sigma = _dense_timing(cell.result.executed.timing)
    for obstacle in _obstacles(cell, fractions):
        _check_member(cell, setting, arm, obstacle, sigma)


def test_the_box_centre_motion_is_the_centre_path_under_the_timing(certified) -> None:
    """TimedPathBox.states and .jerk are the centre path (normalised, T = 1) under the timing,
    as the chain rule written here gives them."""
    for cell in certified:
        executed = cell.result.executed
        tau = np.linspace(0.0, executed.duration_s, 2001)[:-1]
        timing = executed.timing
        j = np.clip(np.searchsorted(timing.breakpoints_s, tau, side="right") - 1, 0, timing.jerk.size - 1)
        ours = _member_motion(
            cell.box.centre.parameters, 1.0, _segment_values(timing, j, tau - timing.breakpoints_s[j])
        )
        q, dq, ddq = executed.states(tau)
        for key, theirs in (("q", q), ("dq", dq), ("ddq", ddq), ("jerk", executed.jerk(tau))):
            np.testing.assert_allclose(theirs, ours[key], rtol=1e-12, atol=1e-12, err_msg=f"{cell.index} {key}")


# --- 2. and 3. rest at both ends, continuous acceleration ------------------------------------------


def test_at_rest_at_both_ends_over_the_whole_path(certified) -> None:
    """sigma' = sigma'' = 0 at 0 and T' (the timing's values, and the last segment's own cubic at its
    end, which the timing does not clamp), sigma(0) = 0 and sigma(T') = 1: every path of the box
    is run whole, from rest to rest."""
    for cell in certified:
        timing = cell.result.executed.timing
        ends = np.array([0.0, timing.duration_s])
        assert np.all(timing.dsigma(ends) == 0.0) and np.all(timing.ddsigma(ends) == 0.0), cell.index
        assert timing.sigma(0.0) == 0.0 and abs(timing.sigma(timing.duration_s) - 1.0) <= 1e-12, cell.index
        last = timing.jerk.size - 1
        end = _segment_values(timing, np.array([last]), np.array([timing.breakpoints_s[-1] - timing.breakpoints_s[-2]]))
        start = _segment_values(timing, np.array([0]), np.array([0.0]))
        assert abs(end[0][0] - 1.0) <= 1e-12 and abs(end[1][0]) <= 1e-12 and abs(end[2][0]) <= 1e-12, (cell.index, end)
        assert start[0][0] == 0.0 and start[1][0] == 0.0 and start[2][0] == 0.0, (cell.index, start)
        q, dq, ddq = cell.result.executed.states(ends)
        assert np.all(dq == 0.0) and np.all(ddq == 0.0), cell.index
        np.testing.assert_allclose(q, cell.box.centre.q(np.array([0.0, 1.0])), rtol=0, atol=1e-12)


def test_acceleration_is_continuous_at_every_breakpoint(certified) -> None:
    """Just left and right of each breakpoint (1e-12 s apart) sigma'' differs by at most
    max |sigma'''| times the gap, and the centre's joint accelerations by at most the certified
    jerk bound times the gap; each stored segment ends where the next one starts (sigma, sigma',
    sigma''). A step in acceleration left at a breakpoint (an unsmoothed profile) fails."""
    gap = 1e-12
    for cell in certified:
        executed = cell.result.executed
        timing = executed.timing
        knots = timing.breakpoints_s[1:-1]
        left, right = knots - gap / 2.0, knots + gap / 2.0
        jump = np.abs(timing.ddsigma(right) - timing.ddsigma(left))
        allowed = 2.0 * np.abs(timing.jerk).max() * gap + 1e-13
        assert jump.max() <= allowed, (cell.index, jump.max(), allowed)
        joint_jump = np.abs(executed.states(right)[2] - executed.states(left)[2]).max(0)
        joint_allowed = 2.0 * cell.result.certificate.jerk_bound_rad_s3 * gap + 1e-12
        assert np.all(joint_jump <= joint_allowed), (cell.index, joint_jump, joint_allowed)
        j = np.arange(timing.jerk.size - 1)
        ends = _segment_values(timing, j, np.diff(timing.breakpoints_s)[:-1])
        for k in range(3):
            mismatch = np.abs(ends[k] - timing.start[1:, k]).max()
            assert mismatch <= 1e-12, (cell.index, k, mismatch)


# --- 4. the stored profile -----------------------------------------------------------------------------


def test_the_stored_profile_rebuilds_the_certified_timing_bit_for_bit(certified) -> None:
    """profile_timing(x, windows) is the certified timing float for float; the profile is float32,
    at rest at both ends (x[0] = x[-1] = 0), moving in between, with positive ramp widths."""
    for cell in certified:
        x, windows = cell.result.profile
        assert x.dtype == np.float32 and windows.dtype == np.float32, cell.index
        assert x.shape == windows.shape == (BOX_SETTINGS.pieces + 1,), cell.index
        assert x[0] == 0.0 and x[-1] == 0.0 and np.all(x[1:-1] > 0.0), cell.index
        assert np.all(windows > 0.0), cell.index
        rebuilt, certified_timing = profile_timing(x, windows), cell.result.executed.timing
        for name in ("breakpoints_s", "start", "jerk"):
            assert np.array_equal(getattr(rebuilt, name), getattr(certified_timing, name)), (cell.index, name)
        assert rebuilt.duration_s == cell.result.executed.duration_s


# --- 5. a box of one path ----------------------------------------------------------------------------------


def test_a_box_of_one_path_is_that_path(setting) -> None:
    """lower = upper = one path's normalised parameters: the box's enclosures equal the one path's,
    the box's piece constraints equal the compiled one-path route's, and its timing's T' that of
    the one-path near-optimal timing (on the normalised and on the original path) to float32 rounding."""
    answer = setting.generator(0.27, 0.09).trajectory
    p = normalised_parameters(answer.parameters, answer.duration_s)
    edges = np.linspace(0.0, 1.0, BOX_SETTINGS.pieces + 1)
    box_route = enclose_path((p.copy(), p.copy()), edges, setting.dynamics)
    one_route = enclose_path(p, edges, setting.dynamics)
    for name in ("d1", "d2", "d3", "accel_u", "accel_x", "torque_u", "torque_x"):
        for a, b in zip(getattr(box_route, name), getattr(one_route, name), strict=True):
            assert np.array_equal(a, b), name
    rows = piece_constraints(box_route, setting.limits, 0.98, 0.99)
    compiled, _ = compiled_piece_constraints(p, edges, setting.dynamics, setting.limits, 0.98, 0.99)
    for name in ("cu", "cx", "rhs", "speed_cap"):
        assert np.array_equal(getattr(rows, name), getattr(compiled, name)), name
    normalised = JointTrajectory(tuple(p), 1.0)
    box = PathBox(p, p, normalised)
    durations = [
        near_optimal_box_timing(box, setting.dynamics, setting.limits, BOX_SETTINGS).executed.duration_s,
        near_optimal_timing(normalised, setting.dynamics, setting.limits, BOX_SETTINGS).executed.duration_s,
        near_optimal_timing(answer, setting.dynamics, setting.limits, BOX_SETTINGS).executed.duration_s,
    ]
    assert max(durations) <= min(durations) * (1.0 + 1e-6), durations


# --- 6. bad input -----------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def valid(setting):
    """A valid box's (lower, upper, centre) around one path, and the path (parameters, T)."""
    answer = setting.generator(0.25, 0.1).trajectory
    p = normalised_parameters(answer.parameters, answer.duration_s)
    return p - 1e-3, p + 1e-3, JointTrajectory(tuple(p), 1.0), (np.array(answer.parameters), answer.duration_s)


def test_a_valid_box_is_accepted(valid) -> None:
    lower, upper, centre, (p, T) = valid
    box = PathBox(lower, upper, centre)
    assert np.array_equal(box.lower, lower) and np.array_equal(box.upper, upper)
    box = PathBox.of_intervals(p - 1e-3, p + 1e-3, (T - 1e-3, T + 1e-3), p, T)
    assert np.all(box.lower <= normalised_parameters(p, T)) and np.all(normalised_parameters(p, T) <= box.upper)


@pytest.mark.parametrize("slot", range(8))
def test_lower_above_upper_is_refused(valid, slot) -> None:
    lower, upper, centre, _ = valid
    lower, upper = lower.copy(), upper.copy()
    lower[slot], upper[slot] = upper[slot], lower[slot]
    with pytest.raises(InvalidParameterError):
        PathBox(lower, upper, centre)


@pytest.mark.parametrize("slot", [0, 2, 3, 4, 6, 7])
def test_of_intervals_refuses_lower_above_upper(valid, slot) -> None:
    _, _, _, (p, T) = valid
    lower, upper = p - 1e-3, p + 1e-3
    lower[slot], upper[slot] = upper[slot], lower[slot]
    with pytest.raises(InvalidParameterError):
        PathBox.of_intervals(lower, upper, (T - 1e-3, T + 1e-3), p, T)


@pytest.mark.parametrize("inverted", ["w", "T"])
def test_of_intervals_refuses_an_inverted_frequency_or_duration(valid, inverted) -> None:
    _, _, _, (p, T) = valid
    lower, upper, durations = p - 1e-3, p + 1e-3, (T - 1e-3, T + 1e-3)
    if inverted == "w":
        lower[1], upper[1] = upper[1], lower[1]
    else:
        durations = durations[::-1]
    with pytest.raises(InvalidParameterError):
        PathBox.of_intervals(lower, upper, durations, p, T)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("side", ["lower", "upper"])
def test_a_non_finite_bound_is_refused(valid, bad, side) -> None:
    lower, upper, centre, (p, T) = valid
    bounds = {"lower": lower.copy(), "upper": upper.copy()}
    bounds[side][5] = bad
    with pytest.raises(InvalidParameterError):
        PathBox(bounds["lower"], bounds["upper"], centre)
    with pytest.raises(InvalidParameterError):
        PathBox.of_intervals(p - 1e-3, p + 1e-3, (T - 1e-3, bad) if side == "upper" else (bad, T + 1e-3), p, T)


def test_a_centre_outside_the_box_or_not_normalised_is_refused(valid) -> None:
    lower, upper, centre, (p, T) = valid
    for slot in range(8):
        for edge, step in ((upper, 1e-6), (lower, -1e-6)):
            outside = np.array(centre.parameters)
            outside[slot] = edge[slot] + step
            with pytest.raises(InvalidParameterError):
                PathBox(lower, upper, JointTrajectory(tuple(outside), 1.0))
    with pytest.raises(InvalidParameterError):  # the right parameters, not normalised (T != 1)
        PathBox(lower, upper, JointTrajectory(centre.parameters, 2.0))
    with pytest.raises(InvalidParameterError):  # of_intervals: a centre whose T is outside the durations
        PathBox.of_intervals(p - 1e-3, p + 1e-3, (T - 1e-3, T + 1e-3), p, T + 0.5)


@pytest.mark.parametrize(
    "shape", [(7,), (9,), (8, 1), (1, 8), (2, 8), ()], ids=lambda s: "x".join(map(str, s)) or "scalar"
)
def test_wrong_shapes_are_refused(valid, shape) -> None:
    lower, upper, centre, _ = valid
    with pytest.raises(InvalidParameterError):
        PathBox(np.resize(lower, shape), np.resize(upper, shape), centre)
    with pytest.raises(InvalidParameterError):
        PathBox(np.resize(lower, shape), upper, centre)


# --- 7. close to the per-query timing (engineering) ----------------------------------------------------


def test_box_duration_is_within_three_percent_of_each_members_own(setting, certified) -> None:
    """Not a theorem (the box's worst-case constraints and the per-query ones differ both ways):
    over a 1/64 cell the box's T' is within 3 % of each member's own near-optimal T'."""
    ratios = {}
    for cell in certified[:4]:
        for obstacle in _corners_centre_random(cell, random=2):
            member = setting.generator(*obstacle).trajectory
            own = near_optimal_timing(member, setting.dynamics, setting.limits, NearOptimalSettings())
            ratios[(cell.index, tuple(round(float(v), 6) for v in obstacle))] = (
                cell.result.executed.duration_s / own.executed.duration_s
            )
    values = np.array(list(ratios.values()))
    assert np.all(np.abs(values - 1.0) <= 0.03), ratios
