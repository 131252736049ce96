"""The region map over any axes (pipeline.certify.region_map): hand-built 2^k-trees and random
subpavings cut one axis at a time, whose lookups (scalar and vectorised) agree with a brute-force
search over the leaves' boxes, at random points, on cell faces and outside the box; the JSON
round trip; maps of the earlier 2^k-tree formats read with every number; and the refusal of
malformed maps and of a wrong number of values."""

from __future__ import annotations

import dataclasses
import itertools
import json

import numpy as np
import pytest

from pipeline.certify.map_files import load_region_map
from pipeline.certify.region_map import FORMAT_JSON, STATUSES, RegionMap, save_region_map_json
from pipeline.exceptions import DataFileError, InvalidParameterError, OutOfFittedRangeError

L_RANGE, W_RANGE, X_RANGE, D_RANGE = (0.2, 0.3), (0.08, 0.12), (-0.03, 0.03), (0.5, 0.6)
RANGES = {"L": L_RANGE, "W": W_RANGE, "x": X_RANGE, "d": D_RANGE}
SHA = "cd" * 32

Node = tuple[int, tuple[int, ...]]


def uniform(depth: int, k: int) -> list[Node]:
    """Every node of one depth of a 2^k-tree."""
    return [(depth, index) for index in itertools.product(range(2**depth), repeat=k)]


def refine(nodes: list[Node], node: Node) -> list[Node]:
    """``nodes`` with ``node`` replaced by its 2^k children."""
    depth, index = node
    children = [
        (depth + 1, tuple(2 * i + b for i, b in zip(index, bits, strict=True)))
        for bits in itertools.product((0, 1), repeat=len(index))
    ]
    return [n for n in nodes if n != node] + children


def chain(nodes: list[Node], node: Node, depth: int, child: int) -> list[Node]:
    """``nodes`` with ``node`` refined, then its child number ``child``, ..., down to ``depth``."""
    k = len(node[1])
    while node[0] < depth:
        nodes = refine(nodes, node)
        bits = [(child >> (k - 1 - a)) & 1 for a in range(k)]
        node = (node[0] + 1, tuple(2 * i + b for i, b in zip(node[1], bits, strict=True)))
    return nodes


def make_map(nodes: list[Node], axes: tuple[str, ...] = ("L", "W", "x"), levels=None, **changes) -> RegionMap:
    """A map over ``axes`` with leaves ``nodes`` (every axis at the node's depth, unless
    ``levels`` (n, k) says otherwise); leaf i has clearance bound 1e-4 i [m] and status i mod 4."""
    depth = np.array([d for d, _ in nodes])
    index = np.array([i for _, i in nodes])
    n = depth.size
    fields = dict(
        family="paper",
        coefficients_source="test",
        coefficients_sha256=SHA,
        axes=axes,
        margin_m=0.01,
        endpoint_tolerance_m=0.002,
        clearance_bound_m=np.arange(n) * 1e-4,
        endpoint_bound_m=np.full(n, 1e-3) + np.arange(n) * 1e-6,
        endpoint_clearance_upper_m=np.full(n, 0.05),
        status=np.arange(n) % len(STATUSES),
    )
    fields.update(changes)
    ranges = fields.pop("ranges_m", tuple(RANGES.get(name, X_RANGE) for name in axes))
    levels = np.repeat(depth[:, None], index.shape[1], axis=1) if levels is None else levels
    return RegionMap.of_leaves(ranges, levels, index, **fields)


def boxes(region_map: RegionMap) -> tuple[np.ndarray, np.ndarray]:
    """Every leaf's closed box (lo (n, k), hi (n, k)) [m], computed here from the leaves' levels and indices."""
    ranges = np.array([RANGES[name] for name in region_map.axes])
    index = region_map.subpaving.indices
    cells = 2.0**region_map.subpaving.levels
    span = ranges[:, 1] - ranges[:, 0]
    return ranges[:, 0] + span * index / cells, ranges[:, 0] + span * (index + 1) / cells


def brute_force(region_map: RegionMap, points: np.ndarray, slack: float = 0.0) -> np.ndarray:
    """(m, n): which leaves' boxes (widened by ``slack`` [m]) hold each point."""
    lo, hi = boxes(region_map)
    return np.all((points[:, None, :] >= lo[None] - slack) & (points[:, None, :] <= hi[None] + slack), -1)


@pytest.fixture(scope="module")
def refined() -> RegionMap:
    """The uniform octree of depth 2 with one node cut into eight and one of those again (78 leaves)."""
    nodes = refine(uniform(2, 3), (2, (1, 2, 3)))
    return make_map(refine(nodes, (3, (3, 4, 6))))


@pytest.fixture(scope="module")
def deep() -> RegionMap:
    """An octree cut down to depth 10 along two chains: deeper than the dense index's level."""
    nodes = chain(uniform(1, 3), (1, (0, 1, 1)), 10, 5)
    return make_map(chain(nodes, (1, (1, 0, 0)), 9, 2))


@pytest.fixture(scope="module")
def one_axis(random_leaves) -> RegionMap:
    """400 random cuts of one axis at a time over (L, W, x, d): leaves of every shape."""
    levels, indices = random_leaves(4, 400, np.random.default_rng(5))
    nodes = [(0, tuple(int(i) for i in index)) for index in indices]
    return make_map(nodes, axes=("L", "W", "x", "d"), levels=levels)


@pytest.fixture(scope="module")
def four_axes() -> RegionMap:
    """A 16-tree over (L, W, x, d), cut down to depth 7 (deeper than its dense index's level)."""
    return make_map(chain(uniform(1, 4), (1, (1, 0, 1, 1)), 7, 9), axes=("L", "W", "x", "d"))


def random_points(region_map: RegionMap, count: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    ranges = np.array([RANGES[name] for name in region_map.axes])
    return rng.uniform(ranges[:, 0], ranges[:, 1], (count, ranges.shape[0]))


def deep_points(region_map: RegionMap, count: int, seed: int) -> np.ndarray:
    """Random points inside the deepest leaves (so that the lookups descend all the way)."""
    rng = np.random.default_rng(seed)
    lo, hi = boxes(region_map)
    depth = region_map.subpaving.levels.sum(axis=1)
    deepest = np.flatnonzero(depth >= depth.max() - 1)
    chosen = rng.choice(deepest, count)
    return rng.uniform(lo[chosen], hi[chosen])


@pytest.mark.parametrize("name", ["refined", "deep", "four_axes", "one_axis"])
def test_lookups_agree_with_a_brute_force_search(request, name) -> None:
    """At thousands of random points (uniform, and inside the deepest leaves) exactly one leaf's
    box holds the point, and every lookup finds that leaf."""
    region_map = request.getfixturevalue(name)
    points = np.vstack([random_points(region_map, 3000, 1), deep_points(region_map, 1000, 2)])
    holding = brute_force(region_map, points)
    assert np.all(holding.sum(1) == 1)
    expected = np.argmax(holding, 1)
    leaves = region_map.leaf_indices(*points.T)
    assert np.array_equal(leaves, expected)
    cells = region_map.cells_at(*points.T)
    assert np.array_equal(cells["leaf"], expected)
    assert np.array_equal(cells["clearance_bound_m"], region_map.clearance_bound_m[expected])
    assert np.array_equal(cells["status"], region_map.status[expected])
    for point, leaf in zip(points[::7].tolist(), expected[::7].tolist(), strict=True):
        assert region_map.leaf_at(*point) == leaf
        cell = region_map.cell_at(*point)
        assert cell == region_map.cell(leaf)
        assert region_map.bounds_at(*point) == (cell.clearance_bound_m, cell.endpoint_bound_m, cell.status)


def test_the_deep_maps_store_one_tree_node_per_leaf(deep, four_axes, one_axis) -> None:
    """Depth 10 over three axes (2^30 deepest cells) and 7 over four (2^28): the lookup's table holds
    one row of four numbers per internal node (n - 1 of them), and the points of the deepest
    leaves are found."""
    for region_map in (deep, four_axes, one_axis):
        tables = region_map.lookup_tables
        assert tables.index.size == 3 + 4 * (region_map.size - 1)
        depth = region_map.subpaving.levels.sum(axis=1)
        deepest = np.flatnonzero(depth == depth.max())
        centres = region_map.leaf_centres_m()[deepest]
        assert np.array_equal(region_map.leaf_indices(*centres.T), deepest)
        assert [region_map.leaf_at(*c) for c in centres.tolist()] == deepest.tolist()


@pytest.mark.parametrize("name", ["refined", "deep", "four_axes", "one_axis"])
def test_points_on_cell_faces_and_corners_find_a_leaf_that_holds_them(request, name) -> None:
    """Every corner of every leaf, and the box's corners: the scalar and the batch lookups find the
    same leaf, whose closed box holds the point (up to rounding)."""
    region_map = request.getfixturevalue(name)
    lo, hi = boxes(region_map)
    k = lo.shape[1]
    corners = np.array(
        [
            np.where(np.array(bits, dtype=bool), hi[leaf], lo[leaf])
            for leaf in range(lo.shape[0])
            for bits in itertools.product((0, 1), repeat=k)
        ]
    )
    leaves = region_map.leaf_indices(*corners.T)
    assert np.all(leaves >= 0)
    span = np.array([b - a for a, b in (RANGES[n] for n in region_map.axes)])
    holds = np.all((corners >= lo[leaves] - 1e-12 * span) & (corners <= hi[leaves] + 1e-12 * span), -1)
    assert holds.all()
    for point, leaf in zip(corners[::3].tolist(), leaves[::3].tolist(), strict=True):
        assert region_map.leaf_at(*point) == leaf
    ranges = [RANGES[n] for n in region_map.axes]
    top = region_map.leaf_at(*(hi for _, hi in ranges))
    bottom = region_map.leaf_at(*(lo for lo, _ in ranges))
    assert np.all(hi[top] == [h for _, h in ranges]) and np.all(lo[bottom] == [lo_ for lo_, _ in ranges])


def test_points_outside_the_box_are_refused_by_axis(refined) -> None:
    centre = [sum(RANGES[n]) / 2 for n in refined.axes]
    for axis, name in enumerate(refined.axes):
        for outside in (np.nextafter(RANGES[name][0], -1.0), np.nextafter(RANGES[name][1], 1.0), np.nan):
            point = list(centre)
            point[axis] = outside
            assert refined.leaf_at(*point) is None and refined.bounds_at(*point) is None
            assert refined.leaf_indices(*np.array([point, centre]).T).tolist()[0] == -1
            cells = refined.cells_at(*np.array([point, centre]).T)
            assert cells["leaf"][0] == -1 and cells["status"][0] == -1 and np.isnan(cells["clearance_bound_m"][0])
            assert cells["leaf"][1] >= 0
            with pytest.raises(OutOfFittedRangeError) as info:
                refined.cell_at(*point)
            assert info.value.name == name and f"{name} = " in str(info.value)


def test_a_wrong_number_of_values_is_refused_by_name(refined) -> None:
    L, W, x = 0.25, 0.1, 0.0
    for call in (refined.leaf_at, refined.bounds_at, refined.cell_at, refined.leaf_indices, refined.cells_at):
        with pytest.raises(InvalidParameterError, match="x is missing") as info:
            call(L, W)
        assert info.value.name == "x"
        with pytest.raises(InvalidParameterError, match="beyond the map's axes"):
            call(L, W, x, 0.55)
    over_lw = make_map(uniform(2, 2), axes=("L", "W"))
    for call in (over_lw.leaf_at, over_lw.bounds_at, over_lw.cell_at, over_lw.leaf_indices, over_lw.cells_at):
        with pytest.raises(InvalidParameterError, match="axes are L, W only"):
            call(L, W, x)
    assert over_lw.leaf_at(L, W) == over_lw.leaf_indices(L, W)


def test_the_batch_lookup_broadcasts_and_keeps_the_shape(refined) -> None:
    L = np.linspace(0.2, 0.3, 12).reshape(3, 4)
    leaves = refined.leaf_indices(L, 0.1, -0.01)
    assert leaves.shape == (3, 4)
    assert leaves.ravel().tolist() == [refined.leaf_at(v, 0.1, -0.01) for v in L.ravel().tolist()]


def test_cells_sizes_centres_and_volume_fractions(refined) -> None:
    lo, hi = boxes(refined)
    sizes, centres = refined.leaf_sizes_m(), refined.leaf_centres_m()
    assert sizes.shape == centres.shape == (refined.size, 3)
    assert np.allclose(sizes, hi - lo, rtol=1e-12, atol=0) and np.allclose(centres, (lo + hi) / 2, rtol=1e-12, atol=0)
    for leaf in (0, 40, refined.size - 1):
        cell = refined.cell(leaf)
        assert len(cell.ranges_m) == 3 and cell.axes == ("L", "W", "x")
        for axis, name in enumerate(cell.axes):
            assert cell.range_of(name) == pytest.approx((lo[leaf, axis], hi[leaf, axis]), abs=1e-15)
    # 63 leaves of 1/64, 7 of 1/512, 8 of 1/4096: volume fractions, not area fractions.
    assert sorted(set(refined.area.tolist())) == [2.0**-12, 2.0**-9, 2.0**-6]
    summary = refined.summary()
    assert summary["axes"] == ["L", "W", "x"]
    expected = {name: float(np.sum(refined.area[refined.status == k])) for k, name in enumerate(STATUSES)}
    assert summary["area_fraction"] == pytest.approx(expected, abs=1e-15)
    assert sum(summary["area_fraction"].values()) == pytest.approx(1.0, abs=1e-12)
    assert summary["worst_cell"]["x_m"] == list(refined.cell(0).range_of("x"))  # leaf 0 has the lowest bound
    assert make_map(uniform(1, 2), axes=("L", "W")).summary()["axes"] == ["L", "W"]


def test_belongs_to_checks_the_axes(refined) -> None:
    class Coefficients:
        source_sha256 = SHA

        class variables:  # stands in for a Variables
            names = ("L", "W", "x")

    assert refined.belongs_to(Coefficients())
    Coefficients.variables.names = ("L", "W")
    assert not refined.belongs_to(Coefficients())
    assert make_map(uniform(1, 2), axes=("L", "W")).belongs_to(Coefficients())


@pytest.mark.parametrize("name", ["refined", "four_axes", "one_axis"])
def test_the_json_round_trip_keeps_the_map_and_its_bytes(request, name, tmp_path) -> None:
    region_map = request.getfixturevalue(name)
    first = tmp_path / "map.json"
    digest = save_region_map_json(region_map, first)
    document = json.loads(first.read_text())
    assert document["format"] == FORMAT_JSON and document["axes"] == list(region_map.axes)
    assert len(document["cells"]["cut_axis"]) == region_map.size - 1
    for name_ in region_map.axes:
        assert document["fitted_range"][name_] == list(RANGES[name_])
    again = load_region_map(first)
    assert again.axes == region_map.axes and again.ranges_m == region_map.ranges_m
    for column in ("clearance_bound_m", "endpoint_bound_m", "status"):
        assert np.array_equal(getattr(again, column), getattr(region_map, column))
    assert np.array_equal(again.subpaving.levels, region_map.subpaving.levels)
    assert np.array_equal(again.subpaving.indices, region_map.subpaving.indices)
    assert save_region_map_json(again, tmp_path / "again.json") == digest
    assert (tmp_path / "again.json").read_bytes() == first.read_bytes()
    points = random_points(region_map, 500, 3)
    assert np.array_equal(again.leaf_indices(*points.T), region_map.leaf_indices(*points.T))


def test_a_map_of_the_earlier_2k_tree_format_keeps_every_number(tmp_path) -> None:
    """A format /2 document over (L, W) (a depth per leaf, halvings of W by split_W) and a /3
    document over (L, W, x) (an index column per axis): read into the same leaves, every bound kept."""
    cells = [(1, 0, 0, 0), (1, 1, 0, 0)] + [(2, i, j, 0) for i in range(4) for j in (2, 3) if (i, j) != (0, 3)]
    cells += [(2, 0, 6, 1), (2, 0, 7, 1)]
    d, il, iw, e = (np.array(column) for column in zip(*cells, strict=True))
    n = d.size
    bounds = np.arange(n) * 1e-3 - 0.001
    old = {
        "format": "twolink-region-map/2",
        "coefficients": {"source": "test", "sha256": "ab" * 32, "family": "paper"},
        "fitted_range": {"L": list(L_RANGE), "W": list(W_RANGE)},
        "margin_m": 0.01,
        "endpoint_tolerance_m": 0.002,
        "details": {"note": 1},
        "cells": {
            "depth": d.tolist(),
            "index_L": il.tolist(),
            "index_W": iw.tolist(),
            "split_W": e.tolist(),
            "clearance_bound_m": bounds.tolist(),
            "endpoint_bound_m": (np.arange(n) * 1e-4).tolist(),
            "endpoint_clearance_upper_m": [None] * n,
            "status": [STATUSES[k % 4] for k in range(n)],
        },
    }
    path = tmp_path / "strips.json"
    path.write_text(json.dumps(old))
    again = load_region_map(path)
    assert again.axes == ("L", "W") and again.details == {"note": 1}
    assert np.array_equal(again.subpaving.levels, np.column_stack([d, d + e]))
    assert np.array_equal(again.subpaving.indices, np.column_stack([il, iw]))
    assert np.array_equal(again.clearance_bound_m, bounds) and np.all(np.isinf(again.endpoint_clearance_upper_m))
    assert again.cell(n - 1).range_of("W") == pytest.approx((0.115, 0.12))
    nodes = refine(uniform(2, 3), (2, (1, 2, 3)))
    depth = np.array([dd for dd, _ in nodes])
    index = np.array([i for _, i in nodes])
    octree = {
        **{key: value for key, value in old.items() if key != "cells"},
        "format": "twolink-region-map/3",
        "axes": ["L", "W", "x"],
        "fitted_range": {"L": list(L_RANGE), "W": list(W_RANGE), "x": list(X_RANGE)},
        "cells": {
            "depth": depth.tolist(),
            **{f"index_{name}": index[:, a].tolist() for a, name in enumerate("LWx")},
            **{name: [0.0] * depth.size for name in ("clearance_bound_m", "endpoint_bound_m")},
            "endpoint_clearance_upper_m": [0.05] * depth.size,
            "status": ["margin"] * depth.size,
        },
    }
    path.write_text(json.dumps(octree))
    again = load_region_map(path)
    assert np.array_equal(again.subpaving.levels, np.repeat(depth[:, None], 3, axis=1))
    assert np.array_equal(again.subpaving.indices, index)


def test_malformed_documents_are_refused(refined, tmp_path) -> None:
    document = refined.to_json()
    path = tmp_path / "bad.json"
    for damage, message in (
        (lambda doc: doc["cells"].pop("cut_axis"), "cut_axis"),
        (lambda doc: doc["fitted_range"].pop("x"), "x"),
        (lambda doc: doc.update(axes=["L", "W", "y"]), "axes"),
        (lambda doc: doc["cells"]["children"].__setitem__(0, [1, 1]), "tree"),
        (lambda doc: doc["cells"]["cut_axis"].__setitem__(0, 3), "tree"),
        (lambda doc: doc["cells"]["status"].pop(), "cells"),
        (lambda doc: doc.update(format="twolink-region-map/9"), "format"),
    ):
        damaged = json.loads(json.dumps(document))
        damage(damaged)
        path.write_text(json.dumps(damaged))
        with pytest.raises(DataFileError, match=message):
            load_region_map(path)


def test_invalid_maps_are_refused_naming_the_value(refined) -> None:
    nodes = refine(uniform(2, 3), (2, (1, 2, 3)))
    for changes, match in (
        ({"axes": ("W", "L", "x")}, "axes"),
        ({"axes": ("L", "W", "y")}, "axes"),
        ({"axes": ("L", "W", "x", "x")}, "axes"),
        ({"axes": ("L", "W", "d", "x"), "ranges_m": (L_RANGE, W_RANGE, D_RANGE, X_RANGE)}, "axes"),
        ({"ranges_m": (L_RANGE, W_RANGE)}, "cells"),
        ({"ranges_m": (L_RANGE, W_RANGE, (0.03, -0.03))}, "ranges"),
        ({"ranges_m": (L_RANGE, W_RANGE, (np.nan, 0.03))}, "ranges"),
        ({"levels": np.full((len(nodes), 3), 31)}, "level"),
        ({"levels": np.full((len(nodes), 3), 2)}, "cell indices"),
    ):
        with pytest.raises(InvalidParameterError, match=match):
            make_map(nodes, **changes)
    with pytest.raises(InvalidParameterError, match="overlaps"):
        make_map([*nodes, nodes[0]])
    with pytest.raises(InvalidParameterError, match="gaps"):
        make_map(nodes[1:])
    with pytest.raises(InvalidParameterError, match="cells"):  # an octree's leaves on two axes
        make_map(nodes, axes=("L", "W"))
    with pytest.raises(InvalidParameterError):
        dataclasses.replace(refined, status=np.full(refined.status.size, 7))
