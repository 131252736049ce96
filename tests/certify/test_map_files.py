"""The region map on disk (:mod:`pipeline.certify.map_files`): a JSON header and a ``.npy`` leaf
table. A round trip keeps every number bit for bit (maps over (L, W) with strips and execution
bounds, over (L, W, x) and over (L, W, x, d)), the same map gives the same bytes, the maps of the
JSON formats are still read (and converted without a change), and a table truncated, edited or
not matching its header, a header of another format, or a missing table are refused in one
line naming the file."""

from __future__ import annotations

import dataclasses
import hashlib
import io
import itertools
import json
import math
from pathlib import Path

import numpy as np
import pytest

from pipeline.certify.execution_bounds import COLUMNS, ROUNDED_DOWN, ExecutionBounds, outward
from pipeline.certify.map_files import FORMAT_ARRAYS, load_region_map, region_map_files, save_region_map
from pipeline.certify.region_map import STATUSES, RegionMap, save_region_map_json
from pipeline.exceptions import DataFileError
from pipeline.io.jsonio import json_safe
from pipeline.model.arm import DEFAULT_URDF, load_planar_arm
from pipeline.model.dynamics import identify_dynamics
from pipeline.model.limits import ArmLimits

RANGES = {"L": (0.2, 0.3), "W": (0.08, 0.12), "x": (-0.03, 0.03), "d": (0.5, 0.6)}
TREE = ("cut_axis", "cut_level", "children")
BOUNDS = ("clearance_bound_m", "endpoint_bound_m", "endpoint_clearance_upper_m")


def _nodes(axes: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
    """The uniform 2^k-tree of depth 1 with its first node cut once more: depths (n,), indices (n, k)."""
    k = len(axes)
    nodes = [(1, i) for i in itertools.product(range(2), repeat=k)][1:]
    nodes += [(2, i) for i in itertools.product(range(2), repeat=k)]
    return np.array([d for d, _ in nodes]), np.array([i for _, i in nodes])


def _map(axes: tuple[str, ...], rng: np.random.Generator, execution: ExecutionBounds | None = None) -> RegionMap:
    depth, index = _nodes(axes)
    n = depth.size
    return RegionMap.of_leaves(
        tuple(RANGES[name] for name in axes),
        np.repeat(depth[:, None], len(axes), axis=1),
        index,
        family="paper",
        coefficients_source="coefficients.json",
        coefficients_sha256="ab" * 32,
        margin_m=0.01,
        endpoint_tolerance_m=0.002,
        clearance_bound_m=np.append(rng.normal(0.0, 0.02, n - 1), -math.inf),
        endpoint_bound_m=np.append(rng.uniform(0.0, 0.003, n - 1), math.inf),
        endpoint_clearance_upper_m=rng.uniform(0.0, 0.1, n),
        status=rng.integers(0, len(STATUSES), n),
        details={"min_cell": 0.25},
        execution=execution,
        axes=axes,
    )


def _execution(n: int, rng: np.random.Generator) -> ExecutionBounds:
    arm = load_planar_arm(DEFAULT_URDF)
    columns = {name: outward(rng.uniform(0.1, 5.0, n), name in ROUNDED_DOWN) for name in COLUMNS}  # as the build
    columns["speed_scale"][0], columns["ramp_s"][0] = math.nan, math.nan  # a leaf no rest-to-rest timing keeps
    columns["paper_torque1_n_m"][1] = math.inf
    return ExecutionBounds(ArmLimits.from_arm(arm), identify_dynamics(arm), columns)


@pytest.fixture(params=[("L", "W"), ("L", "W", "x"), ("L", "W", "x", "d")], ids=lambda a: "".join(a))
def region_map(request) -> RegionMap:
    rng = np.random.default_rng(7)
    axes = request.param
    n = _nodes(axes)[0].size
    return _map(axes, rng, _execution(n, rng) if axes == ("L", "W") else None)


def _same(a: RegionMap, b: RegionMap) -> None:
    """Every number of two maps equal, bit for bit (NaN equal to NaN)."""
    for name in ("status", *BOUNDS):
        assert getattr(a, name).dtype == getattr(b, name).dtype and np.array_equal(
            getattr(a, name), getattr(b, name), equal_nan=True
        ), name
    for name in TREE:
        assert np.array_equal(getattr(a.subpaving, name), getattr(b.subpaving, name)), name
    assert (a.axes, a.ranges_m, a.details, a.coefficients_sha256) == (
        b.axes,
        b.ranges_m,
        b.details,
        b.coefficients_sha256,
    )
    assert (a.execution is None) == (b.execution is None)
    if a.execution is not None:
        assert a.execution.limits == b.execution.limits and a.execution.dynamics == b.execution.dynamics
        for name in COLUMNS:
            assert np.array_equal(a.execution.columns[name], b.execution.columns[name], equal_nan=True), name


def test_a_round_trip_keeps_every_number_and_the_bytes(region_map: RegionMap, tmp_path: Path) -> None:
    path = tmp_path / "region_map.json"
    digest = save_region_map(region_map, path)
    header = json.loads(path.read_text())
    assert header["format"] == FORMAT_ARRAYS and header["leaves"]["file"] == "region_map.npy"
    assert header["leaves"]["rows"] == region_map.size and "cells" not in header
    fields = header["leaves"]["fields"]
    assert "clearance_bound_m" in fields  # full doubles stay float64
    if region_map.execution is not None:  # short decimals: 5 bytes each instead of 8, every bit kept
        assert {"duration_lo_s.mantissa", "duration_lo_s.exponent", "speed_scale.mantissa"} <= set(fields)
        assert "duration_lo_s" not in fields
    again = load_region_map(path)
    _same(region_map, again)
    points = np.array(
        [[0.21, 0.085, 0.0, 0.55][: len(region_map.axes)], [0.29, 0.119, 0.02, 0.51][: len(region_map.axes)]]
    )
    assert np.array_equal(again.leaf_indices(*points.T), region_map.leaf_indices(*points.T))
    assert save_region_map(again, tmp_path / "again" / "region_map.json") == digest
    assert (tmp_path / "again" / "region_map.npy").read_bytes() == (tmp_path / "region_map.npy").read_bytes()
    assert region_map_files(region_map) == region_map_files(again)


def test_a_map_of_the_json_formats_is_read_and_converts_unchanged(region_map: RegionMap, tmp_path: Path) -> None:
    old = tmp_path / "old.json"
    save_region_map_json(region_map, old)
    assert json.loads(old.read_text())["format"] != FORMAT_ARRAYS
    read = load_region_map(old)
    _same(region_map, read)
    save_region_map(read, tmp_path / "new.json")
    _same(region_map, load_region_map(tmp_path / "new.json"))


def _save_nodes_format(region_map: RegionMap, path: Path) -> None:
    """Write ``region_map`` in format /4 (a table of a 2^k-tree's nodes: a depth, an index per axis,
    the halvings of the second axis) as builds of that format did."""
    levels, indices = region_map.subpaving.levels, region_map.subpaving.indices
    columns = {"depth": levels[:, 0].astype("<i1")}
    columns |= {f"index_{name}": indices[:, a].astype("<i4") for a, name in enumerate(region_map.axes)}
    columns |= {"split_W": (levels[:, 1] - levels[:, 0]).astype("<i1"), "status": region_map.status.astype("<i1")}
    columns |= {name: getattr(region_map, name).astype("<f8") for name in BOUNDS}
    n = region_map.size
    table = np.zeros((), dtype=np.dtype([(name, c.dtype.str, (n,)) for name, c in columns.items()]))
    for name, column in columns.items():
        table[name] = column
    buffer = io.BytesIO()
    np.save(buffer, table, allow_pickle=False)
    path.with_suffix(".npy").write_bytes(buffer.getvalue())
    leaves = {"file": "region_map.npy", "sha256": hashlib.sha256(buffer.getvalue()).hexdigest(), "rows": n}
    header = {
        "format": "twolink-region-map/4",
        **region_map.header_json(),
        "leaves": leaves | {"fields": list(columns)},
    }
    path.write_text(json.dumps(json_safe(header)))


def test_a_map_of_the_nodes_format_is_read_with_every_number(region_map: RegionMap, tmp_path: Path) -> None:
    if region_map.execution is not None:
        region_map = dataclasses.replace(region_map, execution=None)
    _save_nodes_format(region_map, tmp_path / "region_map.json")
    read = load_region_map(tmp_path / "region_map.json")
    _same(region_map, read)


@pytest.fixture
def saved(tmp_path: Path) -> Path:
    rng = np.random.default_rng(3)
    path = tmp_path / "region_map.json"
    save_region_map(_map(("L", "W", "x"), rng), path)
    return path


def _refused(path: Path, *words: str) -> None:
    with pytest.raises(DataFileError) as error:
        load_region_map(path)
    message = str(error.value)
    assert "\n" not in message and all(word in message for word in words), message


def test_a_truncated_table_is_refused(saved: Path) -> None:
    table = saved.with_suffix(".npy")
    table.write_bytes(table.read_bytes()[:-8])
    _refused(saved, "region_map.npy", "sha256")


def test_an_edited_table_is_refused(saved: Path) -> None:
    table = saved.with_suffix(".npy")
    data = bytearray(table.read_bytes())
    data[-3] ^= 0x10
    table.write_bytes(bytes(data))
    _refused(saved, "region_map.npy", "sha256")


def test_a_table_that_does_not_match_its_header_is_refused(saved: Path) -> None:
    header = json.loads(saved.read_text())
    header["leaves"]["rows"] += 1
    saved.write_text(json.dumps(header))
    _refused(saved, "rows")


def test_a_missing_table_is_refused(saved: Path) -> None:
    saved.with_suffix(".npy").unlink()
    _refused(saved, "region_map.npy", "cannot be read")


def test_another_format_version_is_refused(saved: Path) -> None:
    header = json.loads(saved.read_text())
    header["format"] = "twolink-region-map/99"
    saved.write_text(json.dumps(header))
    _refused(saved, "twolink-region-map/99", FORMAT_ARRAYS)
