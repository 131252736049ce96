"""The objective and one DOE experiment with the obstacle off the y axis (pipeline.offline.fitness,
pipeline.offline.experiment): the problem's obstacle, targets and clearance follow the centre x,
and the exact-endpoints optimum ends exactly on the moved P1 and P5."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pipeline.geometry.clearance import ANALYTIC, COAL
from pipeline.model.arm import PlanarArm
from pipeline.model.scene import Scene
from pipeline.motion.families import EXACT_ENDPOINTS, PAPER
from pipeline.motion.trajectory import PARAMETER_NAMES, joint_angles
from pipeline.offline.experiment import SolverConfig, solve_experiment
from pipeline.offline.fitness import FitnessConfig, fitness_problem

SMALL = {"n_points": 21, "clearance_samples": 41}
# Near the exact-endpoints optimum (w1, phi1, A2, w2) for L = 0.25, W = 0.10.
NEAR_EXACT = np.array([0.969, 0.471, 2.08, 0.712])


@pytest.mark.parametrize("centre", [-0.04, 0.03])
def test_problem_follows_the_centre(arm: PlanarArm, centre: float) -> None:
    centred = fitness_problem(arm, 0.25, 0.10, Scene(), FitnessConfig(**SMALL), EXACT_ENDPOINTS)
    moved = fitness_problem(arm, 0.25, 0.10, Scene(centre_x_m=centre), FitnessConfig(**SMALL), EXACT_ENDPOINTS)
    assert moved.obstacle.centre_x_m == centre
    assert_allclose(moved.targets_m, centred.targets_m + [centre, 0.0], rtol=0, atol=1e-12)
    assert_allclose(moved.times_s, centred.times_s, rtol=0, atol=1e-12)
    # The exact-endpoints family ends on the moved P1 and P5.
    start, end = moved.endpoint_errors_m(moved.full_parameters(NEAR_EXACT))
    assert start < 1e-9 and end < 1e-9


@pytest.mark.parametrize("centre", [-0.04, 0.03])
def test_analytic_and_coal_routes_agree_on_the_moved_box(arm: PlanarArm, centre: float) -> None:
    scene = Scene(centre_x_m=centre)
    analytic = fitness_problem(arm, 0.25, 0.10, scene, FitnessConfig(**SMALL, clearance_route=ANALYTIC), PAPER)
    coal = fitness_problem(arm, 0.25, 0.10, scene, FitnessConfig(**SMALL, clearance_route=COAL), PAPER)
    rng = np.random.default_rng(2)
    q = np.c_[rng.uniform(0.3, 2.8, 300), rng.uniform(0.05, 2.5, 300)]
    a, c = analytic.clearance_at(q), coal.clearance_at(q)
    positive = (a > 1e-4) & (c > 1e-4)
    assert positive.sum() > 300
    assert_allclose(a[positive], c[positive], rtol=0, atol=1e-9)
    # ... and both differ from the centred box's.
    centred = fitness_problem(arm, 0.25, 0.10, Scene(), FitnessConfig(**SMALL), PAPER).clearance_at(q)
    assert np.max(np.abs(centred - a)) > 0.01


def test_exact_endpoints_experiment_off_centre(arm: PlanarArm) -> None:
    """One DOE experiment with the default PSO: the optimum ends on P1 and P5 to rounding and
    keeps the margin; T is the centred obstacle's."""
    scene = Scene(centre_x_m=0.03)
    result = solve_experiment(arm, 0.25, 0.10, scene, SolverConfig(family=EXACT_ENDPOINTS), np.random.default_rng(0))
    assert result.endpoint_error_start_m < 1e-9 and result.endpoint_error_end_m < 1e-9
    assert result.clearance_m >= scene.margin_m
    centred = fitness_problem(arm, 0.25, 0.10, Scene(), FitnessConfig(), EXACT_ENDPOINTS)
    assert result.duration_s == pytest.approx(centred.path.duration_s, rel=1e-12, abs=0)
    problem = fitness_problem(arm, 0.25, 0.10, scene, FitnessConfig(), EXACT_ENDPOINTS)
    parameters = np.array([result.parameters[name] for name in PARAMETER_NAMES])
    q = joint_angles(parameters, np.array([0.0, result.duration_s]))
    assert_allclose(arm.end_effector_planar(q), problem.path.points_m[[0, -1]], rtol=0, atol=1e-9)
