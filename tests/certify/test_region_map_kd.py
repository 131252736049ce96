"""The region map over more axes than (L, W) (pipeline.certify.region_map): hand-built 2^k-trees
whose lookups (scalar and vectorised) agree with a brute-force search over the leaves' boxes, at
random points, on cell faces and outside the box; the /3 JSON round trip; the (L, W) files'
bytes unchanged; and the refusal of malformed maps and of a wrong number of values."""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json

import numpy as np
import pytest

from pipeline.certify.map_files import load_region_map
from pipeline.certify.region_map import FORMAT, FORMAT_KD, STATUSES, RegionMap, region_map_text, save_region_map_json
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


def make_map(nodes: list[Node], axes: tuple[str, ...] = ("L", "W", "x"), **changes) -> RegionMap:
    """A map over ``axes`` with leaves ``nodes``; leaf i has clearance bound 1e-4 i [m] and status i mod 4."""
    depth = np.array([d for d, _ in nodes])
    index = np.array([i for _, i in nodes])
    n = depth.size
    fields = dict(
        family="paper",
        coefficients_source="test",
        coefficients_sha256=SHA,
        length_range_m=L_RANGE,
        width_range_m=W_RANGE,
        margin_m=0.01,
        endpoint_tolerance_m=0.002,
        depth=depth,
        index_l=index[:, 0],
        index_w=index[:, 1],
        clearance_bound_m=np.arange(n) * 1e-4,
        endpoint_bound_m=np.full(n, 1e-3) + np.arange(n) * 1e-6,
        endpoint_clearance_upper_m=np.full(n, 0.05),
        status=np.arange(n) % len(STATUSES),
        axes=axes,
        extra_ranges_m=tuple(RANGES.get(name, X_RANGE) for name in axes[2:]),
        extra_index=index[:, 2:] if len(axes) > 2 else None,
    )
    fields.update(changes)
    return RegionMap(**fields)


def boxes(region_map: RegionMap) -> tuple[np.ndarray, np.ndarray]:
    """Every leaf's closed box (lo (n, k), hi (n, k)) [m], computed here from the nodes."""
    ranges = np.array([RANGES[name] for name in region_map.axes])
    index = np.column_stack(
        [region_map.index_l, region_map.index_w, *(() if region_map.extra_index is None else [region_map.extra_index])]
    )
    cells = 2.0 ** region_map.depth[:, None]
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
    deepest = np.flatnonzero(region_map.depth >= region_map.depth.max() - 1)
    chosen = rng.choice(deepest, count)
    return rng.uniform(lo[chosen], hi[chosen])


@pytest.mark.parametrize("name", ["refined", "deep", "four_axes"])
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


def test_the_deep_maps_descend_below_a_dense_index_of_bounded_size(deep, four_axes) -> None:
    """Depth 10 over three axes (2^30 deepest cells) and 7 over four (2^28): the tables stay far
    below 64 MB, and the points of the deepest leaves are found (the descent below the dense level)."""
    for region_map in (deep, four_axes):
        k = len(region_map.axes)
        assert 2 ** (k * int(region_map.depth.max())) > 2**22
        assert region_map._index.nbytes + region_map._sub_index.nbytes <= 4 * 2**22 + 2**20
        deepest = np.flatnonzero(region_map.depth == region_map.depth.max())
        centres = region_map.leaf_centres_m()[deepest]
        assert np.array_equal(region_map.leaf_indices(*centres.T), deepest)
        assert [region_map.leaf_at(*c) for c in centres.tolist()] == deepest.tolist()


@pytest.mark.parametrize("name", ["refined", "deep", "four_axes"])
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
    assert sizes.shape == centres.shape == (refined.depth.size, 3)
    assert np.allclose(sizes, hi - lo, rtol=1e-12, atol=0) and np.allclose(centres, (lo + hi) / 2, rtol=1e-12, atol=0)
    for leaf in (0, 40, refined.depth.size - 1):
        cell = refined.cell(leaf)
        assert cell.length_range_m == pytest.approx((lo[leaf, 0], hi[leaf, 0]), abs=1e-15)
        assert cell.width_range_m == pytest.approx((lo[leaf, 1], hi[leaf, 1]), abs=1e-15)
        assert len(cell.extra_ranges_m) == 1
        assert cell.extra_ranges_m[0] == pytest.approx((lo[leaf, 2], hi[leaf, 2]), abs=1e-15)
    # 63 leaves of 1/64, 7 of 1/512, 8 of 1/4096: volume fractions, not area fractions.
    assert sorted(set(refined.area.tolist())) == [2.0**-12, 2.0**-9, 2.0**-6]
    summary = refined.summary()
    assert summary["axes"] == ["L", "W", "x"]
    expected = {name: float(np.sum(refined.area[refined.status == k])) for k, name in enumerate(STATUSES)}
    assert summary["area_fraction"] == pytest.approx(expected, abs=1e-15)
    assert sum(summary["area_fraction"].values()) == pytest.approx(1.0, abs=1e-12)
    assert summary["worst_cell"]["x_m"] == list(refined.cell(0).extra_ranges_m[0])  # leaf 0 has the lowest bound
    assert "axes" not in make_map(uniform(1, 2), axes=("L", "W")).summary()


def test_belongs_to_checks_the_axes(refined) -> None:
    class Coefficients:
        source_sha256 = SHA

        class variables:  # stands in for a Variables
            names = ("L", "W", "x")

    assert refined.belongs_to(Coefficients())
    Coefficients.variables.names = ("L", "W")
    assert not refined.belongs_to(Coefficients())
    assert make_map(uniform(1, 2), axes=("L", "W")).belongs_to(Coefficients())


@pytest.mark.parametrize("name", ["refined", "four_axes"])
def test_the_json_round_trip_keeps_the_map_and_its_bytes(request, name, tmp_path) -> None:
    region_map = request.getfixturevalue(name)
    first = tmp_path / "map.json"
    digest = save_region_map_json(region_map, first)
    document = json.loads(first.read_text())
    assert document["format"] == FORMAT_KD and document["axes"] == list(region_map.axes)
    assert "split_W" not in document["cells"]
    for axis, extra in enumerate(region_map.axes[2:]):
        assert document["cells"][f"index_{extra}"] == region_map.extra_index[:, axis].tolist()
        assert document["fitted_range"][extra] == list(RANGES[extra])
    again = load_region_map(first)
    assert again.axes == region_map.axes and again.extra_ranges_m == region_map.extra_ranges_m
    for column in ("depth", "index_l", "index_w", "extra_index", "clearance_bound_m", "endpoint_bound_m", "status"):
        assert np.array_equal(getattr(again, column), getattr(region_map, column))
    assert save_region_map_json(again, tmp_path / "again.json") == digest
    assert (tmp_path / "again.json").read_bytes() == first.read_bytes()
    points = random_points(region_map, 500, 3)
    assert np.array_equal(again.leaf_indices(*points.T), region_map.leaf_indices(*points.T))


def test_a_map_over_l_w_writes_the_same_bytes_as_before(tmp_path) -> None:
    """The strip map of tests/certify/test_range_map.py, with the bounds below: its file is
    format /2, without the fields of more axes, byte for byte the one written before maps had axes
    (sha256 recorded then)."""
    cells = [(1, 0, 0, 0), (1, 1, 0, 0)] + [(2, i, j, 0) for i in range(4) for j in (2, 3) if (i, j) != (0, 3)]
    cells += [(2, 0, 6, 1), (2, 0, 7, 1)]
    d, il, iw, e = (np.array(column) for column in zip(*cells, strict=True))
    n = d.size
    strips = RegionMap(
        family="paper",
        coefficients_source="test",
        coefficients_sha256="ab" * 32,
        length_range_m=L_RANGE,
        width_range_m=W_RANGE,
        margin_m=0.01,
        endpoint_tolerance_m=0.002,
        depth=d,
        index_l=il,
        index_w=iw,
        clearance_bound_m=np.arange(n) * 1e-3 - 0.001,
        endpoint_bound_m=np.arange(n) * 1e-4,
        endpoint_clearance_upper_m=np.full(n, np.inf),
        status=np.arange(n) % 4,
        split_w=e,
        details={"note": 1},
    )
    text = region_map_text(strips)
    assert (
        hashlib.sha256(text.encode()).hexdigest() == "c339098e3a184a8fca0e988836692c827c8397bceff54251e70abfbddc391659"
    )
    document = json.loads(text)
    assert document["format"] == FORMAT and "axes" not in document and "axes" not in document["summary"]
    path = tmp_path / "strips.json"
    save_region_map_json(strips, path)
    again = load_region_map(path)
    assert again.axes == ("L", "W") and again.extra_index is None and again.extra_ranges_m == ()
    assert region_map_text(again) == text
    assert again.cell(0).extra_ranges_m == ()
    assert again.leaf_sizes_m().shape == (n, 2)


def test_malformed_documents_are_refused(refined, tmp_path) -> None:
    document = refined.to_json()
    path = tmp_path / "bad.json"
    for damage, message in (
        (lambda doc: doc["cells"].pop("index_x"), "index_x"),
        (lambda doc: doc["fitted_range"].pop("x"), "fitted_range lacks"),
        (lambda doc: doc.update(axes=["L", "W", "y"]), "axes"),
        (lambda doc: doc["cells"]["index_x"].__setitem__(0, 4), "extra_index of x"),
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
        ({"axes": ("L", "W", "d", "x"), "extra_ranges_m": (D_RANGE, X_RANGE)}, "axes"),
        ({"extra_ranges_m": ()}, "extra_ranges_m"),
        ({"extra_ranges_m": ((0.03, -0.03),)}, "extra_ranges_m of x"),
        ({"extra_ranges_m": ((np.nan, 0.03),)}, "extra_ranges_m of x"),
        ({"extra_index": None}, "extra_index"),
        ({"split_w": np.ones(len(nodes), dtype=int)}, "split_w"),
        ({"depth": np.full(len(nodes), 21)}, "depth"),
    ):
        with pytest.raises(InvalidParameterError, match=match):
            make_map(nodes, **changes)
    with pytest.raises(InvalidParameterError, match="extra_index"):
        make_map(nodes, extra_index=np.zeros((len(nodes), 2), dtype=int))
    with pytest.raises(InvalidParameterError, match="extra_index"):
        make_map(uniform(1, 2), axes=("L", "W"), extra_index=np.zeros((4, 1), dtype=int))
    with pytest.raises(InvalidParameterError):  # L, W indices of an octree as a quadtree's
        make_map(nodes, axes=("L", "W"))
    with pytest.raises(InvalidParameterError):
        dataclasses.replace(refined, status=np.full(refined.status.size, 7))


def test_gaps_and_overlaps_are_refused_even_when_the_volumes_add_up() -> None:
    """A leaf given twice in place of another of the same size, a leaf beside its own children in
    place of as much volume elsewhere, at the dense level and below it: each refused."""
    nodes = refine(uniform(2, 3), (2, (1, 2, 3)))
    with pytest.raises(InvalidParameterError, match="cells"):
        make_map(uniform(2, 3) + [(2, (0, 0, 0))])  # volume 65/64
    twice = [n for n in nodes if n != (2, (0, 0, 0))] + [(2, (0, 0, 1))]
    with pytest.raises(InvalidParameterError, match=r"overlaps|gaps"):
        make_map(twice)
    parent = [n for n in nodes if n != (2, (3, 3, 3))] + [(2, (1, 2, 3))]
    with pytest.raises(InvalidParameterError, match="overlaps"):
        make_map(parent)
    deep_nodes = chain(uniform(1, 3), (1, (0, 1, 1)), 10, 5)
    leaf = max(deep_nodes)  # a leaf at depth 10
    swapped = [n for n in deep_nodes if n != leaf] + [(10, tuple(i ^ 1 for i in leaf[1]))]
    with pytest.raises(InvalidParameterError, match=r"overlaps|gaps"):
        make_map(swapped)
    with pytest.raises(InvalidParameterError, match="overlaps"):  # 2^-30 more volume: within rounding
        make_map([*deep_nodes, leaf])
    tenth = sorted(n for n in deep_nodes if n[0] == 10)
    beside = [n for n in refine(deep_nodes, tenth[0]) if n != tenth[1]] + [tenth[0]]
    with pytest.raises(InvalidParameterError, match="overlaps"):  # a depth-10 leaf beside its children
        make_map(beside)
