"""Cuts for the clearance (pipeline.certify.clearance_cuts) over (L, W, x, d): the axis halved is the
one along which the clearance, computed from the definitions, changes most; the cuts raise the
margin's volume of a coarse map and change nothing else, and every halved leaf's clearance bound
lies below the clearance sampled densely inside it, along motions built from the definitions (the
regression at the point, the moved path's T, the moved obstacle, analytic distance and Coal)."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest

from pipeline import load_coefficients
from pipeline.certify.clearance_cuts import STEEPEST_SAMPLES_S, steepest_axes
from pipeline.certify.range_certificate import PROGRESS_STAGES, RangeCertificateConfig, certify_range
from pipeline.certify.range_model import RangeModel
from pipeline.certify.region_map import STATUSES, RegionMap, region_map_text
from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.clearance import COAL_DISTANCE_ERROR_M, CoalClearance, analytic_link_clearance
from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle
from pipeline.motion.path import desired_path
from pipeline.motion.trajectory import JointTrajectory
from pipeline.offline.coefficients import Coefficients

#: Cubes of 1/4 over (L, W, x, d), in the second-order form: the search leaves every cube below the
#: margin, the cuts prove part of them.
COARSE = RangeCertificateConfig(min_cell=1 / 4, boundary_cell=1 / 4, second_order=True, strip_split=0)


@pytest.fixture(scope="module")
def eq9_xd(over_xd) -> Coefficients:
    return over_xd(load_coefficients("paper"), d_range_m=(0.55, 0.57), scale=0.2)


@pytest.fixture(scope="module")
def maps(eq9_xd: Coefficients) -> tuple[RegionMap, RegionMap]:
    """The coarse map with 4 rounds of cuts for the clearance, and without."""
    return certify_range(eq9_xd, dataclasses.replace(COARSE, clearance_cuts=4)), certify_range(eq9_xd, COARSE)


def test_the_steepest_axis_is_where_the_clearance_changes_most(eq9_xd: Coefficients, arm: PlanarArm) -> None:
    """20 random cells: the axis chosen is the one along which the clearance at the centre's lowest
    sampled time s*, from the definitions (``_clearance_along``), differs most between the two faces
    across it; and a cell thin along every axis but one is halved along that one."""
    model = RangeModel.from_coefficients(eq9_xd)
    lo, size = model.range_lo, model.range_size
    rng = np.random.default_rng(7)
    radius = size * rng.uniform(1 / 64, 1 / 8, (20, 4))
    centre = lo + radius + rng.uniform(0.0, 1.0, (20, 4)) * (size - 2 * radius)
    chosen = steepest_axes(model, centre, radius)
    s = np.linspace(0.0, 1.0, STEEPEST_SAMPLES_S)
    compared = 0
    for row in range(20):
        s_star = s[[np.argmin(_clearance_along(eq9_xd, arm, centre[row], s))]]
        change = []
        for axis in range(4):
            step = np.zeros(4)
            step[axis] = radius[row, axis]
            ends = (_clearance_along(eq9_xd, arm, centre[row] + sign * step, s_star)[0] for sign in (-1, 1))
            change.append(abs(np.subtract(*ends)))
        top_two = np.sort(change)[-2:]
        if top_two[1] - top_two[0] > 1e-9:  # a clear winner: no tie decided by rounding
            assert chosen[row] == int(np.argmax(change))
            compared += 1
    assert compared >= 15
    for axis in range(4):
        thin = np.full((1, 4), 1e-9)
        thin[0, axis] = size[axis] / 16
        assert steepest_axes(model, lo + size / 2, thin).tolist() == [axis]


def test_cuts_raise_the_margin_and_change_nothing_else(maps: tuple[RegionMap, RegionMap]) -> None:
    cut, plain = maps
    with_cuts, without = cut.summary()["area_fraction"], plain.summary()["area_fraction"]
    assert with_cuts["margin"] > without["margin"] + 0.1
    assert with_cuts["infeasible"] == without["infeasible"]
    assert sum(with_cuts.values()) == pytest.approx(1.0, abs=1e-12)
    assert cut.summary()["endpoint_bound_max_m"] <= plain.summary()["endpoint_bound_max_m"]
    assert int(cut.subpaving.levels.max()) <= 2 + 4  # 4 rounds: one axis halved up to 4 times


def _motion(coefficients: Coefficients, point: np.ndarray) -> tuple[JointTrajectory, Obstacle]:
    """The regression's trajectory at the point (L, W, x, d) and the obstacle it moves, from the
    definitions (the regression at the point, the moved path's T, the moved obstacle)."""
    L, W, x, d = (float(v) for v in point)
    scene = dataclasses.replace(coefficients.scene, centre_x_m=x, top_y_m=d)
    obstacle = Obstacle.in_scene(L, W, scene)
    parameters = coefficients.family.expand(coefficients.predict_free(L, W, x=x, d=d), None)
    trajectory = JointTrajectory.trusted(tuple(float(p) for p in parameters), desired_path(obstacle, scene).duration_s)
    return trajectory, obstacle


def _clearance_along(coefficients: Coefficients, arm: PlanarArm, point: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Analytic clearance [m] of both links (the smaller) at each s = t / T at the point (L, W, x, d)."""
    trajectory, obstacle = _motion(coefficients, point)
    return analytic_link_clearance(trajectory.q(s * trajectory.duration_s), arm, obstacle).min(axis=1)


def _clearance(coefficients: Coefficients, arm: PlanarArm, point: np.ndarray, s: np.ndarray) -> tuple:
    """Analytic and Coal clearance of both links along s at the point (L, W, x, d)."""
    trajectory, obstacle = _motion(coefficients, point)
    q = trajectory.q(s * trajectory.duration_s)
    coal = CoalClearance(arm, obstacle)
    return analytic_link_clearance(q, arm, obstacle).min(), min(coal.link_clearance(row).min() for row in q)


def test_halved_leaves_bound_the_clearance_sampled_inside_them(
    eq9_xd: Coefficients, maps: tuple[RegionMap, RegionMap], arm: PlanarArm
) -> None:
    """12 halved leaves (the margin's and the others), 6 random points each and the centre, 81
    times: every sampled clearance at least the leaf's bound (Coal within its distance error)."""
    region_map = maps[0]
    halved = np.flatnonzero(region_map.subpaving.levels.max(axis=1) > 2)
    kept = halved[region_map.status[halved] == STATUSES.index("margin")]
    assert kept.size > 0
    rng = np.random.default_rng(4)
    chosen = np.unique(np.concatenate([rng.choice(kept, 6, replace=False), rng.choice(halved, 6, replace=False)]))
    centres, sizes = region_map.leaf_centres_m()[chosen], region_map.leaf_sizes_m()[chosen]
    s = np.linspace(0.0, 1.0, 81)
    for row, leaf in enumerate(chosen):
        bound = float(region_map.clearance_bound_m[leaf])
        points = [centres[row], *(centres[row] + sizes[row] * rng.uniform(-0.5, 0.5, (6, 4)))]
        for point in points:
            analytic, coal = _clearance(eq9_xd, arm, point, s)
            assert analytic >= bound - 1e-12
            assert coal >= bound - COAL_DISTANCE_ERROR_M


def test_the_cuts_give_the_same_bytes_on_two_workers(eq9_xd: Coefficients) -> None:
    """The cuts for the clearance and across the infeasibility contour's tilt run in fixed tasks:
    two worker processes write the map one process writes."""
    config = dataclasses.replace(COARSE, clearance_cuts=4, infeasibility_cuts=5, tilt_cuts=1)
    one, two = (region_map_text(certify_range(eq9_xd, dataclasses.replace(config, jobs=jobs))) for jobs in (1, 2))
    assert one == two


def test_the_cuts_report_their_progress_once_each_in_order(eq9_xd: Coefficients) -> None:
    """Over the rounds each cut stage is reported as one run, from 0 up to its total (which grows by
    each round's leaves), in the order of PROGRESS_STAGES."""
    calls: list[tuple[str, int, int]] = []
    config = dataclasses.replace(COARSE, clearance_cuts=4, infeasibility_cuts=5, tilt_cuts=1)
    certify_range(eq9_xd, config, progress=lambda *call: calls.append(call))
    stages = [stage for stage, _, _ in calls]
    runs = [stage for k, stage in enumerate(stages) if k == 0 or stages[k - 1] != stage]
    assert runs == sorted(set(runs), key=PROGRESS_STAGES.index)
    assert {"range map: W cuts", "range map: clearance cuts"} <= set(runs)
    for stage in runs:
        mine = [(done, total) for name, done, total in calls if name == stage]
        assert mine[0][0] == 0 and mine[-1][0] == mine[-1][1] > 0
        assert all(b[0] >= a[0] and b[1] >= a[1] for a, b in itertools.pairwise(mine))


def test_the_setting_is_checked() -> None:
    with pytest.raises(InvalidParameterError, match="clearance_cuts"):
        RangeCertificateConfig(clearance_cuts=9)
    with pytest.raises(InvalidParameterError, match="clearance_cuts"):
        RangeCertificateConfig(clearance_cuts=-1)
    assert [RangeCertificateConfig.for_axes(k).clearance_cuts for k in (2, 3, 4)] == [0, 0, 4]
