"""``g.near_optimal(L, W)``: the certified near-optimal answer read off the map, at lookup cost.
Checked against the per-query route on the same map (the same T', bounds and motion), for its
refusals, and for what it must not load."""

from __future__ import annotations

import dataclasses
import subprocess
import sys

import numpy as np
import pytest

from pipeline import NEAR_OPTIMAL, load_coefficients
from pipeline.certify.cell_timings import near_optimal_cells
from pipeline.certify.map_for_coefficients import with_execution_bounds
from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
from pipeline.exceptions import ExecutionRefusedError, InvalidParameterError
from pipeline.model.arm import PlanarArm
from pipeline.model.dynamics import identify_dynamics
from pipeline.model.limits import ArmLimits
from pipeline.motion.near_optimal import NearOptimalSettings
from pipeline.online.map_timing import near_optimal_from_map
from pipeline.online.online_generator import OnlineGenerator
from pipeline.online.repair import generate_certified


@pytest.fixture(scope="module")
def mapped(arm: PlanarArm):
    """The paper's coefficients with a coarse map and 4 x 4 near-optimal cells for the URDF limits."""
    paper = load_coefficients("paper", region_map=None)
    limits = ArmLimits.from_arm(arm)
    coarse = certify_range(paper, RangeCertificateConfig(min_cell=1 / 16, boundary_cell=1 / 8))
    region_map = with_execution_bounds(coarse, paper, identify_dynamics(arm), limits)
    cells = near_optimal_cells(
        paper, identify_dynamics(arm), limits.with_servo_defaults(), cells_per_axis=4, settings=NearOptimalSettings()
    )
    return dataclasses.replace(paper, region_map=dataclasses.replace(region_map, near_optimal_cells=cells)), cells


def test_the_answer_is_the_per_query_routes_answer_from_the_map(mapped, arm) -> None:
    coefficients, cells = mapped
    g = OnlineGenerator(coefficients)
    for length, width in ((0.25, 0.09), (0.21, 0.085), (0.29, 0.1)):
        answer = g.near_optimal(length, width)
        full = generate_certified(coefficients, length, width, arm, timing=NEAR_OPTIMAL)
        assert full.execution_source == "range"
        assert answer.duration_s == full.duration_s == cells.table["duration_s"][answer.cell]
        np.testing.assert_array_equal(answer.certificate.torque_bound_n_m, full.execution.certificate.torque_bound_n_m)
        np.testing.assert_array_equal(
            answer.certificate.jerk_bound_rad_s3, full.execution.certificate.jerk_bound_rad_s3
        )
        t = np.linspace(0.0, answer.duration_s, 501)
        for a, b in zip(answer.executed.states(t), full.executed.states(t), strict=True):
            np.testing.assert_array_equal(a, b)
        assert answer.certified_clearance_m >= coefficients.scene.margin_m
        assert answer.endpoint_error_bound_m <= 0.01


def test_what_the_map_does_not_decide_is_refused_naming_the_per_query_call(mapped) -> None:
    coefficients, _ = mapped
    with pytest.raises(ExecutionRefusedError, match=r"outside the map's range; generate_certified\(\.\.\., timing"):
        near_optimal_from_map(coefficients, 0.35, 0.1, out_of_range="ignore")
    bare = load_coefficients("paper", region_map=None)
    with pytest.raises(InvalidParameterError, match="near-optimal cells"):
        near_optimal_from_map(bare, 0.25, 0.09)
    with pytest.raises(InvalidParameterError):
        near_optimal_from_map(coefficients, float("nan"), 0.09)


def test_the_map_route_loads_neither_pinocchio_nor_coal(tmp_path) -> None:
    """The module's route is NumPy only: importing it and the generator leaves both out."""
    code = (
        "import sys, pipeline.online.map_timing, pipeline.online.online_generator\n"
        "print('pinocchio' in sys.modules, 'coal' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=tmp_path)
    assert out.stdout.split() == ["False", "False"]
