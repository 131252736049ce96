"""The window of the obstacle's far edge d for an arm (pipeline.offline.scene_window): its edges
are tight against the build's own pre-check, its reasons name what fails, and arms that cannot
pass the default range shrink it or are refused with the constraints that close the window."""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pytest

from pipeline.build.arm_scene import config_at
from pipeline.build.config import BuildConfig
from pipeline.build.doe_fit import check_before_work
from pipeline.exceptions import (
    InfeasibleSceneError,
    InvalidParameterError,
    NoSceneWindowError,
    UnreachableObstacleError,
)
from pipeline.model.arm import PlanarArm, load_planar_arm
from pipeline.model.scene import Scene
from pipeline.offline.convergence import grid_problems
from pipeline.offline.fitness import FitnessConfig
from pipeline.offline.scene_window import (
    END_POSE,
    REACH,
    Failure,
    SceneWindow,
    WindowSettings,
    _rounded_middle,
    scene_window,
)

DEFAULT = BuildConfig()
RANGES = (DEFAULT.design.length_range_m, DEFAULT.design.width_range_m)
#: Rounding slack of the analytic edges [m] (the bisection's own bracket is 1e-4 m).
EDGE_TOLERANCE_M = 2e-4


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("arms")


@pytest.fixture(scope="module")
def arm_040(folder: Path, urdf_with_links) -> PlanarArm:
    return load_planar_arm(urdf_with_links(folder, 0.40, 0.30))


@pytest.fixture(scope="module")
def window_040(arm_040: PlanarArm) -> SceneWindow:
    return scene_window(arm_040, Scene(), *RANGES)


@pytest.fixture(scope="module")
def window_040_no_collision(arm_040: PlanarArm) -> SceneWindow:
    """The window of the build's own pre-check: end poses only clear of the obstacle."""
    return scene_window(arm_040, Scene(), *RANGES, settings=WindowSettings(end_pose_clearance_m=0.0))


def config_for(arm: PlanarArm, d_m: float, **options) -> BuildConfig:
    return BuildConfig.from_settings(urdf_path=arm.urdf_path, scene=Scene(top_y_m=d_m), jobs=1, **options)


def least_end_pose_clearance_m(arm: PlanarArm, d_m: float, length_range_m=RANGES[0], width_range_m=RANGES[1]) -> float:
    """The least clearance of the poses at P1 and P5 over the build's grid, computed as the
    build's end_pose_collisions does [m]."""
    problems = grid_problems(arm, Scene(top_y_m=d_m), FitnessConfig(), DEFAULT.family, length_range_m, width_range_m)
    return min(
        float(p.clearance_at(np.array([p.context.theta_start_rad, p.context.theta_end_rad])).min()) for p in problems
    )


def test_the_test_urdf_has_the_new_link_lengths(arm_040: PlanarArm) -> None:
    assert arm_040.link_lengths_m == pytest.approx((0.40, 0.30), abs=1e-12)
    assert arm_040.reach_m == pytest.approx((0.10, 0.70), abs=1e-12)


def test_the_window_of_a_040_030_arm(window_040: SceneWindow) -> None:
    # Above: P1 = (L/2 + 0.12, d) of the longest obstacle leaves the 0.70 m reach.
    assert window_040.high_m == pytest.approx(math.sqrt(0.70**2 - 0.27**2), abs=EDGE_TOLERANCE_M)
    assert window_040.high_reason.kind == REACH and window_040.high_reason.point_name == "P1"
    assert window_040.high_reason.length_m == pytest.approx(0.30, abs=1e-12)
    # Below: the pose at P5 comes within the margin of the widest obstacle.
    assert 0.62 < window_040.low_m < 0.63
    assert window_040.low_reason.kind == END_POSE and window_040.low_reason.point_name == "P5"
    assert window_040.low_reason.value_m < 0.01
    assert window_040.low_m <= window_040.recommended_m <= window_040.high_m
    assert window_040.recommended_m == pytest.approx(0.635, abs=1e-12)  # the middle, on a 5 mm step
    assert window_040.recommended_clearance_m >= 0.01
    assert not window_040.shrunk and window_040.length_range_m == RANGES[0]
    text = "\n".join(window_040.lines())
    assert "P1 at 0.7000 m from the base is outside the arm's reach" in text and "recommended d = 0.635 m" in text


def test_edges_are_tight_against_the_build_pre_check(arm_040: PlanarArm, window_040_no_collision) -> None:
    window = window_040_no_collision
    for d in (window.low_m, window.recommended_m, window.high_m):
        check_before_work(config_for(arm_040, d), arm_040)  # passes
    for reason in (window.low_reason, window.high_reason):
        assert reason.d_m not in (window.low_m, window.high_m)
        assert min(abs(reason.d_m - window.low_m), abs(reason.d_m - window.high_m)) <= window.tolerance_m
    with pytest.raises(UnreachableObstacleError) as above:
        check_before_work(config_for(arm_040, window.high_reason.d_m), arm_040)
    assert above.value.point_name == "P1"
    with pytest.raises(InfeasibleSceneError) as below:
        check_before_work(config_for(arm_040, window.low_reason.d_m), arm_040)
    assert below.value.point_name == window.low_reason.point_name == "P5"
    # The user's tries: 0.60 and 0.50 collide at P5, 0.65 leaves the reach, 0.63 builds.
    assert window.low_m > 0.60 and window.high_m < 0.65 and window.low_m <= 0.63 <= window.high_m


def test_the_margin_edge_is_tight_on_the_end_poses(arm_040: PlanarArm, window_040: SceneWindow) -> None:
    assert least_end_pose_clearance_m(arm_040, window_040.low_m) >= 0.01
    assert least_end_pose_clearance_m(arm_040, window_040.low_reason.d_m) < 0.01
    assert window_040.low_m - window_040.low_reason.d_m <= window_040.tolerance_m
    assert least_end_pose_clearance_m(arm_040, window_040.recommended_m) == pytest.approx(
        window_040.recommended_clearance_m, abs=1e-12
    )


def test_the_paper_arm_keeps_its_d_for_the_pre_check_but_not_for_the_margin(arm: PlanarArm) -> None:
    """d = 0.56 m passes the build's pre-check (the default build), but at W near 0.12 m its end
    poses come within the margin (a known limit of the default build)."""
    no_collision = scene_window(arm, Scene(), *RANGES, settings=WindowSettings(end_pose_clearance_m=0.0))
    assert no_collision.low_m < 0.56 < no_collision.high_m
    margin = scene_window(arm, Scene(), *RANGES)
    assert margin.low_m > 0.56 and margin.low_reason.width_m == pytest.approx(0.12, abs=1e-12)
    assert least_end_pose_clearance_m(arm, 0.56) < 0.01


def test_a_narrow_window_shrinks_the_length_range(folder: Path, urdf_with_links) -> None:
    """l1 = 0.30, l2 = 0.28: over the default range the window is about 5 mm wide (its build does
    not converge); the widest L range that leaves at least 1 cm is searched for."""
    arm = load_planar_arm(urdf_with_links(folder, 0.30, 0.28))
    assert arm.link_lengths_m == pytest.approx((0.30, 0.28), abs=1e-12)
    narrow = scene_window(arm, Scene(), *RANGES, settings=WindowSettings(shrink=False))
    assert narrow.narrow and 0.004 < narrow.width_m < 0.006 and not narrow.shrunk
    assert narrow.lines()[-1].startswith("caution: the window is only 5.1 mm wide (< 10 mm)")
    window = scene_window(arm, Scene(), *RANGES)
    assert window.shrunk and not window.narrow and window.width_m >= 0.01
    assert window.requested_window_m == pytest.approx((narrow.low_m, narrow.high_m), abs=1e-12)
    assert window.width_range_m == RANGES[1]
    low, high = window.length_range_m
    assert low == RANGES[0][0] and 0.5 * (RANGES[0][1] - RANGES[0][0]) - 1e-12 <= high - low < 0.1
    assert window.low_m <= window.recommended_m <= window.high_m
    assert "is only 5.1 mm wide (< 10 mm): the range is shrunk" in window.lines()[0]
    check_before_work(config_at(config_for(arm, 0.56), window), arm)  # passes over the shrunk range
    # The next wider L range leaves less than 1 cm.
    wider = scene_window(arm, Scene(), (low, high + 0.01), RANGES[1], settings=WindowSettings(shrink=False))
    assert wider.narrow


def test_a_025_025_arm_is_refused_though_slivers_of_the_range_fit(folder: Path, urdf_with_links) -> None:
    arm = load_planar_arm(urdf_with_links(folder, 0.25, 0.25))
    with pytest.raises(NoSceneWindowError) as refused:
        scene_window(arm, Scene(), *RANGES)
    assert refused.value.shrink_tried and "the arm's pose at P5 collides" in str(refused.value)
    sliver = scene_window(arm, Scene(), (0.20, 0.25), RANGES[1], settings=WindowSettings(shrink=False))
    assert sliver.narrow  # 4 mm: not offered


def test_a_025_020_arm_is_refused_naming_the_end_pose_where_the_reach_allows(folder: Path, urdf_with_links) -> None:
    """P3 = (0, d - W - 0.10) needs d >= 0.12 + 0.10 + 0.05 = 0.27 m, P1 = (0.27, d) at L = 0.30
    needs d <= sqrt(0.45^2 - 0.27^2) = 0.36 m; in between the pose at P5 collides, and no L or W
    range of at least half the default's lets it pass."""
    arm = load_planar_arm(urdf_with_links(folder, 0.25, 0.20))
    assert arm.link_lengths_m == pytest.approx((0.25, 0.20), abs=1e-12)
    with pytest.raises(NoSceneWindowError) as refused:
        scene_window(arm, Scene(), *RANGES)
    message = str(refused.value)
    assert "(P3 below and P1 above it)" in message and "the arm's pose at P5 collides" in message
    assert refused.value.lowest_m == pytest.approx(0.27, abs=0.0025)  # to the scan's step
    assert refused.value.highest_m == pytest.approx(0.36, abs=0.0025)
    narrow = scene_window(arm, Scene(), (0.20, 0.22), RANGES[1], settings=WindowSettings(shrink=False))  # a sliver
    assert narrow.high_m - narrow.low_m < 0.005


def test_a_010_010_arm_is_refused_naming_p1_quickly(folder: Path, urdf_with_links) -> None:
    arm = load_planar_arm(urdf_with_links(folder, 0.10, 0.10))
    started = time.perf_counter()
    with pytest.raises(NoSceneWindowError) as refused:
        scene_window(arm, Scene(), *RANGES)
    assert time.perf_counter() - started < 5.0
    message = str(refused.value)
    assert "no d brings P1 of every obstacle into the arm's reach" in message and "\n" not in message
    assert refused.value.shrink_tried and refused.value.lowest_m is None and refused.value.highest_m is None


def test_reach_constraints_that_contradict_each_other_are_named_with_their_bounds(
    folder: Path, urdf_with_links
) -> None:
    """l1 = 0.45, l2 = 0.10: P3 = (0, d - W - 0.10) needs d >= 0.12 + 0.10 + 0.35 = 0.57 m, P1 =
    (0.27, d) at L = 0.30 needs d <= sqrt(0.55^2 - 0.27^2) = 0.4792 m."""
    arm = load_planar_arm(urdf_with_links(folder, 0.45, 0.10))
    with pytest.raises(NoSceneWindowError) as refused:
        scene_window(arm, Scene(), *RANGES)
    assert refused.value.lowest_m == pytest.approx(0.57, abs=EDGE_TOLERANCE_M)
    assert refused.value.highest_m == pytest.approx(math.sqrt(0.55**2 - 0.27**2), abs=EDGE_TOLERANCE_M)
    assert "P3 needs d >= 0.57" in str(refused.value) and "P1 needs d <= 0.479" in str(refused.value)


def test_a_varied_x_narrows_the_window_and_passes_the_pre_check(arm_040: PlanarArm, window_040) -> None:
    settings = WindowSettings(centre_x_points=5, shrink=False)
    window = scene_window(arm_040, Scene(), *RANGES, (-0.03, 0.03), settings=settings)
    assert window.centre_x_range_m == (-0.03, 0.03)
    assert window_040.low_m - window.tolerance_m <= window.low_m <= window.high_m
    assert window.high_m <= window_040.high_m + window.tolerance_m
    assert window.high_m < window_040.high_m - 0.01  # P1 moved 3 cm out leaves the reach earlier
    check_before_work(config_for(arm_040, window.recommended_m, vary=(("x", -0.03, 0.03),)), arm_040)
    with pytest.raises(InvalidParameterError, match="constraint point P1"):  # --vary names the range
        check_before_work(config_for(arm_040, window.high_reason.d_m, vary=(("x", -0.03, 0.03),)), arm_040)


@pytest.mark.parametrize(
    ("low", "high", "expected"),
    [
        (0.6247, 0.6458, 0.635),
        (0.3843, 0.3868, 0.385),
        (0.3838, 0.3846, 0.384),
        (0.3841, 0.3847, 0.3844),
        (0.38411, 0.38419, 0.38415),
    ],
)
def test_the_recommended_value_is_the_middle_rounded_inside(low: float, high: float, expected: float) -> None:
    value = _rounded_middle(low, high, WindowSettings().rounding_m)
    assert low <= value <= high
    assert value == pytest.approx(expected, abs=1e-9)


def test_settings_ranges_and_results_are_checked(arm_040: PlanarArm, window_040: SceneWindow) -> None:
    with pytest.raises(InvalidParameterError, match="tolerance_m"):
        WindowSettings(tolerance_m=0.01)
    with pytest.raises(InvalidParameterError, match="end_pose_clearance_m"):
        WindowSettings(end_pose_clearance_m=-0.001)
    for lengths in ((0.30, 0.20), (0.0, 0.2), (math.nan, 0.3), (0.2,)):
        with pytest.raises(InvalidParameterError, match="L range"):
            scene_window(arm_040, Scene(), lengths, RANGES[1])
    with pytest.raises(InvalidParameterError, match="x range"):
        scene_window(arm_040, Scene(), *RANGES, (0.03, -0.03))
    fields = dict(window_040.__dict__)
    fields["recommended_m"] = window_040.high_m + 0.01
    with pytest.raises(InvalidParameterError, match="recommended_m"):
        SceneWindow(**fields)


def test_failures_read_as_one_phrase() -> None:
    reach = Failure(REACH, "P1", 0.646, 0.3, 0.08, 0.0, 0.70004, (0.1, 0.7))
    assert str(reach) == (
        "P1 at 0.7000 m from the base is outside the arm's reach [0.1000, 0.7000] m "
        "(L = 0.300 m, W = 0.080 m, d = 0.6460 m)"
    )
    assert reach.too_far and reach.excess_m == pytest.approx(4e-5, abs=1e-12)
    pose = Failure(END_POSE, "P5", 0.62, 0.2, 0.12, 0.02, -0.003, (0.01, math.inf))
    assert "the arm's pose at P5 collides with the obstacle" in str(pose) and "x = 0.020 m" in str(pose)
    assert not pose.too_far and pose.excess_m == pytest.approx(0.013, abs=1e-12)
    near = Failure(END_POSE, "P1", 0.62, 0.2, 0.12, 0.0, 0.00999, (0.01, math.inf))
    assert str(near) == (
        "the arm's pose at P1 keeps 9.99 mm from the obstacle, less than 10.00 mm "
        "(L = 0.200 m, W = 0.120 m, d = 0.6200 m)"
    )
