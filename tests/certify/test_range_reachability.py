"""The reachability witness (pipeline.certify.reachability): its certified clearance is a lower
bound on Coal's distance along its trajectory (through Pinocchio), its endpoint errors are
within the tolerance by Pinocchio's kinematics, it never does worse than the coefficients' own
trajectory, and at (0.20, 0.12) m it agrees with the infeasibility certificate (the map
proves no trajectory keeps 1 cm with 2 mm there) while a looser tolerance reaches further."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
from pipeline.certify.reachability import best_clearance_at, witness_lines, witnesses_for_map
from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.clearance import CoalClearance
from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle
from pipeline.motion.path import desired_path
from pipeline.motion.trajectory import JointTrajectory
from pipeline.offline.coefficients import Coefficients, fit_coefficients, load_coefficients, paper_data_path
from pipeline.offline.doe import load_doe
from pipeline.offline.endpoint_regression import EndpointConstraint


@pytest.fixture(scope="module")
def eq9() -> Coefficients:
    """Table 2 fitted as the build fits (endpoint errors within 2 mm over the range); the name
    keeps the paper's origin in view."""
    doe = load_doe(paper_data_path("paper_table2_doe.json"))
    fitted, _ = fit_coefficients(doe, None, EndpointConstraint())
    return fitted


def _coal_and_ends(coefficients: Coefficients, arm: PlanarArm, witness) -> tuple[float, float]:
    """Coal's clearance at 2001 times and the larger Pinocchio endpoint error of the witness."""
    obstacle = Obstacle.in_scene(witness.length_m, witness.width_m, coefficients.scene)
    path = desired_path(obstacle, coefficients.scene)
    trajectory = JointTrajectory(witness.parameters, path.duration_s)
    coal = CoalClearance(arm, obstacle)
    q = trajectory.q(np.linspace(0.0, path.duration_s, 2001))
    sampled = min(float(coal.link_clearance(row).min()) for row in q)
    ends = arm.to_plane(
        np.array([arm.end_effector_position(row) for row in trajectory.q(np.array([0.0, path.duration_s]))])
    )
    return sampled, float(np.linalg.norm(ends - path.points_m[[0, -1]], axis=-1).max())


@pytest.mark.parametrize(("L", "W"), [(0.25, 0.10), (0.27, 0.118)])
def test_witness_is_certified_sound_and_within_the_tolerance(eq9: Coefficients, arm: PlanarArm, L, W) -> None:
    witness = best_clearance_at(eq9, arm, L, W, 0.002)
    sampled, end_error = _coal_and_ends(eq9, arm, witness)
    assert witness.clearance_m <= sampled + 1e-9
    assert end_error <= 0.002 + 1e-9
    assert max(witness.endpoint_errors_m) == pytest.approx(end_error, abs=1e-9)
    assert witness.within_tolerance
    assert witness.clearance_m >= witness.regression_clearance_m - 1e-6


def test_witness_agrees_with_the_infeasibility_certificate_near_w_012(eq9: Coefficients, arm: PlanarArm) -> None:
    """The map proves (0.20, 0.12) infeasible for 2 mm: the search stays below the margin; with
    3 mm the end pose is free enough for it to keep more than with 2 mm."""
    tight = best_clearance_at(eq9, arm, 0.20, 0.12, 0.002)
    loose = best_clearance_at(eq9, arm, 0.20, 0.12, 0.003)
    assert tight.clearance_m < 0.01
    assert loose.clearance_m > tight.clearance_m
    region_map = certify_range(eq9, RangeCertificateConfig(min_cell=1 / 32, boundary_cell=1 / 16))
    cell = region_map.cell_at(0.20, 0.12)
    assert tight.clearance_m <= cell.endpoint_clearance_upper_m


def test_witnesses_spread_over_the_cells_below_the_margin(eq9: Coefficients, arm: PlanarArm) -> None:
    region_map = certify_range(eq9, RangeCertificateConfig(min_cell=1 / 16, boundary_cell=1 / 16))
    witnesses = witnesses_for_map(eq9, region_map, arm, 3)
    assert len(witnesses) == 3
    for w in witnesses:
        assert region_map.cell_at(w.length_m, w.width_m).status in ("collision_free", "undecided")
    assert len(witness_lines(witnesses)) == 3
    assert len({w.length_m for w in witnesses}) > 1


def test_a_search_that_cannot_meet_the_tolerance_says_so(arm: PlanarArm) -> None:
    """Eq. 9 itself misses P1 or P5 by about 5 mm at (0.25, 0.10); asked for 0.1 mm, whatever the
    search ends with is flagged, not passed off as a witness."""
    witness = best_clearance_at(load_coefficients("paper"), arm, 0.25, 0.10, 1e-4)
    if not witness.within_tolerance:
        assert max(witness.endpoint_errors_m) > 1e-4
        assert "NOT within the tolerance" in witness_lines([witness])[0]
    else:
        assert max(witness.endpoint_errors_m) <= 1e-4


def test_bad_tolerance_is_refused(eq9: Coefficients, arm: PlanarArm) -> None:
    with pytest.raises(InvalidParameterError):
        best_clearance_at(eq9, arm, 0.25, 0.10, 0.0)
