"""The map's near-optimal cells: one timing per cell of a grid over the fitted range, certified for
every obstacle of the cell. Checked by executing the cell's timing for random obstacles of the cell
and sampling the motion densely with this file's own chain rule (not the pipeline's trajectory
code), against the cell's bounds and the limits; the table's files, its lookups and the online
routes that read it."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline import load_coefficients
from pipeline.certify.cell_timings import near_optimal_cells
from pipeline.certify.map_for_coefficients import with_execution_bounds
from pipeline.certify.near_optimal_cells import (
    FORMAT,
    cells_file_names,
    cells_files,
    load_near_optimal_cells,
)
from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
from pipeline.exceptions import DataFileError
from pipeline.model.arm import PlanarArm
from pipeline.model.dynamics import identify_dynamics
from pipeline.model.limits import ArmLimits
from pipeline.motion.near_optimal import NEAR_OPTIMAL, NearOptimal, NearOptimalSettings, profile_timing
from pipeline.online.batch import generate_batch
from pipeline.online.batch_execution import execution_batch
from pipeline.online.generator import generate
from pipeline.online.repair import generate_certified

GRID = 4
SETTINGS = NearOptimalSettings(pieces=50)
SAMPLES = 4001


@pytest.fixture(scope="module")
def paper():
    return load_coefficients("paper")


@pytest.fixture(scope="module")
def limits(arm: PlanarArm) -> ArmLimits:
    return ArmLimits.from_arm(arm, (5.0, 5.0)).with_servo_defaults()


@pytest.fixture(scope="module")
def cells(paper, arm: PlanarArm, limits: ArmLimits):
    return near_optimal_cells(paper, identify_dynamics(arm), limits, cells_per_axis=GRID, settings=SETTINGS)


def _motion(parameters, T: float, timing, t: np.ndarray, dynamics):
    """q, dq, ddq, jerk, tau (each (m, 2)) of the path ``parameters`` (duration T) executed with the
    timing ``timing`` of [0, T'] onto [0, T]: this file's own chain rule."""
    s, d1, d2, d3 = timing.sigma(t), timing.dsigma(t), timing.ddsigma(t), timing.dddsigma(t)
    out = [[], [], [], []]
    for a, w, phi, gamma in np.asarray(parameters, dtype=float).reshape(2, 4):
        sin, cos = np.sin(w * s + phi), np.cos(w * s + phi)
        t1, t2, t3 = a * w * cos, -a * w * w * sin, -a * w**3 * cos
        out[0].append(a * sin + gamma)
        out[1].append(t1 * d1)
        out[2].append(t2 * d1 * d1 + t1 * d2)
        out[3].append(t3 * d1**3 + 3.0 * t2 * d1 * d2 + t1 * d3)
    q, dq, ddq, jerk = (np.stack(v, 1) for v in out)
    return q, dq, ddq, jerk, dynamics.torque(q, dq, ddq)


def test_every_cell_is_certified_and_its_bounds_hold_for_random_obstacles_of_it(paper, arm, limits, cells) -> None:
    """Dense samples of the motion of 3 random obstacles per cell (and its corners) executing the
    cell's timing: no |dq|, |ddq|, |jerk|, |tau| above the cell's bound or the limit, no angle
    outside the cell's range; at rest at both ends. Fails if a bound held only for the cell's centre."""
    dynamics = identify_dynamics(arm)
    assert cells.certified.all()
    rng = np.random.default_rng(7)
    size = cells.range_size_m / GRID
    for cell in range(cells.table.size):
        corner = cells.range_lo_m + np.array(np.unravel_index(cell, cells.cells_per_axis)) * size
        points = [corner + f * size for f in ([1e-9, 1e-9], [1 - 1e-9, 1 - 1e-9], *rng.random((3, 2)))]
        certificate = cells.certificate(cell)
        for length, width in points:
            assert cells.cell_of(length, width) == cell
            trajectory = generate(paper, float(length), float(width)).trajectory
            timing = cells.timing(cell, trajectory.duration_s)
            assert timing.duration_s == cells.table["duration_s"][cell]
            t = np.concatenate([np.linspace(0.0, timing.duration_s, SAMPLES), timing.breakpoints_s])
            q, dq, ddq, jerk, tau = _motion(trajectory.parameters, trajectory.duration_s, timing, t, dynamics)
            for values, bound, limit in (
                (dq, certificate.speed_bound_rad_s, limits.velocity_rad_s),
                (ddq, certificate.acceleration_bound_rad_s2, limits.acceleration_rad_s2),
                (jerk, certificate.jerk_bound_rad_s3, limits.jerk_rad_s3),
                (tau, certificate.torque_bound_n_m, limits.effort_n_m),
            ):
                peak = np.abs(values).max(0)
                assert np.all(peak <= np.asarray(bound) * (1 + 1e-9)), (cell, length, width, peak, bound)
                assert np.all(np.asarray(bound) <= np.asarray(limit))
            for i in (0, 1):
                lo, hi = certificate.angle_range_rad[i]
                assert lo - 1e-12 <= q[:, i].min() and q[:, i].max() <= hi + 1e-12
            ends = _motion(
                trajectory.parameters, trajectory.duration_s, timing, np.array([0.0, timing.duration_s]), dynamics
            )
            assert np.all(ends[1] == 0.0) and np.all(ends[2] == 0.0)


def test_the_stored_profile_rebuilds_the_timing(cells) -> None:
    """The float32 profile and ramp widths rebuild the timing the cell's T' belongs to."""
    assert cells.table.dtype["x"].base == np.float32
    for cell in (0, 5, cells.table.size - 1):
        row = cells.table[cell]
        assert row["x"][0] == 0.0 and row["x"][-1] == 0.0 and np.all(row["x"][1:-1] > 0.0)
        assert profile_timing(row["x"], row["windows_s"]).duration_s == row["duration_s"]
        scaled = cells.timing(cell, 2.5)
        assert scaled.path_duration_s == 2.5 and math.isclose(float(scaled.sigma(scaled.duration_s)), 2.5)


@settings(max_examples=200, deadline=None)
@given(st.floats(0.19, 0.31), st.floats(0.075, 0.125))
def test_the_scalar_lookup_equals_the_vectorised_one(cells, length: float, width: float) -> None:
    """cell_of (Python floats) and cells_of (NumPy) agree inside, on faces and outside the box."""
    vectorised = int(cells.cells_of(np.array([[length, width]]))[0])
    assert cells.cell_of(length, width) == (None if vectorised < 0 else vectorised)


def test_cells_are_in_c_order_and_the_box_top_belongs_to_the_last(cells) -> None:
    lo, size = cells.range_lo_m, cells.range_size_m
    assert cells.cell_of(*(lo + size / GRID * (1 + 1e-6))) == GRID + 1
    assert cells.cell_of(lo[0] + size[0] / GRID * 1.5, lo[1] + size[1] / GRID * 0.5) == GRID
    assert cells.cell_of(*(lo + size)) == cells.table.size - 1
    assert cells.cell_of(*(lo - 1e-9)) is None


def test_the_files_are_deterministic_round_trip_and_refuse_tampering(paper, arm, limits, cells, tmp_path) -> None:
    again = near_optimal_cells(paper, identify_dynamics(arm), limits, cells_per_axis=GRID, settings=SETTINGS)
    files = cells_files(cells)
    assert files == cells_files(again)
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
    table_name, header_name = cells_file_names()
    read = load_near_optimal_cells(tmp_path / header_name)
    assert read.table.tobytes() == cells.table.tobytes()
    assert read.limits == cells.limits and read.dynamics == cells.dynamics and read.axes == ("L", "W")
    data = bytearray(files[table_name])
    data[-3] ^= 1
    (tmp_path / table_name).write_bytes(bytes(data))
    with pytest.raises(DataFileError, match="sha256"):
        load_near_optimal_cells(tmp_path / header_name)
    header = json.loads(files[header_name])
    header["format"] = "twolink-near-optimal-cells/0"
    (tmp_path / header_name).write_text(json.dumps(header))
    with pytest.raises(DataFileError, match=FORMAT):
        load_near_optimal_cells(tmp_path / header_name)


def test_only_some_cells_are_the_same_rows_as_all(paper, arm, limits, cells) -> None:
    some = near_optimal_cells(
        paper, identify_dynamics(arm), limits, cells_per_axis=GRID, settings=SETTINGS, only=np.array([3, 9])
    )
    assert np.array_equal(some.table[[3, 9]], cells.table[[3, 9]])
    assert np.isnan(np.delete(some.table["duration_s"], [3, 9])).all()


@pytest.fixture(scope="module")
def cell_map(paper, arm, limits, cells):
    coarse = certify_range(paper, RangeCertificateConfig(min_cell=1 / 16, boundary_cell=1 / 8))
    with_bounds = with_execution_bounds(coarse, paper, identify_dynamics(arm), ArmLimits.from_arm(arm, (5.0, 5.0)))
    return dataclasses.replace(with_bounds, near_optimal_cells=cells)


def test_the_online_routes_read_the_cell(paper, arm, limits, cells, cell_map) -> None:
    """generate_certified(..., NEAR_OPTIMAL) and execution_batch(..., NEAR_OPTIMAL) answer from the
    cell (its T' and bounds); from_map=False and other limits go per query."""
    user = ArmLimits.from_arm(arm, (5.0, 5.0))
    answer = generate_certified(paper, 0.25, 0.09, arm, region_map=cell_map, timing=NEAR_OPTIMAL, limits=user)
    cell = cells.cell_of(0.25, 0.09)
    assert answer.execution_source == "range"
    assert answer.duration_s == cells.table["duration_s"][cell]
    np.testing.assert_array_equal(answer.execution.certificate.jerk_bound_rad_s3, cells.table["bounds"][cell, 10:])
    assert answer.execution.limits == limits
    per_query = generate_certified(
        paper, 0.25, 0.09, arm, region_map=cell_map, timing=NearOptimal(from_map=False), limits=user
    )
    assert per_query.execution_source == "query"
    assert answer.duration_s == pytest.approx(per_query.duration_s, rel=0.15)  # a coarse 4 x 4 grid
    other = dataclasses.replace(user, acceleration_rad_s2=(4.0, 4.0))
    assert (
        generate_certified(
            paper, 0.25, 0.09, arm, region_map=cell_map, timing=NEAR_OPTIMAL, limits=other
        ).execution_source
        == "query"
    )
    lengths, widths = np.array([0.25, 0.21, 0.5]), np.array([0.09, 0.11, 0.1])
    batch = generate_batch(paper, lengths, widths, region_map=cell_map)
    result = execution_batch(paper, batch, NEAR_OPTIMAL, region_map=cell_map)
    assert result.duration_s[0] == answer.duration_s and np.isnan(result.duration_s[2])
    assert result.within_limits.tolist() == [True, True, False]
    np.testing.assert_array_equal(result.jerk_bound_rad_s3[1], cells.table["bounds"][cells.cell_of(0.21, 0.11), 10:])


@pytest.mark.parametrize("axes", ["x", "xd"])
def test_cells_over_more_axes_hold_for_moved_obstacles(paper, arm, limits, over_x, over_xd, axes) -> None:
    """Over (L, W, x) and (L, W, x, d) the grid takes every axis the coefficients vary; each cell's
    bounds hold for random obstacles of the cell, moved and (for d) raised, dense samples against
    the cell's bounds (this file's own chain rule)."""
    coefficients = over_x(paper) if axes == "x" else over_xd(paper)
    dynamics = identify_dynamics(arm)
    cells = near_optimal_cells(coefficients, dynamics, limits, cells_per_axis=2, settings=SETTINGS)
    assert cells.axes == ("L", "W", *axes) and cells.table.size == 2 ** len(cells.axes)
    rng = np.random.default_rng(11)
    checked = 0
    for _ in range(12):
        point = cells.range_lo_m + rng.random(len(cells.axes)) * cells.range_size_m
        cell = cells.cell_of(*point)
        if cell is None:
            continue
        values = dict(zip(cells.axes[2:], (float(v) for v in point[2:]), strict=True))
        trajectory = generate(coefficients, float(point[0]), float(point[1]), **values).trajectory
        timing = cells.timing(cell, trajectory.duration_s)
        t = np.concatenate([np.linspace(0.0, timing.duration_s, SAMPLES), timing.breakpoints_s])
        _, dq, ddq, jerk, tau = _motion(trajectory.parameters, trajectory.duration_s, timing, t, dynamics)
        certificate = cells.certificate(cell)
        for values_, bound in (
            (dq, certificate.speed_bound_rad_s),
            (ddq, certificate.acceleration_bound_rad_s2),
            (jerk, certificate.jerk_bound_rad_s3),
            (tau, certificate.torque_bound_n_m),
        ):
            assert np.all(np.abs(values_).max(0) <= np.asarray(bound) * (1 + 1e-9)), (point, bound)
        checked += 1
    assert checked >= 6
