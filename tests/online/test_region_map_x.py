"""A region map over (L, W, x) online: generate, generate_batch and generate_certified read the
bounds of the leaf holding (L, W, x) (a hand-built map whose leaves' bounds differ), a map over
other axes is refused, and the refusals (unreachable, no certified trajectory, not executable)
name x after L and W."""

from __future__ import annotations

import itertools
import pickle
from dataclasses import replace

import numpy as np
import pytest

from pipeline.certify.region_map import RegionMap
from pipeline.exceptions import (
    ExecutionRefusedError,
    NoCertifiedTrajectoryError,
    RegionMapMismatchError,
    UnreachableObstacleError,
)
from pipeline.offline.coefficients import Coefficients
from pipeline.offline.variables import Variables
from pipeline.online.batch import generate_batch
from pipeline.online.generator import generate
from pipeline.online.repair import RepairConfig, generate_certified

LWX = Variables(("L", "W", "x"))
X_RANGE = (-0.03, 0.03)
SHA = "ef" * 32


@pytest.fixture(scope="module")
def paper_x(paper, over_x) -> Coefficients:
    """The paper's Eq. 9 over (L, W, x) with small x terms, and a sha256 for maps to link to."""
    return replace(over_x(paper, X_RANGE, seed=1, scale=0.02), source_sha256=SHA)


def octree(leaf_map, coefficients: Coefficients, axes: tuple[str, ...] = ("L", "W", "x")) -> RegionMap:
    """The uniform octree of depth 2 over the fitted box with its node (1, 2, 3) cut in eight
    (71 leaves); leaf i has clearance bound 20 mm + 0.1 mm i, endpoint bound 1 mm, status margin
    for even i, collision_free for odd i."""
    k = len(axes)
    nodes = [(2, i) for i in itertools.product(range(4), repeat=k) if i != (1, 2, 3)[:k]]
    nodes += [
        (3, tuple(2 * a + b for a, b in zip((1, 2, 3), bits, strict=False)))
        for bits in itertools.product((0, 1), repeat=k)
    ]
    depth = np.array([d for d, _ in nodes])
    index = np.array([i for _, i in nodes])
    n = depth.size
    extra = (X_RANGE,) if k > 2 else ()
    return leaf_map(coefficients, depth, index, 0.02 + 1e-4 * np.arange(n), np.arange(n) % 2, axes, extra)


@pytest.fixture(scope="module")
def map_x(paper_x, leaf_map) -> RegionMap:
    return octree(leaf_map, paper_x)


POINTS = [(0.25, 0.1, 0.02), (0.25, 0.1, -0.02), (0.21, 0.085, -0.03), (0.2, 0.12, 0.03), (0.235, 0.107, 0.019)]


@pytest.mark.parametrize(("L", "W", "x"), POINTS)
def test_generate_reads_the_leaf_holding_l_w_x(paper_x, map_x, L, W, x) -> None:
    leaf = map_x.leaf_at(L, W, x)
    cell = map_x.cell(leaf)
    assert cell.ranges_m[2][0] <= x <= cell.ranges_m[2][1]
    for answer in (
        generate(paper_x, L, W, x=x, region_map=map_x),
        generate(replace(paper_x, region_map=map_x), L, W, x=x),
    ):
        assert answer.certificate_source == "range"
        assert answer.certified_clearance_m == map_x.clearance_bound_m[leaf]
        assert answer.endpoint_error_bound_m == map_x.endpoint_bound_m[leaf]
        assert answer.range_status == ("margin", "collision_free")[leaf % 2]
        assert answer.variables == (("x", x),)


def test_the_bounds_follow_x_at_the_same_size(paper_x, map_x) -> None:
    """At one (L, W), obstacles at x = -0.02 and x = +0.02 lie in different leaves and get their bounds."""
    low, high = (generate(paper_x, 0.25, 0.1, x=x, region_map=map_x) for x in (-0.02, 0.02))
    assert map_x.leaf_at(0.25, 0.1, -0.02) != map_x.leaf_at(0.25, 0.1, 0.02)
    assert low.certified_clearance_m != high.certified_clearance_m


def test_outside_the_box_there_are_no_bounds(paper_x, map_x) -> None:
    answer = generate(paper_x, 0.25, 0.1, x=0.031, region_map=map_x, out_of_range="ignore")
    assert answer.extrapolated and answer.certificate_source is None and answer.certified_clearance_m is None
    assert generate(paper_x, 0.25, 0.1, x=0.02, region_map=None).certificate_source is None


def test_the_batch_reads_the_same_leaves(paper_x, map_x) -> None:
    rng = np.random.default_rng(4)
    L, W = rng.uniform(0.2, 0.3, 200), rng.uniform(0.08, 0.12, 200)
    x = rng.uniform(-0.035, 0.035, 200)  # some outside the fitted range
    batch = generate_batch(paper_x, L, W, x=x, region_map=map_x)
    inside = np.abs(x) <= 0.03
    assert np.array_equal(batch.leaf, np.where(inside, map_x.leaf_indices(L, W, x), -1))
    assert np.array_equal(batch.range_status[inside], map_x.status[batch.leaf[inside]])
    assert np.all(np.isnan(batch.certified_clearance_m[~inside]))
    for i in range(0, 200, 17):
        if inside[i]:
            answer = generate(paper_x, float(L[i]), float(W[i]), x=float(x[i]), region_map=map_x)
            assert batch.certified_clearance_m[i] == answer.certified_clearance_m
            assert batch.endpoint_error_bound_m[i] == answer.endpoint_error_bound_m
    assert generate_batch(paper_x, L, W, x=x, region_map=None).leaf is None


def test_a_map_over_other_axes_is_refused(paper, paper_x, map_x, leaf_map) -> None:
    over_lw = octree(leaf_map, paper_x, axes=("L", "W"))
    with pytest.raises(RegionMapMismatchError):
        generate(paper_x, 0.25, 0.1, x=0.0, region_map=over_lw)
    with pytest.raises(RegionMapMismatchError):
        generate_batch(paper_x, [0.25], [0.1], x=[0.0], region_map=over_lw)
    same_sha = replace(paper, source_sha256=SHA)
    with pytest.raises(RegionMapMismatchError):
        generate(same_sha, 0.25, 0.1, region_map=map_x)
    assert generate(same_sha, 0.25, 0.1, region_map=over_lw).certificate_source == "range"


def test_certify_or_repair_takes_a_margin_leaf_from_the_map(paper_x, map_x, arm) -> None:
    """In a leaf the map certifies to keep the margin the clearance is taken from it (no
    per-query certificate); the answer's obstacle is the one at x."""
    L, W, x = next(p for p in POINTS if map_x.leaf_at(*p) % 2 == 0)
    answer = generate_certified(
        paper_x, L, W, arm, x=x, region_map=map_x, config=RepairConfig(endpoint_tolerance_m=0.01)
    )
    assert answer.certificate is None and not answer.repaired
    assert answer.generated.certified_clearance_m == map_x.bounds_at(L, W, x)[0]
    assert answer.generated.obstacle.centre_x_m == x


def test_an_unreachable_obstacle_names_x(paper_x) -> None:
    with pytest.raises(UnreachableObstacleError) as info:
        generate(paper_x, 0.25, 0.1, x=0.5, out_of_range="ignore")
    assert str(info.value).startswith("L = 0.25 m, W = 0.1 m, x = 0.5 m: constraint point")
    assert info.value.variables == {"x": 0.5}


def test_no_certified_trajectory_names_x(paper_x, arm) -> None:
    config = RepairConfig(repair=False, margin_m=0.5)
    with pytest.raises(NoCertifiedTrajectoryError) as info:
        generate_certified(paper_x, 0.25, 0.1, arm, x=0.02, config=config)
    assert str(info.value).startswith("no certified trajectory for L = 0.2500 m, W = 0.1000 m, x = 0.0200 m: ")
    assert info.value.variables == {"x": 0.02}


def test_execution_refused_names_x(paper_x, map_x, arm) -> None:
    """Held to an endpoint tolerance of 0, the regression's answer (certified clear by the map's
    margin leaf) is refused for its endpoint error; the message names x."""
    L, W, x = next(p for p in POINTS if map_x.leaf_at(*p) % 2 == 0)
    config = RepairConfig(endpoint_tolerance_m=0.0)
    with pytest.raises(ExecutionRefusedError) as info:
        generate_certified(paper_x, L, W, arm, x=x, region_map=map_x, config=config)
    assert str(info.value).startswith(f"no executable trajectory for L = {L:.4f} m, W = {W:.4f} m, x = {x:.4f} m: ")
    assert info.value.variables == {"x": x}


@pytest.mark.parametrize(
    ("error", "plain"),
    [
        (
            NoCertifiedTrajectoryError(0.25, 0.1, 0.004, 0.01, "repair disabled", {"x": 0.02}),
            NoCertifiedTrajectoryError(0.25, 0.1, 0.004, 0.01, "repair disabled"),
        ),
        (
            ExecutionRefusedError(0.25, 0.1, "paper", ("a", "b"), {"x": 0.02}),
            ExecutionRefusedError(0.25, 0.1, "paper", ("a", "b")),
        ),
        (
            UnreachableObstacleError("P1", 0.7, (0.05, 0.65), (0.25, 0.1), {"x": np.float64(0.02)}),
            UnreachableObstacleError("P1", 0.7, (0.05, 0.65), (0.25, 0.1)),
        ),
    ],
)
def test_the_messages_name_x_only_when_given(error, plain) -> None:
    """With x the message has ", x = ... m" right after W; without, it is as it was; both survive a pickle."""
    message, without = str(error), str(plain)
    assert ", x = 0.02" in message and " m" in message.split(", x = ")[1][:8]
    assert message.replace(", x = 0.0200 m", "").replace(", x = 0.02 m", "") == without
    assert "x =" not in without and plain.variables == {}
    again = pickle.loads(pickle.dumps(error))
    assert str(again) == message and again.variables == error.variables
