"""Strips along W (pipeline.certify.strip_split) against independent references: the online
generator's motions (analytic clearance, itself shown equal to Coal in test_range_certificate)
for the strips' clearance bounds, and Coal on inverse-kinematics poses near P1 and P5 for
their infeasibility bounds, including the strips proven by monotonicity alone."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pipeline import load_coefficients
from pipeline.certify import strip_split
from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
from pipeline.certify.range_model import RangeModel
from pipeline.certify.region_map import STATUSES, RegionMap
from pipeline.certify.search import node_boxes
from pipeline.certify.strip_split import strip_clearance_bounds, strip_infeasibility_bounds
from pipeline.exceptions import InvalidParameterError
from pipeline.geometry.clearance import COAL_DISTANCE_ERROR_M, CoalClearance, analytic_link_clearance
from pipeline.model.arm import PlanarArm
from pipeline.model.kinematics import inverse_kinematics
from pipeline.model.obstacle import Obstacle
from pipeline.offline.coefficients import Coefficients
from pipeline.online.generator import generate

#: The top strip of the default range, where Eq. 9's end poses lose the margin.
TOP = {"L": (0.2, 0.21), "W": (0.118, 0.12)}
CONFIG = RangeCertificateConfig(min_cell=1 / 16, boundary_cell=1 / 8)


@pytest.fixture(scope="module")
def top() -> Coefficients:
    return dataclasses.replace(load_coefficients("paper"), fitted_range_m=TOP)


@pytest.fixture(scope="module")
def maps(top: Coefficients) -> tuple[RegionMap, RegionMap]:
    """The top strip's map with strips (the default 2^3 per cut cell) and without."""
    return certify_range(top, CONFIG), certify_range(top, dataclasses.replace(CONFIG, strip_split=0))


def _room_near(coefficients: Coefficients, arm: PlanarArm, L: float, W: float, tolerance_m: float) -> float:
    """Sampled room at (L, W) by Coal: the smaller over P1 and P5 of the largest Coal clearance
    of an inverse-kinematics pose whose tip lies within the tolerance of the end point."""
    coal = CoalClearance(arm, Obstacle.in_scene(L, W, coefficients.scene))
    ends = []
    for side in (1.0, -1.0):
        end = np.array([side * (L / 2 + coefficients.scene.start_dx_m), coefficients.scene.y1_m])
        best = -np.inf
        for radius in np.linspace(0.0, tolerance_m, 5):
            for angle in np.linspace(0.0, 2 * np.pi, 90, endpoint=False):
                tip = end + radius * np.array([np.cos(angle), np.sin(angle)])
                q = inverse_kinematics(tip, arm.link_lengths_m, coefficients.elbow)
                best = max(best, float(coal.link_clearance(q).min()))
        ends.append(best)
    return min(ends)


def _halvings(region_map: RegionMap) -> np.ndarray:
    """Per leaf, how many more times it is cut along W than along L (> 0: a strip)."""
    return region_map.subpaving.levels[:, 1] - region_map.subpaving.levels[:, 0]


def test_strips_gain_area_on_both_sides_of_the_contours(maps: tuple[RegionMap, RegionMap], check_strips_gain) -> None:
    """Cut cells give area to "margin" and to "infeasible" that the uncut map left below the
    margin, and the fractions still add up."""
    check_strips_gain(*maps)


def test_strip_clearance_bounds_hold_along_the_motions(top: Coefficients, maps, arm: PlanarArm) -> None:
    """At random points of 60 strips and 801 times each, the generator's motion clears the
    strip's bound."""
    region_map = maps[0]
    strips = np.flatnonzero(_halvings(region_map) > 0)
    rng = np.random.default_rng(5)
    for k in rng.choice(strips, size=min(60, strips.size), replace=False):
        cell = region_map.cell(int(k))
        L, W = rng.uniform(*cell.range_of("L")), rng.uniform(*cell.range_of("W"))
        answer = generate(top, L, W, out_of_range="ignore")
        q = answer.q(np.linspace(0.0, answer.duration_s, 801))
        lowest = float(analytic_link_clearance(q, arm, answer.obstacle).min())
        assert lowest >= cell.clearance_bound_m - 1e-12


def test_strip_clearance_bound_is_the_floor_or_better_and_tightens(top: Coefficients, arm: PlanarArm) -> None:
    """Four strips of the top strip's cells, each asked for its own sampled minimum less 0.05 mm:
    the s search proves it (a bound within 0.05 mm of the truth) and never exceeds the sampled
    minimum; a floor above what the search proves is returned as it is."""
    model = RangeModel.from_coefficients(top)
    c, r = node_boxes(model, np.full(4, 4), np.array([[1, 10], [5, 41], [9, 72], [13, 103]]), split_w=3)
    lowest = np.empty(4)
    for k in range(4):
        answer = generate(top, *c[k], out_of_range="ignore")
        q = answer.q(np.linspace(0.0, answer.duration_s, 4001))
        lowest[k] = float(analytic_link_clearance(q, arm, answer.obstacle).min())
    for k in range(4):
        margin = lowest[k] - 5e-5
        bound = strip_clearance_bounds(model, c[k : k + 1], r[k : k + 1], np.full(1, -1.0), margin, 16)[0]
        assert margin <= bound <= lowest[k] + 1e-12
    high = strip_clearance_bounds(model, c, r, np.full(4, 0.3), 0.5, 16)
    assert np.all(high == 0.3)


def test_second_order_strip_bounds_prove_closer_to_the_sampled_minimum(top: Coefficients, arm: PlanarArm) -> None:
    """Four strips, each asked for its own sampled minimum less 25 um: the mean-value form alone
    proves none of them, the tighter of both forms proves every one, and no bound exceeds the
    sampled minimum."""
    model = RangeModel.from_coefficients(top)
    c, r = node_boxes(model, np.full(4, 4), np.array([[1, 10], [5, 41], [9, 72], [13, 103]]), split_w=3)
    for k in range(4):
        answer = generate(top, *c[k], out_of_range="ignore")
        q = answer.q(np.linspace(0.0, answer.duration_s, 4001))
        lowest = float(analytic_link_clearance(q, arm, answer.obstacle).min())
        margin = lowest - 2.5e-5
        box = (model, c[k : k + 1], r[k : k + 1], np.full(1, -1.0), margin, 16)
        mean_value = strip_clearance_bounds(*box)[0]
        tighter = strip_clearance_bounds(*box, second_order=True)[0]
        assert mean_value < margin <= tighter <= lowest + 1e-12


def test_infeasible_strips_hold_no_feasible_end_poses(top: Coefficients, maps, arm: PlanarArm) -> None:
    """Every strip proven infeasible, including those above the one proven in their column (by
    monotonicity alone), has at its roomiest points (W0, both ends of L) no sampled Coal pose
    within the tolerance of P1 and P5 that clears its bound; and below the lowest proven strip of
    some column lie strips whose sampled room does reach the margin (a bound passed downwards
    would be caught here)."""
    region_map = maps[0]
    tolerance, margin = region_map.endpoint_tolerance_m, region_map.margin_m
    infeasible = np.flatnonzero((_halvings(region_map) > 0) & (region_map.status == STATUSES.index("infeasible")))
    assert infeasible.size > 0
    for k in infeasible[:: max(1, infeasible.size // 12)]:
        cell = region_map.cell(int(k))
        for L in cell.range_of("L"):
            room = _room_near(top, arm, L, cell.range_of("W")[0], tolerance)
            assert room <= cell.endpoint_clearance_upper_m + COAL_DISTANCE_ERROR_M
    reaching = 0
    index_l, index_w = region_map.subpaving.indices.T
    for k in np.flatnonzero(_halvings(region_map) > 0):
        cell = region_map.cell(int(k))
        below_proven = cell.status != "infeasible" and any(
            region_map.cell(int(j)).status == "infeasible"
            for j in np.flatnonzero((index_l == index_l[k]) & (_halvings(region_map) > 0))
            if index_w[j] > index_w[k]
        )
        if (
            below_proven
            and _room_near(top, arm, np.mean(cell.range_of("L")), cell.range_of("W")[0], tolerance) >= margin
        ):
            reaching += 1
            if reaching >= 2:
                break
    assert reaching >= 1


def test_a_wrong_choice_of_strips_costs_proofs_not_soundness(top: Coefficients, maps, arm, monkeypatch) -> None:
    """The sampled room only chooses which strips to try: with the slack turned into a head
    start (strips tried whose room is 0.1 mm above the margin) nothing false is proven, and
    strips that were proven are now left open."""
    model = RangeModel.from_coefficients(top)
    region_map = maps[0]
    strips = np.flatnonzero(_halvings(region_map) > 0)
    index_l, index_w = region_map.subpaving.indices.T
    order = np.lexsort((index_w[strips], index_l[strips]))
    strips = strips[order]
    e = int(_halvings(region_map).max())
    index = np.column_stack([index_l[strips], index_w[strips]])
    c, r = node_boxes(model, region_map.subpaving.levels[strips, 0], index, e)
    tolerance, margin = region_map.endpoint_tolerance_m, region_map.margin_m
    right = strip_infeasibility_bounds(model, c, r, index_l[strips], margin, tolerance)
    monkeypatch.setattr(strip_split, "ROOM_SLACK_M", -1e-4)
    wrong = strip_infeasibility_bounds(model, c, r, index_l[strips], margin, tolerance)
    assert np.count_nonzero(wrong < margin) < np.count_nonzero(right < margin)
    for k in np.flatnonzero(wrong < margin)[:6]:
        L0, W0 = c[k] - r[k]
        assert _room_near(top, arm, L0, W0, tolerance) <= wrong[k] + COAL_DISTANCE_ERROR_M


def test_strip_split_is_checked() -> None:
    for bad in (-1, 7, 1.5):
        with pytest.raises(InvalidParameterError, match="strip_split"):
            RangeCertificateConfig(strip_split=bad)
