"""The acceptance sweep over coefficients that vary the obstacle's centre x beside (L, W): every
variable sampled over its fitted range (seeded), each case generated and measured with its x,
looked up in the (L, W, x) region map's leaf holding it (no contradiction, and a doctored map is
caught), x in the records and the summary, and the map drawn in slices of x."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from pipeline.cli import EXIT_USAGE
from pipeline.io.jsonio import write_json_atomic
from pipeline.offline.coefficients import Coefficients
from pipeline.online.loading import load_coefficients
from verify.acceptance.cases import SweepRange, sample_cases
from verify.acceptance.metrics import MeasureSettings, measure_case
from verify.acceptance.range_check import check_range
from verify.acceptance.run import run_sweep
from verify.sweep import main

FAST = MeasureSettings(time_samples=200)
X_RANGE = (-0.03, 0.03)


@pytest.fixture(scope="module")
def x_file(tmp_path_factory, over_x) -> Path:
    """The paper's Eq. 9 lifted to (L, W, x) as a file, with its coarse (L, W, x) region map
    beside it (512 leaves, a few seconds)."""
    from pipeline.certify.map_files import save_region_map
    from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range

    folder = tmp_path_factory.mktemp("over_x")
    path = folder / "coefficients.json"
    write_json_atomic(path, over_x(load_coefficients("paper"), x_range_m=X_RANGE).to_json())
    coefficients = load_coefficients(path, region_map=None)
    config = RangeCertificateConfig(min_cell=1 / 8, boundary_cell=1 / 4, max_depth_s=12)
    save_region_map(certify_range(coefficients, config), folder / "region_map.json")
    return path


@pytest.fixture(scope="module")
def x_coefficients(x_file: Path) -> Coefficients:
    coefficients = load_coefficients(x_file)
    assert coefficients.region_map is not None and coefficients.region_map.axes == ("L", "W", "x")
    return coefficients


def test_every_variable_is_sampled_over_its_range_and_lw_as_before(x_coefficients: Coefficients) -> None:
    box = SweepRange.from_fitted(x_coefficients.fitted_range_m, x_coefficients.variables.names)
    assert box.names == ("L", "W", "x") and box.extra_m == (("x", X_RANGE),)
    cases = sample_cases(box, 400, 5)
    assert cases.shape == (400, 3)
    np.testing.assert_array_equal(cases, sample_cases(box, 400, 5))
    for column, (lo, hi) in enumerate(box.ranges_m):
        assert np.all((cases[:, column] >= lo) & (cases[:, column] <= hi))
        assert cases[:, column].min() < lo + 0.05 * (hi - lo) and cases[:, column].max() > hi - 0.05 * (hi - lo)
    # The (L, W) columns are the (L, W) sweep's cases for the same seed.
    np.testing.assert_array_equal(
        cases[:, :2], sample_cases(SweepRange.from_fitted(x_coefficients.fitted_range_m), 400, 5)
    )
    assert box.to_dict() == {"L": [0.2, 0.3], "W": [0.08, 0.12], "x": list(X_RANGE)}


def test_a_case_is_measured_with_the_obstacle_moved(x_coefficients: Coefficients, arm) -> None:
    left = measure_case(x_coefficients, 0.27, 0.11, arm, FAST, extra=(("x", -0.03),))
    right = measure_case(x_coefficients, 0.27, 0.11, arm, FAST, extra=(("x", 0.03),))
    assert left.extra == (("x", -0.03),) and left.to_json()["x"] == -0.03
    assert left.point == (0.27, 0.11, -0.03)
    assert abs(left.clearance_m - right.clearance_m) > 1e-4  # another obstacle, another clearance


def test_the_cli_samples_x_checks_the_map_and_draws_slices(capsys, x_file: Path, tmp_path: Path) -> None:
    out_file, plots = tmp_path / "sweep.json", tmp_path / "plots"
    argv = ["--coefficients", str(x_file), "--n", "30", "--seed", "2", "--samples", "200", "--no-progress"]
    main([*argv, "--json", str(out_file), "--plots", str(plots)])
    out = capsys.readouterr().out
    assert "30 over (L, W, x), L in [0.2000, 0.3000] m, W in [0.0800, 0.1200] m, x in [-0.0300, 0.0300] m" in out
    document = json.loads(out_file.read_text())
    xs = np.array([case["x"] for case in document["cases"]])
    assert len(set(xs)) == 30 and np.all((xs >= X_RANGE[0]) & (xs <= X_RANGE[1]))
    assert list(document["cases"][0])[:4] == ["index", "L", "W", "x"]
    assert document["provenance"]["range_m"]["x"] == list(X_RANGE)
    check = document["region_map"]["cross_check"]
    assert check["checked"] and check["passed"] and check["violations"] == []
    assert check["n_out_of_range"] == 0 and check["sampled_clearance"]["checked"] == 30 - check["n_not_measured"]
    assert "x_m" in document["region_map"]["worst_cell"]
    assert "map check       PASS" in out
    assert (plots / "slices.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not (plots / "region_map.png").exists()  # the (L, W) drawing of a map is for (L, W) maps
    assert all(case["x"] == 0.0 for case in document["case_studies"])  # x at its range's midpoint


def test_same_seed_same_results_and_x_matters_to_the_map(x_coefficients: Coefficients) -> None:
    def run(seed: int):
        return run_sweep(
            str(x_coefficients.source),
            n=8,
            seed=seed,
            settings=FAST,
            coefficients=x_coefficients,
            region_map=x_coefficients.region_map,
            case_studies=False,
        )

    first, again, other = run(4), run(4), run(5)
    assert [c.to_json() for c in first.cases] == [c.to_json() for c in again.cases]
    assert [c.point for c in first.cases] != [c.point for c in other.cases]
    assert first.range_check is not None and first.range_check.checked and first.range_check.passed
    # A map claiming more than the motions keep is contradicted, leaf by leaf in (L, W, x).
    region_map = x_coefficients.region_map
    doctored = dataclasses.replace(region_map, clearance_bound_m=np.full_like(region_map.clearance_bound_m, 1.0))
    contradicted = check_range(doctored, x_coefficients, first.cases, FAST)
    measured = [c.index for c in first.cases if c.measurement is not None]
    assert contradicted.sampled is not None and list(contradicted.sampled.violations) == measured
    assert not contradicted.passed


def test_compare_needs_the_same_variables(capsys, x_file: Path) -> None:
    status = main(["--compare", "paper", str(x_file), "--n", "2", "--no-progress"])
    err = capsys.readouterr().err
    assert status == EXIT_USAGE
    assert len(err.strip().splitlines()) == 1 and "same variables" in err
