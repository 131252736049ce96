"""The region map (pipeline.certify.region_map): lookups, JSON round trip, validation, the link to
the coefficients by sha256, and the CLI ``python -m pipeline.certify_range``."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from pipeline import load_coefficients
from pipeline.certify.map_files import load_region_map
from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
from pipeline.certify.region_map import STATUSES, RegionMap, save_region_map_json
from pipeline.commands.certify_range import main
from pipeline.exceptions import DataFileError, InvalidParameterError, OutOfFittedRangeError
from pipeline.io.jsonio import json_safe
from pipeline.offline.coefficients import save_coefficients


@pytest.fixture(scope="module")
def small_map() -> RegionMap:
    return certify_range(load_coefficients("paper"), RangeCertificateConfig(min_cell=1 / 16, boundary_cell=1 / 8))


def test_the_same_coefficients_give_the_same_map_bytes_with_any_worker_count(small_map: RegionMap, tmp_path) -> None:
    """The file holds no wall time and no worker count: a second certificate with two workers
    writes the same bytes; the map read back reports its time as unknown."""
    again = certify_range(
        load_coefficients("paper"), RangeCertificateConfig(min_cell=1 / 16, boundary_cell=1 / 8, jobs=2)
    )
    first, second = tmp_path / "one.json", tmp_path / "two.json"
    assert save_region_map_json(small_map, first) == save_region_map_json(again, second)
    assert first.read_bytes() == second.read_bytes()
    assert small_map.seconds > 0 and np.isnan(load_region_map(first).seconds)


def test_cell_at_and_batch_lookup_agree(small_map: RegionMap) -> None:
    rng = np.random.default_rng(0)
    L, W = rng.uniform(0.2, 0.3, 500), rng.uniform(0.08, 0.12, 500)
    batch = small_map.cells_at(L, W)
    for k in range(500):
        cell = small_map.cell_at(L[k], W[k])
        assert cell.range_of("L")[0] <= L[k] <= cell.range_of("L")[1]
        assert cell.range_of("W")[0] <= W[k] <= cell.range_of("W")[1]
        assert cell.clearance_bound_m == batch["clearance_bound_m"][k]
        assert STATUSES[batch["status"][k]] == cell.status
        # The generator's scalar lookup (flat index) finds the same leaf.
        assert small_map.bounds_at(L[k], W[k]) == (cell.clearance_bound_m, cell.endpoint_bound_m, cell.status)
    corners = small_map.cells_at(np.array([0.2, 0.3, 0.31]), np.array([0.08, 0.12, 0.1]))
    assert list(corners["leaf"][:2] >= 0) == [True, True] and corners["leaf"][2] == -1
    assert np.isnan(corners["clearance_bound_m"][2])
    with pytest.raises(OutOfFittedRangeError):
        small_map.cell_at(0.31, 0.1)
    assert small_map.bounds_at(0.31, 0.1) is None
    top = small_map.bounds_at(0.3, 0.12)  # the range's far corner belongs to the last leaf
    assert top is not None and top[0] == small_map.cell_at(0.3, 0.12).clearance_bound_m
    for value in ("0.25", None, np.array([0.25, 0.26])):  # not read as a number by the compiled lookup
        with pytest.raises(InvalidParameterError, match="W = "):
            small_map.bounds_at(0.25, value)


def test_json_round_trip_and_hash_link(small_map: RegionMap, tmp_path) -> None:
    path = tmp_path / "map.json"
    digest = save_region_map_json(small_map, path)
    assert len(digest) == 64
    again = load_region_map(path)
    for name in ("clearance_bound_m", "endpoint_bound_m", "status"):
        assert np.array_equal(getattr(again, name), getattr(small_map, name))
    assert np.array_equal(again.subpaving.levels, small_map.subpaving.levels)
    assert np.array_equal(again.subpaving.indices, small_map.subpaving.indices)
    assert again.summary()["area_fraction"] == small_map.summary()["area_fraction"]
    coefficients = load_coefficients("paper")
    assert again.belongs_to(coefficients)
    assert not again.belongs_to(dataclasses.replace(coefficients, source_sha256="0" * 64))


def test_summary_fractions_add_up(small_map: RegionMap) -> None:
    summary = small_map.summary()
    assert sum(summary["area_fraction"].values()) == pytest.approx(1.0)
    assert set(summary["area_fraction"]) == set(STATUSES)
    assert summary["clearance_bound_min_m"] == pytest.approx(float(np.min(small_map.clearance_bound_m)))


def test_malformed_maps_are_refused(small_map: RegionMap, tmp_path) -> None:
    document = small_map.to_json()
    document["cells"]["children"][0] = document["cells"]["children"][1]  # no longer a tree
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(document))
    with pytest.raises(DataFileError):
        load_region_map(path)
    path.write_text(json.dumps({"format": "something else"}))
    with pytest.raises(DataFileError):
        load_region_map(path)
    with pytest.raises(InvalidParameterError):
        dataclasses.replace(small_map, status=np.full(small_map.status.size, 7))


def test_cli_writes_map_and_summary(tmp_path, capsys) -> None:
    out, summary = tmp_path / "map.json", tmp_path / "summary.json"
    code = main(["paper", "-o", str(out), "--json", str(summary), "--min-cell", "0.0625", "--boundary-cell", "0.125"])
    assert code == 0
    document = json.loads(summary.read_text())
    assert set(document["area_fraction"]) == {"margin", "collision_free", "infeasible", "undecided"}
    for key in ("clearance_bound_min_m", "endpoint_bound_max_m", "seconds"):
        assert isinstance(document[key], float)
    assert load_region_map(out).coefficients_sha256 == load_coefficients("paper").source_sha256
    printed = capsys.readouterr().out
    assert "range certificate: margin" in printed and " s\n" in printed


def test_cli_passes_the_cuts_along_w_to_the_certificate(tmp_path) -> None:
    """--strip-split and --infeasibility-cuts reach the map's settings (its details), and without
    strips the coarse map of Eq. 9 has no leaf deeper along W than along L, where with them it has."""
    halvings = {}
    for strips in ("0", "2"):
        out = tmp_path / f"map{strips}.json"
        argv = ["paper", "-o", str(out), "--min-cell", "0.0625", "--boundary-cell", "0.125", "--no-progress"]
        assert main([*argv, "--strip-split", strips, "--infeasibility-cuts", "1"]) == 0
        region_map = load_region_map(out)
        assert region_map.details["config"]["strip_split"] == int(strips)
        assert region_map.details["config"]["infeasibility_cuts"] == 1
        levels = region_map.subpaving.levels
        halvings[strips] = int(np.max(levels[:, 1] - levels[:, 0]))
    assert halvings["0"] <= 1 < halvings["2"]


@pytest.mark.parametrize(
    "argv",
    [
        ["paper", "--margin", "-0.01"],
        ["paper", "--min-cell", "2"],
        ["paper", "--jobs", "-1"],
        ["paper", "--witnesses", "-1"],
        ["paper", "--witnesses", "two"],
        ["paper", "--extra-depth", "7"],
        ["paper", "--extra-depth", "-1"],
        ["paper", "--merge-spread", "-1e-4"],
        ["paper", "--strip-split", "7"],
        ["paper", "--infeasibility-cuts", "9"],
        ["/nonexistent/coefficients.json"],
    ],
)
def test_cli_errors_are_one_line_and_exit_2(argv, capsys) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "error" in err


def test_the_map_records_the_coefficients_file_name_not_its_folder(tmp_path) -> None:
    """The same coefficients certified in two folders give the same map bytes (the link is the
    sha256; the map names the file, not where it lies)."""
    paper = load_coefficients("paper")
    config = RangeCertificateConfig(min_cell=1 / 8, boundary_cell=1 / 8)
    digests = []
    for folder in ("one", "two/deeper"):
        path = tmp_path / folder / "coefficients.json"
        path.parent.mkdir(parents=True)
        save_coefficients(paper, path)
        region_map = certify_range(load_coefficients(path), config)
        assert region_map.coefficients_source == "coefficients.json"
        digests.append(save_region_map_json(region_map, tmp_path / folder / "region_map.json"))
    assert digests[0] == digests[1]
    assert certify_range(paper, config).coefficients_source == "paper"


def test_leaf_centres_are_the_cells_midpoints(small_map: RegionMap) -> None:
    centres = small_map.leaf_centres_m()
    assert centres.shape == (small_map.size, 2)
    for leaf in range(0, small_map.size, 7):
        cell = small_map.cell(leaf)
        assert centres[leaf, 0] == pytest.approx(sum(cell.range_of("L")) / 2, abs=1e-15)
        assert centres[leaf, 1] == pytest.approx(sum(cell.range_of("W")) / 2, abs=1e-15)


def test_the_small_map_has_strips_and_they_tile_their_cells(small_map: RegionMap) -> None:
    """The certificate cut cells along W alone (strips): only of the deepest cells, 2^E strips per
    cut cell, each 1 / 2^E of it in W and all of it in L."""
    levels, indices = small_map.subpaving.levels, small_map.subpaving.indices
    halvings = levels[:, 1] - levels[:, 0]
    split = np.flatnonzero(halvings > 0)
    assert split.size > 0
    assert np.all(levels[split, 0] == levels[:, 0].max())
    e = int(halvings.max())
    parents = {(int(indices[k, 0]), int(indices[k, 1]) >> e) for k in split}
    assert len(parents) * 2**e == split.size
    sizes = small_map.leaf_sizes_m()
    plain = np.flatnonzero((halvings == 0) & (levels[:, 0] == levels[:, 0].max()))
    assert np.allclose(sizes[split, 0], sizes[plain[0], 0], rtol=1e-12)
    assert np.allclose(sizes[split, 1] * 2**e, sizes[plain[0], 1], rtol=1e-12)
    assert float(np.sum(small_map.area)) == pytest.approx(1.0, abs=1e-12)


def test_strip_lookups_agree_at_strip_edges(small_map: RegionMap) -> None:
    """At every edge between strips (and a hair either side) the scalar lookup, the batch lookup
    and cell_at find the same leaf, and the point lies in that leaf's closed cell."""
    levels = small_map.subpaving.levels
    split = np.flatnonzero(levels[:, 1] > levels[:, 0])[:64]
    points = []
    for k in split:
        cell = small_map.cell(int(k))
        L = sum(cell.range_of("L")) / 2
        for W in (
            *cell.range_of("W"),
            np.nextafter(cell.range_of("W")[0], 1.0),
            np.nextafter(cell.range_of("W")[1], 0.0),
        ):
            points.append((L, min(W, small_map.range_of("W")[1])))
    points = np.array(points)
    leaves = small_map.leaf_indices(points[:, 0], points[:, 1])
    for (L, W), leaf in zip(points, leaves, strict=True):
        cell = small_map.cell_at(L, W)
        assert cell == small_map.cell(int(leaf))
        assert small_map.bounds_at(L, W) == (cell.clearance_bound_m, cell.endpoint_bound_m, cell.status)
        assert cell.range_of("W")[0] <= W <= cell.range_of("W")[1]
        assert cell.range_of("L")[0] <= L <= cell.range_of("L")[1]


def test_strips_survive_the_json_round_trip(small_map: RegionMap, tmp_path) -> None:
    path = tmp_path / "map.json"
    save_region_map_json(small_map, path)
    again = load_region_map(path)
    assert np.array_equal(again.subpaving.levels, small_map.subpaving.levels)
    assert save_region_map_json(again, tmp_path / "again.json") == save_region_map_json(
        small_map, tmp_path / "first.json"
    )


def test_strips_of_any_leaf_are_ordinary_leaves() -> None:
    """Leaves of depths 1 and 2 (the verifier's layout) with a depth-1 leaf and a depth-2 cell each
    cut in two along W: ordinary leaves of the subpaving, found by every lookup."""
    # Lower half: a depth-1 leaf and one as two strips; upper half: the cells of depth 2, cell (0, 3) as two strips.
    cells = [(1, 0, 0, 0), (1, 1, 0, 1), (1, 1, 1, 1)] + [
        (2, i, j, 0) for i in range(4) for j in (2, 3) if (i, j) != (0, 3)
    ]
    cells += [(2, 0, 6, 1), (2, 0, 7, 1)]
    d, il, iw, e = (np.array(column) for column in zip(*cells, strict=True))
    n = d.size
    strips = RegionMap.of_leaves(
        ((0.2, 0.3), (0.08, 0.12)),
        np.column_stack([d, d + e]),
        np.column_stack([il, iw]),
        family="paper",
        coefficients_source="test",
        coefficients_sha256="",
        axes=("L", "W"),
        margin_m=0.01,
        endpoint_tolerance_m=0.002,
        **{key: np.arange(n) * 1e-3 for key in ("clearance_bound_m", "endpoint_bound_m", "endpoint_clearance_upper_m")},
        status=np.zeros(n, dtype=int),
    )
    assert strips.cell_at(0.21, 0.119).range_of("W") == pytest.approx((0.115, 0.12))
    assert strips.cell_at(0.21, 0.114).range_of("W") == pytest.approx((0.11, 0.115))
    assert strips.cell_at(0.29, 0.09).range_of("W") == pytest.approx((0.08, 0.09))
    assert strips.bounds_at(0.21, 0.119)[0] == (n - 1) * 1e-3
    assert strips.leaf_indices(np.array([0.21, 0.21]), np.array([0.119, 0.114])).tolist() == [n - 1, n - 2]


def test_format_1_maps_are_read_as_unsplit(tmp_path) -> None:
    """Maps written before strips (format /1, no split_W column) still load, every leaf a quadtree node."""
    region_map = certify_range(
        load_coefficients("paper"), RangeCertificateConfig(min_cell=1 / 8, boundary_cell=1 / 8, strip_split=0)
    )
    path = tmp_path / "old.json"
    levels, indices = region_map.subpaving.levels, region_map.subpaving.indices
    document = {k: v for k, v in region_map.to_json().items() if k != "axes"}
    document["format"] = "twolink-region-map/1"
    cells = {"depth": levels[:, 0].tolist(), "index_L": indices[:, 0].tolist(), "index_W": indices[:, 1].tolist()}
    document["cells"] = cells | {k: v for k, v in document["cells"].items() if not k.startswith(("cut", "child"))}
    path.write_text(json.dumps(json_safe(document)))
    old = load_region_map(path)
    assert np.array_equal(old.subpaving.levels, levels) and np.array_equal(old.status, region_map.status)
