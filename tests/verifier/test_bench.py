"""The benchmark's command line (verify.bench) and library (verify.benchmark): it runs on tiny
settings and writes the JSON schema, reports build timing files, skips OMPL cleanly when it is
missing, and gives one clear line and exit status 2 on bad input. Row (a*) (the generator with the
range certificate) answers with the map's certified clearance and the generator's own parameters,
takes the map beside the coefficients, a named one, or certifies them in-process, and refuses a map
of other coefficients. No timing is asserted: these machines are noisy."""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from pipeline import load_coefficients
from pipeline.certify.cell_timings import near_optimal_cells
from pipeline.certify.map_files import load_region_map, save_region_map
from pipeline.certify.map_for_coefficients import DEFAULT_MAP_NAME, default_config
from pipeline.certify.near_optimal_cells import cells_files
from pipeline.certify.range_certificate import RangeCertificateConfig
from pipeline.cli import EXIT_OK, EXIT_USAGE, HelpFormatter
from pipeline.exceptions import (
    DataFileError,
    EndpointConstraintWarning,
    InvalidParameterError,
    RegionMapMismatchWarning,
)
from pipeline.io.jsonio import write_json_atomic
from pipeline.offline.coefficients import Coefficients, save_coefficients
from pipeline.online.generator import RANGE_SOURCE, generate
from pipeline.online.query_state import state_of
from verify.acceptance.cases import SweepRange, sample_cases
from verify.bench import build_parser, main
from verify.benchmark import methods as bench_methods
from verify.benchmark import ompl_planner as planner
from verify.benchmark import range_map as bench_range_map
from verify.benchmark import results as bench_results
from verify.benchmark import run as bench_run
from verify.benchmark import toppra_peer
from verify.benchmark.per_query import PerQueryRow, time_side_by_side


def coarse_config(coefficients: Coefficients) -> RangeCertificateConfig:
    """The build's certificate settings on coarser cells (a few seconds): on the paper's Eq. 9 it
    still certifies the whole fitted range collision-free (no undecided cell)."""
    return default_config(coefficients, min_cell=1 / 32, boundary_cell=1 / 16)


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A coefficients file (the paper's Eq. 9, written as the build writes its coefficients, marked so
    that its sha256 differs from the paper's file) with its region map beside it, as
    ``python -m pipeline.build`` leaves them; returns the coefficients file."""
    folder = tmp_path_factory.mktemp("built")
    path = folder / "coefficients.json"
    save_coefficients(dataclasses.replace(load_coefficients("paper"), extra={"note": "test_bench fixture"}), path)
    coefficients = load_coefficients(path)
    region_map = bench_range_map.certify_range(coefficients, coarse_config(coefficients))
    save_region_map(region_map, folder / DEFAULT_MAP_NAME)
    state = state_of(coefficients)  # near-optimal cells for the recorded arm, 2 x 2, as the build writes them
    cells = near_optimal_cells(coefficients, state.dynamics, state.limits.with_servo_defaults(), cells_per_axis=2)
    for name, data in cells_files(cells).items():
        (folder / name).write_bytes(data)
    return path


#: Tiny settings: 3 obstacles, a 4-particle 2-iteration PSO without polish on one of them; the rows over
#: (L, W, x) left out (test_bench_over_x.py).
TINY = [
    "--n",
    "3",
    "--repeats",
    "3",
    "--batch-repeats",
    "2",
    "--slow-repeats",
    "1",
    "--pso-cases",
    "1",
    "--pso-swarm-size",
    "4",
    "--pso-iterations",
    "2",
    "--pso-restarts",
    "1",
    "--pso-no-polish",
    "--ompl-time",
    "0.5",
    "--no-x",
    "--quiet",
]
METHOD_KEYS = (
    "key",
    "label",
    "obstacles",
    "timed_runs",
    "median_s",
    "ratio_to_a",
    "ratio_to_b",
    "queries",
    "answered",
    "answered_fraction",
    "certified_collision_free",
    "certified_fraction",
    "keeps_margin",
    "keeps_margin_fraction",
    "note",
)


def run_main(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    status = main(list(argv))
    captured = capsys.readouterr()
    return status, captured.out, captured.err


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory: pytest.TempPathFactory, built: Path) -> tuple[int, str, dict]:
    """One tiny benchmark run of the built coefficients (their map beside them), with a build timing
    file to report and a tiny 3 x 3 build run by the benchmark; (status, stdout, JSON)."""
    folder = tmp_path_factory.mktemp("bench")
    timing = folder / "build_timing.json"
    write_json_atomic(
        timing,
        {
            "total_s": 12.5,
            "jobs": 1,
            "experiments": [{"test": 1, "seconds": 5.0}, {"test": 2, "seconds": 7.5}],
            "coal_queries": 123456,
            "objective_evaluations": 1000,
        },
    )
    out_json = folder / "bench.json"
    stdout = io.StringIO()
    # The reduced build's tiny PSO gives optima too rough for the endpoint-constrained
    # regression to converge; it is timed here, not judged.
    with contextlib.redirect_stdout(stdout), warnings.catch_warnings():
        warnings.simplefilter("ignore", EndpointConstraintWarning)
        status = main(
            [
                "--coefficients",
                str(built),
                *TINY,
                "--build-timing",
                str(timing),
                "--run-build",
                "3",
                "--json",
                str(out_json),
            ]
        )
    return status, stdout.getvalue(), json.loads(out_json.read_text())


def test_help_lists_every_option_with_units_and_defaults(capsys: pytest.CaptureFixture[str]) -> None:
    status, out, _ = run_main(capsys, "--help")
    assert status == EXIT_OK
    text = " ".join(out.split())
    for action in build_parser()._actions:
        for option in action.option_strings:
            assert option in out
        if action.option_strings != ["-h", "--help"] and action.default not in (None, False):
            assert "(default" in HelpFormatter("x")._get_help_string(action), action.option_strings
    for expected in ("default: results/coefficients.json", "[s]", "[cases]", "(default: 50)", "(default: 3)"):
        assert expected in text


def test_tiny_run_prints_the_table_and_writes_the_json_schema(tiny_run: tuple[int, str, dict]) -> None:
    status, out, data = tiny_run
    assert status == EXIT_OK
    assert data["format"] == bench_results.FORMAT
    for key in (
        "command",
        "coefficients",
        "settings",
        "margin_m",
        "cases",
        "methods",
        "a_range",
        "near_optimal",
        "ratios",
        "sweep",
        "build",
        "machine",
    ):
        assert key in data
    assert data["command"].startswith("python -m verify.bench --coefficients ")
    assert len(data["cases"]) == 3
    keys = [m["key"] for m in data["methods"]]
    expected = ["a", "a_batch", "a_range", "a_range_batch", "n_opt_lookup", "b", "n_opt"]
    expected += ["toppra"] if toppra_peer.toppra_available() else []
    expected += ["n_opt_map", "n_opt_map_batch"]
    assert keys == [*expected, "c"] + (["d", "d_cert"] if planner.ompl_available() else [])
    for method in data["methods"]:
        for key in METHOD_KEYS:
            assert key in method, (method["key"], key)
        assert method["median_s"] > 0
        assert 0.0 <= method["answered_fraction"] <= 1.0
        if method["answered"]:
            assert 0.0 <= method["certified_fraction"] <= 1.0
            assert method["keeps_margin"] <= method["certified_collision_free"] <= method["answered"]
        assert method["label"] in out
    methods = {m["key"]: m for m in data["methods"]}
    a, b = methods["a"], methods["b"]
    assert math.isclose(a["ratio_to_a"], 1.0) and math.isclose(b["ratio_to_b"], 1.0)
    assert a["timed_runs"] == 3 * 3  # 3 passes over 3 obstacles
    assert methods["a_range"]["timed_runs"] == 3 * 3 and methods["a_range_batch"]["timed_runs"] == 2  # --batch-repeats
    c = methods["c"]
    assert c["obstacles"] == 1 and c["extra"]["pso"]["swarm_size"] == 4 and c["extra"]["polish"] is False
    # (b) answers only with a certificate that keeps the margin.
    if b["answered"]:
        assert b["certified_fraction"] == 1.0 and b["keeps_margin_fraction"] == 1.0
    for key in ("without_certificate", "with_certificate"):
        assert data["sweep"][key]["cases_per_s"] > 0
    assert data["build"]["file"]["total_s"] == 12.5
    assert data["build"]["file"]["coal_queries"] == 123456
    assert data["build"]["file"]["experiment_seconds"] == [5.0, 7.5]
    reduced = data["build"]["reduced"]  # --run-build 3 with the tiny PSO of (c)
    assert reduced["experiments"] == 9 and reduced["coal_queries"] > 0 and reduced["total_s"] > 0
    assert "swarm 4, iterations 2, restarts 1, polish False" in reduced["source"]
    assert "doe.json" not in out  # the build's own output is kept off stdout
    for text in ("median/query", "vs (a)", "vs (b)", "cert. free", "cases/s", "123,456 Coal distance queries"):
        assert text in out
    assert "not absolute claims" in out


def test_near_optimal_rows_time_n_star_and_toppra_on_the_same_paths(tiny_run: tuple[int, str, dict]) -> None:
    """(n*) and (tp): timed per query ((slow-repeats) passes over the obstacles), T'/T_TOPP-RA and
    the sampled excesses reported in the JSON and the text; ours is certified, so its excess is 0."""
    _, out, data = tiny_run
    methods = {m["key"]: m for m in data["methods"]}
    n_star = methods["n_opt"]
    assert n_star["timed_runs"] == 3 * 1 and n_star["answered"] == 3  # --slow-repeats 1 over 3 obstacles
    assert n_star["extra"]["sampled_excess_max"] == {"speed": 0.0, "acceleration": 0.0, "torque": 0.0, "jerk": 0.0}
    summary = data["near_optimal"]
    assert summary["ours_excess_max"] == n_star["extra"]["sampled_excess_max"]
    assert summary["limits"] and all(math.isfinite(j) for j in summary["limits"][0]["jerk_rad_s3"])
    assert "(n*) near-optimal certified per query" in out
    assert "Largest relative excess over a limit, sampled at 100x the grid" in out
    if not toppra_peer.toppra_available():
        assert "(tp) toppra skipped: toppra is not installed" in out and summary["paths"] == 0
        return
    toppra = methods["toppra"]
    assert toppra["timed_runs"] == 3 and toppra["extra"]["gridpoints"] == 100
    assert summary["paths"] == 3 and summary["toppra_gridpoints"] == 100
    assert 0.0 < summary["duration_ratio_min"] <= summary["duration_ratio_median"] <= summary["duration_ratio_max"]
    assert all(v >= 0.0 for v in summary["toppra_excess_max"].values())
    assert math.isclose(data["ratios"]["n_opt_over_toppra"], n_star["median_s"] / toppra["median_s"], rel_tol=1e-12)
    assert "(tp) toppra (100 grid points) per query" in out and "(n*) / (tp) = " in out
    assert f"T'/T_TOPP-RA median {summary['duration_ratio_median']:.4f}" in out


def test_near_optimal_rows_from_the_map_read_the_cells(tiny_run: tuple[int, str, dict]) -> None:
    """(n*g), (n*m), (n*m'): the near-optimal answers from the map's cells beside the coefficients:
    every (n*m) answer's timing and bounds from the map, the lookup and the batch answering the
    same queries, and T'/T_TOPP-RA of the map's timing reported beside (n*)'s."""
    _, out, data = tiny_run
    methods = {m["key"]: m for m in data["methods"]}
    lookup, full, batched = methods["n_opt_lookup"], methods["n_opt_map"], methods["n_opt_map_batch"]
    assert lookup["timed_runs"] == 3 * 3 and full["timed_runs"] == 3 and batched["timed_runs"] == 2
    # The lookup and the batch answer what the map proves in full (clearance, endpoints, limits); the
    # full call also certifies (or repairs) per query the clearance the map leaves open, and reads the
    # cell's timing for every answer it did not repair.
    from_map = full["extra"]["execution_from_map"]
    assert 0 < lookup["answered"] == batched["answered"] <= from_map <= full["answered"]
    for label in ("(n*g) near-optimal certified, map lookup", "(n*m) near-optimal certified, from the map"):
        assert label in out
    if toppra_peer.toppra_available():
        median, largest = data["near_optimal"]["map_over_toppra"]
        assert 1.0 < median <= largest
        assert (
            f"(n*m) near-optimal from the map vs (tp), same paths and limits: T'/T_TOPP-RA median {median:.4f}" in out
        )


def test_a_range_row_certifies_every_in_range_query_of_a_clean_map(tiny_run: tuple[int, str, dict]) -> None:
    _, out, data = tiny_run
    summary = data["a_range"]
    for key in ("median_us", "batched_us_per_obstacle", "certified_fraction", "margin_fraction", "ratio_to_d"):
        assert key in summary
    assert summary["median_us"] > 0 and summary["batched_us_per_obstacle"] > 0
    # The fixture's map certifies its whole range collision-free, and every obstacle is in range.
    assert summary["region_map"]["certified_collision_free_fraction"] == 1.0
    assert summary["in_range_queries"] == 3
    assert summary["certified_fraction"] == 1.0
    assert 0.0 <= summary["margin_fraction"] <= 1.0
    assert summary["same_parameters_as_a"] is True
    assert summary["region_map"]["origin"] == "beside" and summary["region_map"]["certify_s"] is None
    assert summary["region_map"]["path"].endswith(DEFAULT_MAP_NAME)
    methods = {m["key"]: m for m in data["methods"]}
    for key in ("a_range", "a_range_batch"):
        assert methods[key]["certified_fraction"] == 1.0 and methods[key]["extra"]["same_parameters_as_a"]
    ratios = data["ratios"]
    if planner.ompl_available():
        d = methods["d"]["median_s"]
        assert math.isclose(summary["ratio_to_d"], d / methods["a_range"]["median_s"], rel_tol=1e-12)
        assert math.isclose(ratios["d_over_a_range"], summary["ratio_to_d"], rel_tol=1e-12)
        assert math.isclose(ratios["d_over_a"], d / methods["a"]["median_s"], rel_tol=1e-12)
        assert "(d) / (a*) = " in out
    else:
        assert summary["ratio_to_d"] is None and ratios["d_over_a_range"] is None
    assert "(a*) range certificate: median" in out and "certified clearance > 0 on 100%" in out
    assert "beside the coefficients" in out


def test_a_range_answers_are_the_generators_with_the_maps_bounds(built: Path) -> None:
    coefficients = load_coefficients(built)
    region_map = load_region_map(built.with_name(DEFAULT_MAP_NAME))
    cases = sample_cases(SweepRange.from_fitted(coefficients.fitted_range_m), 20, 3)
    row = PerQueryRow(coefficients, cases, region_map)
    time_side_by_side([row], 1)
    answers = row.answers
    _, batch = bench_methods.bench_range_batched(coefficients, cases, region_map, 1)
    for i, (length, width) in enumerate(cases):
        plain = generate(coefficients, float(length), float(width))
        answer = answers[i]
        assert answer.trajectory.parameters == plain.trajectory.parameters  # the same numbers, bit for bit
        assert answer.duration_s == plain.duration_s
        np.testing.assert_allclose(batch.parameters[i], plain.trajectory.array, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(batch.durations_s[i], plain.duration_s, rtol=1e-12, atol=0.0)
        cell = region_map.cell_at(float(length), float(width))
        assert answer.certificate_source == RANGE_SOURCE
        assert answer.certified_clearance_m == cell.clearance_bound_m == batch.certified_clearance_m[i]
    counts = bench_methods.range_counts(answers, coefficients.scene.margin_m)
    batch_counts = bench_methods.batch_range_counts(batch, coefficients.scene.margin_m)
    assert counts == batch_counts
    assert counts.in_range == counts.certified == 20
    expected_margin = sum(a.certified_clearance_m >= coefficients.scene.margin_m for a in answers)
    assert counts.keeps_margin == expected_margin


def test_range_counts_leave_out_extrapolated_and_refused_queries(built: Path) -> None:
    coefficients = load_coefficients(built)
    region_map = load_region_map(built.with_name(DEFAULT_MAP_NAME))
    inside = generate(coefficients, 0.25, 0.10, region_map=region_map)
    outside = generate(coefficients, 0.305, 0.10, region_map=region_map, out_of_range="ignore")
    assert outside.extrapolated and outside.certificate_source is None
    counts = bench_methods.range_counts([inside, outside, None], 0.01)
    assert (counts.in_range, counts.certified) == (1, 1)
    assert counts.clearance_min_m == inside.certified_clearance_m


def test_a_foreign_region_map_is_refused_with_one_line(capsys: pytest.CaptureFixture[str], built: Path) -> None:
    foreign = built.with_name(DEFAULT_MAP_NAME)  # certifies the built file, not the paper's Eq. 9
    status, out, err = run_main(
        capsys, "--coefficients", "paper", "--region-map", str(foreign), "--n", "2", "--pso-cases", "0", "--no-ompl"
    )
    assert status == EXIT_USAGE and "median/query" not in out  # refused before any timing
    assert str(foreign) in err and "--region-map certifies coefficients sha256" in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not load_region_map(foreign).belongs_to(load_coefficients("paper"))
    with pytest.raises(DataFileError) as info:
        bench_range_map.bench_region_map(load_coefficients("paper"), foreign)
    assert info.value.path == foreign


def test_a_named_region_map_is_used(built: Path) -> None:
    coefficients = load_coefficients(built)
    chosen = bench_range_map.bench_region_map(coefficients, built.with_name(DEFAULT_MAP_NAME))
    assert chosen.origin == "file" and chosen.certify_s is None
    assert "named by --region-map" in chosen.describe()


def test_without_a_map_the_coefficients_are_certified_in_process(built: Path, tmp_path: Path) -> None:
    # A stale map beside other coefficients: the benchmark certifies them itself and says why.
    other = dataclasses.replace(load_coefficients(built), extra={"note": "other coefficients"})
    path = tmp_path / "coefficients.json"
    save_coefficients(other, path)
    (tmp_path / DEFAULT_MAP_NAME).write_bytes(built.with_name(DEFAULT_MAP_NAME).read_bytes())
    with pytest.warns(RegionMapMismatchWarning, match="not attached"):
        coefficients = load_coefficients(path)
    messages: list[str] = []
    stages: list[tuple[str, int, int]] = []
    chosen = bench_range_map.bench_region_map(
        coefficients,
        None,
        config=coarse_config(coefficients),
        log=messages.append,
        progress=lambda *call: stages.append(call),
    )
    assert chosen.origin == "certified" and chosen.path is None
    assert chosen.region_map.belongs_to(coefficients)
    assert chosen.certify_s is not None and chosen.certify_s > 0
    assert "certifies other coefficients" in chosen.reason and "in-process" in messages[0]
    assert stages[0] == ("range map: search", 0, 4) and stages[-1][1] == stages[-1][2]  # certify_range's stages
    assert "certified in-process in" in chosen.describe() and chosen.to_json()["origin"] == "certified"
    assert "no region map exists for 'paper'" in bench_range_map._missing_reason(load_coefficients("paper"))


def test_a_named_region_map_replaces_the_one_beside_unread_and_the_arm_is_the_recorded_one(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, built: Path
) -> None:
    """--region-map FILE: the (here broken) map beside the coefficients is not read; without
    --urdf the arm is the one recorded with the coefficients; --no-progress is accepted and no bar
    is drawn off a terminal anyway."""
    source = tmp_path / "coefficients.json"
    source.write_bytes(built.read_bytes())  # the same coefficients: the built map certifies them
    (tmp_path / DEFAULT_MAP_NAME).write_text("{not json")
    common = ["--coefficients", str(source), "--n", "2", "--repeats", "2", "--batch-repeats", "2"]
    common += ["--slow-repeats", "1"]
    common += ["--pso-cases", "0", "--no-ompl", "--no-near-optimal", "--build-timing", str(tmp_path / "none.json")]
    named = ["--region-map", str(built.with_name(DEFAULT_MAP_NAME))]
    status, out, err = run_main(capsys, *common, *named, "--no-progress", "--json", str(tmp_path / "b.json"))
    assert status == EXIT_OK and "named by --region-map" in out and "Traceback" not in err
    assert "(n*) and (tp) toppra skipped: --no-near-optimal" in out and "(n*) near-optimal" not in out
    assert "%" not in err  # progress lines only, no bar
    status, _, err = run_main(capsys, *common, "--quiet")  # the broken map beside them, found: one line
    assert status == EXIT_USAGE and str(tmp_path / DEFAULT_MAP_NAME) in err and len(err.strip().splitlines()) == 1


def test_missing_ompl_skips_d_with_a_clear_line(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path, built: Path
) -> None:
    monkeypatch.setattr(planner, "ompl_available", lambda: False)
    status, out, _ = run_main(
        capsys,
        "--coefficients",
        str(built),
        "--n",
        "2",
        "--repeats",
        "2",
        "--batch-repeats",
        "2",
        "--slow-repeats",
        "1",
        "--pso-cases",
        "0",
        "--build-timing",
        str(tmp_path / "none.json"),
        "--quiet",
    )
    assert status == EXIT_OK
    assert "(d) skipped: ompl is not installed" in out
    assert "(c) skipped: --pso-cases 0" in out
    assert "OMPL RRT-Connect" not in out
    assert "(n*) near-optimal certified per query" in out
    assert "none.json not found" in out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--coefficients", "no/such/coefficients.json"], "coefficients file not found"),
        (["--n", "0"], "--n"),
        (["--seed", "-1"], "--seed"),
        (["--n", "3", "--pso-cases", "4"], "--pso-cases"),
        (["--ompl-time", "0"], "--ompl-time"),
        (["--ompl-time", "nan"], "--ompl-time"),
        (["--ompl-margin", "-0.001"], "--ompl-margin"),
        (["--repeats", "0"], "--repeats"),
        (["--toppra-gridpoints", "1"], "--toppra-gridpoints"),
        (["--batch-repeats", "0"], "--batch-repeats"),
        (["--pso-swarm-size", "1"], "--pso-swarm-size"),
        (["--n", "three"], "--n"),
        (["--run-build", "2"], "--run-build"),
        (["--json", "/proc/x"], "--json"),
        (["--json", "/etc/passwd/x.json"], "--json"),
        (["--region-map", "no/such/region_map.json"], "no/such/region_map.json"),
    ],
)
def test_bad_input_gives_one_line_and_status_2(
    capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    if argv[0] != "--coefficients":
        argv = ["--coefficients", "paper", *argv]
    status, out, err = run_main(capsys, *argv, "--quiet")
    assert status == EXIT_USAGE
    assert message in err
    assert len(err.strip().splitlines()) == 1
    assert "Traceback" not in err
    assert out == ""


def test_malformed_build_timing_is_bad_input(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    broken = tmp_path / "build_timing.json"
    broken.write_text('{"jobs": 1}\n')
    status, _, err = run_main(capsys, "--coefficients", "paper", "--build-timing", str(broken), "--quiet")
    assert status == EXIT_USAGE
    assert "not a build timing file" in err and len(err.strip().splitlines()) == 1


def test_solver_config_takes_the_builds_settings_from_provenance() -> None:
    from pipeline import load_coefficients

    coefficients = load_coefficients("paper")
    config, source = bench_run.solver_config(coefficients, bench_results.BenchSettings())
    assert "defaults" in source and config.family.name == "paper" and config.polish
    recorded = type(coefficients)(
        **{
            **coefficients.__dict__,
            "extra": {"provenance": {"pso": {"swarm_size": 7, "iterations": 9, "restarts": 2}, "polish": False}},
        }
    )
    config, source = bench_run.solver_config(recorded, bench_results.BenchSettings(pso_iterations=3))
    assert (config.pso.swarm_size, config.pso.iterations, config.pso.restarts) == (7, 3, 2)
    assert config.polish is False
    assert "build" in source and "iterations" in source


def test_another_arm_is_refused_naming_both(capsys: pytest.CaptureFixture[str], double_pendulum_urdf) -> None:
    status, _, err = run_main(capsys, "--coefficients", "paper", "--urdf", str(double_pendulum_urdf), "--quiet")
    assert status == EXIT_USAGE and "0.3, 0.35" in err and "0.1, 0.2" in err and "--urdf" in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_batched_rows_cycle_the_obstacles_and_count_only_the_first_n(built: Path) -> None:
    coefficients = load_coefficients(built)
    region_map = load_region_map(built.with_name(DEFAULT_MAP_NAME))
    cases = sample_cases(SweepRange.from_fitted(coefficients.fitted_range_m), 7, 4)
    cycled = bench_run._batch_cases(cases, 30)
    assert cycled.shape == (30, 2) and np.array_equal(cycled[7:14], cases) and np.array_equal(cycled[28:], cases[:2])
    assert bench_run._batch_cases(cases, 3).shape == (7, 2)  # never fewer than the obstacles
    _, batch = bench_methods.bench_range_batched(coefficients, cycled, region_map, 1)
    margin = coefficients.scene.margin_m
    assert bench_methods.batch_range_counts(batch, margin, 7).in_range == 7
    assert bench_methods.batch_range_counts(batch, margin).in_range == 30
    with pytest.raises(InvalidParameterError, match="batch-size"):
        bench_results.BenchSettings(batch_size=0)
