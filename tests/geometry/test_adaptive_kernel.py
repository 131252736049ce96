"""The adaptive certificate's compiled rounds (pipeline.geometry.adaptive_kernel) give the same
certificates as the readable NumPy route, on random trajectories and obstacles."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.geometry.clearance import COAL_DISTANCE_ERROR_M, CoalClearance, analytic_link_clearance
from pipeline.geometry.link_reach import LinkReach
from pipeline.geometry.sinusoid_certificate import certify
from pipeline.model.obstacle import Obstacle
from pipeline.motion.trajectory import JointTrajectory


def _cases(scene, seed: int, n: int):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        length, width = rng.uniform(0.15, 0.35), rng.uniform(0.05, 0.12)
        p = np.array([rng.uniform(0.3, 1.2), rng.uniform(0.3, 2.0), rng.uniform(-1.5, 1.5), rng.uniform(-0.5, 1.5)] * 2)
        p[4:] += rng.normal(scale=0.3, size=4)
        yield JointTrajectory(tuple(p), float(rng.uniform(1.0, 5.0))), Obstacle.in_scene(length, width, scene)


@pytest.mark.parametrize("decide", [0.01, 0.05, None])
def test_compiled_rounds_equal_readable_route_coal(arm, scene, decide) -> None:
    reach = LinkReach.from_arm(arm)
    for trajectory, obstacle in _cases(scene, 7, 25):
        out = []
        for compiled in (False, True):
            coal = CoalClearance(arm, obstacle)
            out.append(
                certify(
                    trajectory,
                    coal.link_clearance,
                    reach,
                    decide_above_m=decide,
                    link_clearance=coal.link_distances,
                    compiled=compiled,
                )
            )
        assert out[0] == out[1]  # every field: bounds, times, samples, evaluations, rounds


@pytest.mark.parametrize("budget", [0, 3, 40])
def test_compiled_rounds_equal_readable_route_analytic_and_budget(arm, scene, budget) -> None:
    reach = LinkReach.from_arm(arm)
    for trajectory, obstacle in _cases(scene, 11, 15):

        def clearance(q, obstacle=obstacle):
            return analytic_link_clearance(q, arm, obstacle)

        a, b = (
            certify(
                trajectory,
                clearance,
                reach,
                distance_error_m=COAL_DISTANCE_ERROR_M,
                tolerance_m=1e-6,
                max_evaluations=budget,
                compiled=compiled,
            )
            for compiled in (False, True)
        )
        assert a == b
