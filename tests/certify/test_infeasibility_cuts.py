"""Cuts along W at the infeasibility contour (pipeline.certify.infeasibility_cuts) over (L, W, x)
and (L, W, x, d): the pieces tile their leaf, the proven parts hold no end pose that clears their
bound in a dense sampling of the poses near the moved P1 and P5 (the independent check), and a
map with the cuts gains infeasible volume where the map without them leaves it below the margin."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline import load_coefficients
from pipeline.certify.infeasibility_cuts import cut_leaves, dyadic_pieces, lowest_infeasible_cuts, tilt_axes
from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
from pipeline.certify.range_model import RangeModel
from pipeline.certify.region_map import STATUSES, RegionMap
from pipeline.certify.search import cell_boxes
from pipeline.exceptions import InvalidParameterError
from pipeline.model.arm import PlanarArm
from pipeline.model.obstacle import Obstacle
from pipeline.offline.coefficients import Coefficients

#: The top of Eq. 9's W range, where its end poses lose the margin, over a band of x.
TOP = {"L": (0.2, 0.22), "W": (0.118, 0.12), "x": (-0.004, 0.004)}
CONFIG = RangeCertificateConfig(min_cell=1 / 8, boundary_cell=1 / 8, infeasibility_cuts=5)
TOLERANCE_M, MARGIN_M = 0.002, 0.01


@pytest.fixture(scope="module")
def top(over_x) -> Coefficients:
    return dataclasses.replace(over_x(load_coefficients("paper"), scale=1.0), fitted_range_m=TOP)


@pytest.fixture(scope="module")
def maps(top: Coefficients) -> tuple[RegionMap, RegionMap]:
    """The top band's map with the cuts (2^5 levels) and without."""
    return certify_range(top, CONFIG), certify_range(top, dataclasses.replace(CONFIG, infeasibility_cuts=0))


@settings(max_examples=300, deadline=None)
@given(st.integers(0, 8).flatmap(lambda e: st.tuples(st.just(e), st.integers(0, 2**e), st.integers(0, 2**e))))
def test_dyadic_pieces_tile_the_interval_in_order(case: tuple[int, int, int]) -> None:
    cuts, a, b = case
    start, stop = min(a, b), max(a, b)
    pieces = dyadic_pieces(start, stop, cuts)
    covered = []
    for level, index in pieces:
        assert 0 <= level <= cuts
        size = 2 ** (cuts - level)
        covered.extend(range(index * size, (index + 1) * size))
    assert covered == list(range(start, stop))
    assert len(pieces) <= 2 * cuts + 1


def test_the_pieces_of_a_cut_leaf_tile_it_and_lie_on_their_side_of_the_cut(top: Coefficients) -> None:
    model = RangeModel.from_coefficients(top)
    rng = np.random.default_rng(2)
    levels = rng.integers(0, 6, (20, 3))
    index = np.column_stack([rng.integers(0, 2**lv) for lv in levels.T])
    cuts = 5
    j = rng.integers(1, 2**cuts, 20)
    owner, piece_levels, piece_index, above = cut_leaves(levels, index, j, cuts)
    assert np.array_equal(np.unique(owner), np.arange(20))
    leaf_c, leaf_r = cell_boxes(model, levels, index)
    piece_c, piece_r = cell_boxes(model, piece_levels, piece_index)
    np.testing.assert_array_equal(np.delete(piece_levels - levels[owner], 1, axis=1), 0)  # W deeper only
    volume = np.prod(piece_r, axis=1)
    np.testing.assert_allclose(np.bincount(owner, volume), np.prod(leaf_r, axis=1), rtol=1e-12)
    w_cut = (leaf_c[:, 1] - leaf_r[:, 1]) + 2 * leaf_r[:, 1] * j / 2**cuts
    low, high = piece_c[:, 1] - piece_r[:, 1], piece_c[:, 1] + piece_r[:, 1]
    assert np.all(np.where(above, low >= w_cut[owner] - 1e-15, high <= w_cut[owner] + 1e-15))


def test_cuts_gain_infeasible_volume_and_keep_the_margin(maps: tuple[RegionMap, RegionMap]) -> None:
    with_cuts, without = (m.summary()["area_fraction"] for m in maps)
    assert with_cuts["infeasible"] > without["infeasible"] + 0.01
    assert with_cuts["margin"] == without["margin"]
    assert sum(with_cuts.values()) == pytest.approx(1.0, abs=1e-12)
    levels = maps[0].subpaving.levels
    assert np.count_nonzero(levels[:, 1] > levels[:, 0]) > 0  # pieces: cut along W more than along L


def test_proven_parts_hold_no_end_pose_that_clears_their_bound(
    top: Coefficients, maps, arm: PlanarArm, end_pose_clearance
) -> None:
    """Every piece proven infeasible by a cut has, at its roomiest face (its lowest W), at the four
    corners over (L, x) and two random points of it, no sampled end pose near the moved P1 or P5
    that clears its bound."""
    region_map = maps[0]
    levels = region_map.subpaving.levels
    pieces = np.flatnonzero((levels[:, 1] > levels[:, 0]) & (region_map.status == STATUSES.index("infeasible")))
    assert pieces.size > 0
    rng = np.random.default_rng(3)
    for k in pieces[:: max(1, pieces.size // 12)]:
        cell = region_map.cell(int(k))
        (L0, L1), (x0, x1), W = cell.range_of("L"), cell.range_of("x"), cell.range_of("W")[0]
        corners = [(L0, x0), (L0, x1), (L1, x0), (L1, x1)]
        for L, x in [*corners, *zip(rng.uniform(L0, L1, 2), rng.uniform(x0, x1, 2), strict=True)]:
            scene = dataclasses.replace(top.scene, centre_x_m=float(x))
            room = end_pose_clearance(top, arm, Obstacle.in_scene(L, W, scene), scene, TOLERANCE_M).min()
            assert room <= cell.endpoint_clearance_upper_m + 1e-12 < MARGIN_M


def test_over_x_and_d_the_proven_parts_hold_no_end_pose_that_clears_their_bound(
    over_xd, arm: PlanarArm, end_pose_clearance
) -> None:
    """Cells of 1/32 at the top of W over (L, W, x, d): a cut is found in some, and the part above
    it holds no sampled end pose near the moved P1 or P5 (y1 = d) that clears its bound."""
    lifted = over_xd(load_coefficients("paper"))
    model = RangeModel.from_coefficients(lifted)
    rng = np.random.default_rng(5)
    half = model.range_size / 64
    centre = model.range_lo + half * (2 * rng.integers(0, 32, (24, 4)) + 1)
    centre[:, 1] = model.range_lo[1] + model.range_size[1] - half[1] * (1 + 2 * rng.integers(0, 3, 24))
    radius = np.tile(half, (24, 1))
    found = lowest_infeasible_cuts(model, centre, radius, 5, TOLERANCE_M, MARGIN_M)
    cut = np.flatnonzero(found[:, 0] < 32)
    assert cut.size >= 2 and np.all(found[cut, 1] < MARGIN_M) and np.all(np.isinf(found[found[:, 0] == 32, 1]))
    for k in cut:
        w_cut = centre[k, 1] - radius[k, 1] + 2 * radius[k, 1] * found[k, 0] / 32
        for _ in range(4):
            L, x, d = (rng.uniform(centre[k, a] - radius[k, a], centre[k, a] + radius[k, a]) for a in (0, 2, 3))
            scene = dataclasses.replace(lifted.scene, centre_x_m=float(x), top_y_m=float(d))
            room = end_pose_clearance(lifted, arm, Obstacle.in_scene(L, w_cut, scene), scene, TOLERANCE_M).min()
            assert room <= found[k, 1] + 1e-12


def test_the_setting_is_checked() -> None:
    with pytest.raises(InvalidParameterError, match="infeasibility_cuts"):
        RangeCertificateConfig(infeasibility_cuts=9)
    with pytest.raises(InvalidParameterError, match="infeasibility_cuts"):
        RangeCertificateConfig(infeasibility_cuts=-1)
    assert RangeCertificateConfig.for_axes(2).infeasibility_cuts == 0
    assert RangeCertificateConfig.for_axes(3).infeasibility_cuts == 0
    assert RangeCertificateConfig.for_axes(4).infeasibility_cuts == 7


#: The top of W over (L, W, x, d), where the contour where the end poses' room crosses the margin
#: tilts across d as much as across W (the room depends on the obstacle's near edge d - W).
TOP_XD = {**TOP, "d": (0.557, 0.561)}
XD_CONFIG = RangeCertificateConfig(min_cell=1 / 4, boundary_cell=1 / 4, infeasibility_cuts=5)


@pytest.fixture(scope="module")
def tilted_maps(over_xd) -> tuple[RegionMap, RegionMap]:
    """The (L, W, x, d) top band's map with the cuts along W after 2 halvings across the
    contour's tilt, and with the cuts alone."""
    band = dataclasses.replace(over_xd(load_coefficients("paper")), fitted_range_m=TOP_XD)
    tilted = dataclasses.replace(XD_CONFIG, tilt_cuts=2)
    return certify_range(band, tilted), certify_range(band, XD_CONFIG)


def test_halving_across_the_tilt_gains_infeasible_volume_and_keeps_the_margin(tilted_maps) -> None:
    tilted, straight = (m.summary()["area_fraction"] for m in tilted_maps)
    assert tilted["infeasible"] > straight["infeasible"] + 0.05
    assert tilted["margin"] == straight["margin"]
    assert sum(tilted.values()) == pytest.approx(1.0, abs=1e-12)
    levels = tilted_maps[0].subpaving.levels
    assert np.any(np.delete(levels, 1, axis=1) > 2)  # halved beyond the smallest cell across W


def test_tilted_pieces_hold_no_end_pose_that_clears_their_bound(
    over_xd, tilted_maps, arm: PlanarArm, end_pose_clearance
) -> None:
    """Every infeasible leaf halved across the tilt has, at the 8 corners of its roomiest face
    (its lowest W) over (L, x, d) and two random points of it, no end pose of the dense sampling
    near the moved P1 or P5 that clears its bound."""
    band = dataclasses.replace(over_xd(load_coefficients("paper")), fitted_range_m=TOP_XD)
    region_map = tilted_maps[0]
    levels = region_map.subpaving.levels
    halved = np.any(np.delete(levels, 1, axis=1) > 2, axis=1)
    pieces = np.flatnonzero(halved & (region_map.status == STATUSES.index("infeasible")))
    assert pieces.size > 0
    rng = np.random.default_rng(7)
    for k in pieces[:: max(1, pieces.size // 10)]:
        cell = region_map.cell(int(k))
        ranges = [cell.range_of(name) for name in ("L", "x", "d")]
        W = cell.range_of("W")[0]
        points = [*itertools.product(*ranges), *zip(*(rng.uniform(lo, hi, 2) for lo, hi in ranges), strict=True)]
        for L, x, d in points:
            scene = dataclasses.replace(band.scene, centre_x_m=float(x), top_y_m=float(d))
            room = end_pose_clearance(band, arm, Obstacle.in_scene(L, W, scene), scene, TOLERANCE_M).min()
            assert room <= cell.endpoint_clearance_upper_m + 1e-12 < MARGIN_M


def test_the_tilt_axis_is_the_one_across_which_the_room_changes_most(
    over_xd, arm: PlanarArm, end_pose_clearance
) -> None:
    """On cells of the band, the axis ``tilt_axes`` picks changes the densely sampled room between
    its two faces by at least as much as every other axis but W, within the sampling's spread."""
    band = dataclasses.replace(over_xd(load_coefficients("paper")), fitted_range_m=TOP_XD)
    model = RangeModel.from_coefficients(band)
    rng = np.random.default_rng(11)
    radius = np.tile(model.range_size / 8, (6, 1))  # cells of 1/4
    centre = model.range_lo + radius * (2 * rng.integers(0, 4, (6, 4)) + 1)
    chosen = tilt_axes(model, centre, radius, TOLERANCE_M)
    assert np.all(chosen != 1)

    def room(point: np.ndarray) -> float:
        L, W, x, d = point
        scene = dataclasses.replace(band.scene, centre_x_m=float(x), top_y_m=float(d))
        return float(end_pose_clearance(band, arm, Obstacle.in_scene(L, W, scene), scene, TOLERANCE_M).min())

    for row in range(centre.shape[0]):
        change = {}
        for axis in (0, 2, 3):
            step = np.zeros(4)
            step[axis] = radius[row, axis]
            change[axis] = abs(room(centre[row] + step) - room(centre[row] - step))
        assert change[int(chosen[row])] >= max(change.values()) - 5e-5


def test_the_tilt_setting_is_checked() -> None:
    with pytest.raises(InvalidParameterError, match="tilt_cuts"):
        RangeCertificateConfig(tilt_cuts=7)
    with pytest.raises(InvalidParameterError, match="tilt_cuts"):
        RangeCertificateConfig(tilt_cuts=-1)
    assert [RangeCertificateConfig.for_axes(k).tilt_cuts for k in (2, 3, 4)] == [0, 0, 1]
