"""Strips along W over (L, W, x) (pipeline.certify.strip_split with a moved obstacle) against
independent references: the online generator's motions (analytic clearance, itself shown equal to
Coal in test_range_certificate) for the strips' clearance bounds, and a dense sampling of the end
poses near the moved P1 and P5 for their infeasibility bounds, including the strips proven by
monotonicity alone, and a map whose bytes do not depend on how many columns of strips a task
holds. The band of x is narrow, so that the strips' infeasibility bound proves some on Eq. 9's
coefficients."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pipeline import load_coefficients
from pipeline.certify import range_certificate
from pipeline.certify.map_files import region_map_files
from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
from pipeline.certify.region_map import STATUSES, RegionMap
from pipeline.geometry.clearance import analytic_link_clearance
from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle
from pipeline.offline.coefficients import Coefficients
from pipeline.online.generator import generate

#: The top strip of Eq. 9's range, where its end poses lose the margin, over a band of x narrow
#: enough for the strips' infeasibility bound to prove some.
TOP = {"L": (0.2, 0.21), "W": (0.118, 0.12), "x": (-1e-5, 1e-5)}
CONFIG = RangeCertificateConfig(min_cell=1 / 16, boundary_cell=1 / 8, strip_split=3)


@pytest.fixture(scope="module")
def top(over_x) -> Coefficients:
    return dataclasses.replace(over_x(load_coefficients("paper"), scale=1.0), fitted_range_m=TOP)


@pytest.fixture(scope="module")
def maps(top: Coefficients) -> tuple[RegionMap, RegionMap]:
    """The top strip's map with strips (2^3 per cut cell) and without."""
    return certify_range(top, CONFIG), certify_range(top, dataclasses.replace(CONFIG, strip_split=0))


def _halvings(region_map: RegionMap) -> np.ndarray:
    """Per leaf, how many more times it is cut along W than along L (> 0: a strip)."""
    return region_map.subpaving.levels[:, 1] - region_map.subpaving.levels[:, 0]


def test_strips_gain_area_and_keep_the_other_axes_whole(maps: tuple[RegionMap, RegionMap], check_strips_gain) -> None:
    with_strips = maps[0]
    levels = with_strips.subpaving.levels[check_strips_gain(*maps)]
    np.testing.assert_array_equal(levels[:, 0], levels[:, 2])  # L and x at the cell's level, W deeper


def test_strip_clearance_bounds_hold_along_the_moved_motions(top: Coefficients, maps, arm: PlanarArm) -> None:
    """At random points of 40 strips and 801 times each, the generator's motion around the moved
    obstacle clears the strip's bound."""
    region_map = maps[0]
    strips = np.flatnonzero(_halvings(region_map) > 0)
    rng = np.random.default_rng(7)
    for k in rng.choice(strips, size=min(40, strips.size), replace=False):
        cell = region_map.cell(int(k))
        L, W, x = (rng.uniform(*cell.range_of(name)) for name in ("L", "W", "x"))
        answer = generate(top, L, W, x=x, region_map=None, out_of_range="ignore")
        assert answer.obstacle.centre_x_m == x
        q = answer.q(np.linspace(0.0, answer.duration_s, 801))
        assert float(analytic_link_clearance(q, arm, answer.obstacle).min()) >= cell.clearance_bound_m - 1e-12


def test_infeasible_strips_hold_no_feasible_end_poses(
    top: Coefficients, maps, arm: PlanarArm, end_pose_clearance
) -> None:
    """Every strip proven infeasible, including those above the one proven in their column (by
    monotonicity alone), has at its roomiest face (its lowest W), at the four corners over (L, x)
    and two random points of it, no sampled end pose near the moved P1 or P5 that clears its
    bound."""
    region_map = maps[0]
    tolerance = region_map.endpoint_tolerance_m
    infeasible = np.flatnonzero((_halvings(region_map) > 0) & (region_map.status == STATUSES.index("infeasible")))
    assert infeasible.size > 0
    rng = np.random.default_rng(3)
    for k in infeasible[:: max(1, infeasible.size // 10)]:
        cell = region_map.cell(int(k))
        (L0, L1), (x0, x1), W = cell.range_of("L"), cell.range_of("x"), cell.range_of("W")[0]
        points = [
            (L0, x0),
            (L0, x1),
            (L1, x0),
            (L1, x1),
            *zip(rng.uniform(L0, L1, 2), rng.uniform(x0, x1, 2), strict=True),
        ]
        for L, x in points:
            scene = dataclasses.replace(top.scene, centre_x_m=float(x))
            room = end_pose_clearance(top, arm, Obstacle.in_scene(L, W, scene), scene, tolerance).min()
            assert room <= cell.endpoint_clearance_upper_m + 1e-9


def test_the_map_does_not_depend_on_how_many_columns_a_task_holds(
    top: Coefficients, maps: tuple[RegionMap, RegionMap], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A strip's bounds depend on its column alone: with one column per task (a task per column)
    the map's bytes are those of the default tasks."""
    monkeypatch.setattr(range_certificate, "_STRIP_COLUMNS", 1)
    one_per_task = certify_range(top, CONFIG)
    assert region_map_files(one_per_task) == region_map_files(maps[0])
    assert np.count_nonzero(_halvings(maps[0]) > 0) > range_certificate._STRIP_COLUMNS  # more than one task
