"""The benchmark's row (a*) over (L, W, x) (verify.benchmark.over_x): with coefficients over (L, W, x)
and their map, it times ``generate(..., x=x)`` with the map's bounds on random (L, W, x) in their box,
and OMPL plans around the same moved obstacles; without the coefficients the row is left out with
one line saying how to make them; bad files are refused with one line. Tiny counts, hand-made
coefficients (the paper's Eq. 9 lifted to (L, W, x)) and a coarse map; no timing is asserted."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from pipeline import load_coefficients
from pipeline.certify.map_files import save_region_map
from pipeline.certify.map_for_coefficients import DEFAULT_MAP_NAME, default_config
from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
from pipeline.cli import EXIT_OK, EXIT_USAGE
from pipeline.offline.coefficients import save_coefficients
from pipeline.online.generator import RANGE_SOURCE
from verify.bench import main
from verify.benchmark import methods as bench_methods
from verify.benchmark import ompl_planner as planner
from verify.benchmark import over_x as bench_over_x
from verify.benchmark.per_query import PerQueryRow, time_side_by_side
from verify.benchmark.results import MAKE_COEFFICIENTS_X


@pytest.fixture(scope="module")
def built_lw(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """(L, W) coefficients (the paper's Eq. 9 written as a build writes them) with a coarse map beside."""
    folder = tmp_path_factory.mktemp("lw")
    path = folder / "coefficients.json"
    save_coefficients(dataclasses.replace(load_coefficients("paper"), extra={"note": "test_bench_over_x"}), path)
    coefficients = load_coefficients(path)
    config = default_config(coefficients, min_cell=1 / 32, boundary_cell=1 / 16)
    save_region_map(certify_range(coefficients, config), folder / DEFAULT_MAP_NAME)
    return path


@pytest.fixture(scope="module")
def built_x(tmp_path_factory: pytest.TempPathFactory, over_x) -> Path:
    """Coefficients over (L, W, x) (the paper's Eq. 9 lifted, x in [-0.03, 0.03] m) in a file with a
    coarse map over (L, W, x) beside it, as ``python -m pipeline.build --vary x ...`` leaves them."""
    folder = tmp_path_factory.mktemp("x")
    path = folder / "coefficients.json"
    save_coefficients(over_x(load_coefficients("paper")), path)
    coefficients = load_coefficients(path)
    coarse = RangeCertificateConfig(min_cell=1 / 8, boundary_cell=1 / 4, max_depth_s=12)
    save_region_map(certify_range(coefficients, coarse), folder / DEFAULT_MAP_NAME)
    return path


def run_main(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    status = main(list(argv))
    captured = capsys.readouterr()
    return status, captured.out, captured.err


#: Tiny settings without (c): 3 obstacles, 2 passes of the cheap rows, 1 of the slow ones.
TINY = ["--n", "3", "--repeats", "2", "--batch-repeats", "2", "--slow-repeats", "1", "--pso-cases", "0"]
TINY += ["--ompl-time", "0.5", "--quiet"]


def test_row_over_x_answers_with_the_map_and_ompl_plans_around_the_moved_obstacles(
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    tmp_path: Path,
    built_lw: Path,
    built_x: Path,
) -> None:
    planned = []  # every obstacle OMPL was given
    plan = planner.plan_rrt_connect

    def spy(arm, obstacle, start, goal, config=None):
        planned.append(obstacle)
        return plan(arm, obstacle, start, goal, config)

    monkeypatch.setattr(planner, "plan_rrt_connect", spy)
    out_json = tmp_path / "bench.json"
    common = ["--coefficients", str(built_lw), "--coefficients-x", str(built_x), *TINY]
    status, out, err = run_main(capsys, *common, "--build-timing", str(tmp_path / "none.json"), "--json", str(out_json))
    assert status == EXIT_OK, err
    data = json.loads(out_json.read_text())
    methods = {m["key"]: m for m in data["methods"]}
    keys = [m["key"] for m in data["methods"]]
    with_ompl = planner.ompl_available()
    # The existing rows first, unchanged, then the rows over (L, W, x).
    assert keys[:4] == ["a", "a_batch", "a_range", "a_range_batch"] and "a_range_x" in keys
    assert keys[keys.index("a_range_x") :] == ["a_range_x"] + (["d_x", "d_x_cert"] if with_ompl else [])
    row = methods["a_range_x"]
    assert row["timed_runs"] == 2 * 3 and row["obstacles"] == 3 and row["answered"] == 3
    assert row["label"] in out and "generate(coefficients_x, L, W, x=x, region_map=m)" in out
    assert row["keeps_margin"] <= row["certified_collision_free"] <= row["extra"]["in_range_queries"] == 3
    info = data["a_range_x"]["over_x"]
    assert info["source"] == str(built_x) and info["region_map"]["path"] == str(built_x.with_name(DEFAULT_MAP_NAME))
    cases = np.array(info["cases_m"])
    assert cases.shape == (3, 3)
    for j, name in enumerate(("L", "W", "x")):
        lo, hi = info["fitted_range_m"][name]
        assert np.all((lo <= cases[:, j]) & (cases[:, j] <= hi))
    assert np.ptp(cases[:, 2]) > 0.0  # the obstacles move
    np.testing.assert_array_equal(info["obstacle_centre_x_m"], cases[:, 2])  # the answers' obstacles, at x
    assert "(a*) over (L, W, x): median" in out and "(a*) over (L, W, x): coefficients" in out
    if with_ompl:
        d_x = methods["d_x"]
        assert d_x["queries"] == 3 and d_x["obstacles"] == 3
        # OMPL got the moved obstacles: each (L, W, x) of the row, centred at its x.
        assert d_x["extra"]["obstacle_centre_x_m"] == list(cases[:, 2])
        moved = [(o.length_m, o.width_m, o.centre_x_m) for o in planned if o.centre_x_m != 0.0]
        for length, width, x in cases:
            assert (length, width, x) in moved
        assert all(o.centre_x_m == 0.0 for o in planned[: len(planned) - len(moved)])  # (d) on (L, W) first
        ratio = data["ratios"]["d_x_over_a_range_x"]
        assert math.isclose(ratio, d_x["median_s"] / row["median_s"], rel_tol=1e-12)
        assert math.isclose(data["a_range_x"]["ratio_to_d_x"], ratio, rel_tol=1e-12)
        assert "over (L, W, x): (d) / (a*) = " in out and d_x["label"] in out
    else:
        assert data["ratios"]["d_x_over_a_range_x"] is None and "(d) over (L, W, x) skipped" in out


def test_row_over_x_is_the_generators_answer_with_the_maps_bounds(built_x: Path) -> None:
    coefficients = load_coefficients(built_x)
    region_map = coefficients.region_map
    assert region_map is not None and region_map.axes == ("L", "W", "x")
    cases = bench_over_x.sample_cases_x(coefficients, 12, 5)
    row = PerQueryRow(coefficients, cases, region_map)
    time_side_by_side([row], 1)
    answers = row.answers
    assert len(row.times_s) == len(cases)
    for (length, width, x), answer in zip(cases, answers, strict=True):
        assert answer.centre_x_m == x and answer.obstacle.centre_x_m == x
        assert answer.certificate_source == RANGE_SOURCE
        clearance, endpoint, _ = region_map.bounds_at(float(length), float(width), float(x))
        assert answer.certified_clearance_m == clearance and answer.endpoint_error_bound_m == endpoint
        assert bench_over_x.moved_scene(coefficients, np.array([length, width, x]), None) == answer.scene
    counts = bench_methods.range_counts(answers, coefficients.scene.margin_m)
    assert counts.in_range == 12
    assert counts.certified == sum(a.certified_clearance_m > 0.0 for a in answers)


@pytest.fixture(scope="module")
def built_xd(tmp_path_factory: pytest.TempPathFactory, over_xd) -> Path:
    """Coefficients over (L, W, x, d) (the paper's Eq. 9 lifted, d in [0.55, 0.57] m) with a coarse
    map over (L, W, x, d) beside them."""
    folder = tmp_path_factory.mktemp("xd")
    path = folder / "coefficients.json"
    save_coefficients(over_xd(load_coefficients("paper"), scale=0.02, d_scale=0.2), path)
    coefficients = load_coefficients(path)
    coarse = RangeCertificateConfig(min_cell=1 / 4, boundary_cell=1 / 4, max_depth_s=10)
    save_region_map(certify_range(coefficients, coarse), folder / DEFAULT_MAP_NAME)
    return path


def test_row_over_x_and_d_answers_with_the_maps_bounds_at_the_moved_far_edge(built_xd: Path) -> None:
    """Over (L, W, x, d) the row passes d too: each answer's obstacle has its far edge at the
    case's d, and its bounds are the map's leaf's at (L, W, x, d)."""
    coefficients = load_coefficients(built_xd)
    region_map = coefficients.region_map
    assert region_map is not None and region_map.axes == ("L", "W", "x", "d")
    cases = bench_over_x.sample_cases_x(coefficients, 6, 5)
    assert cases.shape == (6, 4) and np.ptp(cases[:, 3]) > 0.0
    row = PerQueryRow(coefficients, cases, region_map)
    time_side_by_side([row], 1)
    assert bench_over_x.row_name(coefficients) == "(a*) over (L, W, x, d)"
    for case, answer in zip(cases, row.answers, strict=True):
        assert answer.obstacle.centre_x_m == case[2] and answer.obstacle.top_y_m == case[3]
        clearance, endpoint, _ = region_map.bounds_at(*map(float, case))
        assert answer.certified_clearance_m == clearance and answer.endpoint_error_bound_m == endpoint
        assert bench_over_x.moved_scene(coefficients, case, None) == answer.scene


def test_without_coefficients_x_the_row_is_left_out_with_the_command_that_makes_them(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path, built_lw: Path
) -> None:
    monkeypatch.chdir(tmp_path)  # no results-x/ here
    common = ["--coefficients", str(built_lw), *TINY, "--no-ompl", "--build-timing", "none.json"]
    status, out, _ = run_main(capsys, *common, "--json", "b.json")
    assert status == EXIT_OK
    lines = [line for line in out.splitlines() if "(a*) over (L, W, x)" in line]
    reason = f"no results-x/coefficients.json and no --coefficients-x (make it with: {MAKE_COEFFICIENTS_X})"
    assert lines == [f"(a*) over (L, W, x) skipped: {reason}"]
    data = json.loads((tmp_path / "b.json").read_text())
    assert data["a_range_x"] is None and data["ratios"]["d_x_over_a_range_x"] is None
    assert "a_range_x" not in [m["key"] for m in data["methods"]]
    assert "over (L, W, x): (d)" not in out
    status, out, _ = run_main(capsys, *common, "--no-x")
    assert status == EXIT_OK and "(a*) over (L, W, x) skipped: --no-x" in out


def test_bad_coefficients_x_are_refused_with_one_line(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, built_lw: Path, built_x: Path
) -> None:
    common = ["--coefficients", str(built_lw), *TINY, "--no-ompl", "--build-timing", str(tmp_path / "none.json")]
    lone = tmp_path / "lone" / "coefficients.json"  # over (L, W, x), without their map
    lone.parent.mkdir()
    lone.write_bytes(built_x.read_bytes())
    for path, message in (
        (tmp_path / "no" / "coefficients.json", "--coefficients-x"),
        (built_lw, "--coefficients-x must vary (L, W, x) or (L, W, x, d)"),
        (lone, "python -m pipeline.certify_range"),
    ):
        status, out, err = run_main(capsys, *common, "--coefficients-x", str(path))
        assert status == EXIT_USAGE and message in err, err
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err and "median/query" not in out
