"""The acceptance verifier's command line (verify.sweep) and library (verify.acceptance): bad input gives one clear
line and exit status 2, the JSON schema, determinism under a seed, and results independent of
--jobs."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pipeline.cli import EXIT_FAILED, EXIT_OK, EXIT_USAGE
from pipeline.exceptions import InvalidParameterError
from pipeline.io.jsonio import write_json_atomic
from verify import sweep
from verify.acceptance.cases import SweepRange, case_study_sizes, on_doe_grid, sample_cases
from verify.acceptance.metrics import MeasureSettings
from verify.acceptance.results import CaseResult
from verify.acceptance.run import run_cases, run_sweep
from verify.sweep import build_parser, main

FAST = ["--samples", "200", "--no-progress"]
CASE_KEYS = (
    "L",
    "W",
    "T_s",
    "clearance_m",
    "certified_clearance_m",
    "endpoint_error_start_m",
    "endpoint_error_end_m",
    "tracking_max_m",
    "tracking_rms_m",
    "passed",
    "extrapolated",
    "peak_velocity_rad_s",
    "peak_acceleration_rad_s2",
)


def run_main(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    status = main(list(argv))
    captured = capsys.readouterr()
    return status, captured.out, captured.err


# --------------------------------------------------------------------------------------------
# Command line: help and bad input.


def test_help_lists_every_option_with_units_and_defaults(capsys: pytest.CaptureFixture[str]) -> None:
    status, out, _ = run_main(capsys, "--help")
    assert status == 0
    for action in build_parser()._actions:
        for option in action.option_strings:
            assert option in out
    for text in ("[m]", "default: results/coefficients.json", "default: 1000", "default: 0.005", "[rad/s^2]"):
        assert text in " ".join(out.split())


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--n", "0"], "--n"),
        (["--n", "-5"], "--n"),
        (["--seed", "-1"], "--seed"),
        (["--jobs", "-2"], "--jobs"),
        (["--samples", "1"], "--samples"),
        (["--range", "0.30", "0.20", "0.08", "0.12"], "LMIN <= LMAX"),
        (["--range", "0.20", "0.30", "0.12", "0.08"], "WMIN <= WMAX"),
        (["--range", "-0.1", "0.30", "0.08", "0.12"], "LMIN"),
        (["--range", "0.2", "0.30", "0", "0.12"], "WMIN"),
        (["--range", "nan", "0.30", "0.08", "0.12"], "LMIN"),
        (["--range", "0.2", "0.3"], "--range"),
        (["--n", "ten"], "--n"),
        (["--bogus"], "unrecognized"),
        (["--coefficients", "/nonexistent/coefficients.json"], "not found"),
        (["--json", "/proc/x"], "--json"),
        (["--plots", "/proc/x"], "--plots"),
        (["--html", "/proc/x/view.html"], "--html"),
        (["--resolution", "0"], "--resolution"),
        (["--tolerance", "-1e-5"], "--tolerance"),
        (["--max-endpoint-error", "-1"], "--max-endpoint-error"),
        (["--min-clearance", "inf"], "--min-clearance"),
        (["--max-acceleration", "1", "0"], "--max-acceleration"),
    ],
)
def test_bad_input_is_one_clear_line_and_status_2(
    capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    status, out, err = run_main(capsys, *argv, "--no-progress")
    assert status == EXIT_USAGE
    assert "Traceback" not in err + out
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "error" in lines[0] and message in lines[0], err


def test_missing_default_file_says_what_to_do(capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    status, _, err = run_main(capsys, "--no-progress")
    assert status == EXIT_USAGE
    assert "results/coefficients.json" in err and "--coefficients paper" in err and "Traceback" not in err


@pytest.mark.parametrize("content", ["{not json", "[]", '{"family": "paper"}', ""])
def test_malformed_coefficients_file(capsys: pytest.CaptureFixture[str], tmp_path: Path, content: str) -> None:
    bad = tmp_path / "coefficients.json"
    bad.write_text(content)
    status, _, err = run_main(capsys, "--coefficients", str(bad), "--n", "2", *FAST)
    assert status == EXIT_USAGE
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1 and str(bad) in err


def test_bad_input_in_a_real_process_has_no_traceback() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "verify.sweep", "--range", "0.3", "0.2", "0.08", "0.12"],
        cwd=Path(__file__).resolve().parents[2],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == EXIT_USAGE
    assert "Traceback" not in done.stderr and "LMIN <= LMAX" in done.stderr


def test_viewer_flags_fail_clearly_when_the_viewer_is_unavailable(capsys, monkeypatch) -> None:
    real_import = sweep.importlib.import_module

    def no_viewer(name: str, *args, **kwargs):
        if name.startswith("verify.viewer"):
            raise ImportError(f"No module named {name!r}")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(sweep.importlib, "import_module", no_viewer)
    for flag in (["--meshcat"], ["--html", "view.html"]):
        status, _, err = run_main(capsys, "--coefficients", "paper", "--n", "1", *FAST, *flag)
        assert status == EXIT_USAGE and "viewer" in err and "Traceback" not in err


def test_html_flag_hands_the_cases_to_the_viewer(capsys, monkeypatch, tmp_path: Path) -> None:
    """--html calls verify.viewer.sweep_view.sweep_html(cases, regenerate, path, arm=..., region_map=...) after
    the sweep (no region map for the paper's Eq. 9 unless --region-map names one)."""
    calls = []

    class FakeViewer:
        @staticmethod
        def sweep_html(cases, regenerate, path, *, arm=None, region_map=None):
            generated = regenerate(cases[0].L_m, cases[0].W_m)
            calls.append((cases, generated, path, arm, region_map))

        @staticmethod
        def show_sweep(cases, regenerate, *, arm=None, region_map=None):  # pragma: no cover - not called here
            raise AssertionError("--meshcat was not given")

    real_import = sweep.importlib.import_module
    monkeypatch.setattr(
        sweep.importlib,
        "import_module",
        lambda name, *a, **k: FakeViewer if name == "verify.viewer.sweep_view" else real_import(name, *a, **k),
    )
    page = tmp_path / "view.html"
    status, out, _ = run_main(capsys, "--coefficients", "paper", "--n", "2", *FAST, "--html", str(page))
    assert status in (EXIT_OK, EXIT_FAILED) and len(calls) == 1
    cases, generated, path, arm, region_map = calls[0]
    assert path == page and arm is not None and len(cases) == 2 and region_map is None
    assert isinstance(cases[0], CaseResult) and cases[0].certified_clearance_m is not None  # typed, not dicts
    assert generated.obstacle.length_m == cases[0].L_m
    assert f"wrote {page}" in out


def test_coefficients_for_another_arm_are_refused(capsys: pytest.CaptureFixture[str], double_pendulum_urdf) -> None:
    status, _, err = run_main(capsys, "--coefficients", "paper", "--n", "1", *FAST, "--urdf", str(double_pendulum_urdf))
    assert status == EXIT_USAGE and "links of" in err and "0.1, 0.2" in err and "Traceback" not in err


# --------------------------------------------------------------------------------------------
# Library pieces.


def test_sample_cases_is_seeded_and_inside_the_range() -> None:
    chosen = SweepRange((0.2, 0.3), (0.08, 0.12))
    a, b = sample_cases(chosen, 50, 4), sample_cases(chosen, 50, 4)
    assert np.array_equal(a, b) and not np.array_equal(a, sample_cases(chosen, 50, 5))
    assert np.all((a[:, 0] >= 0.2) & (a[:, 0] <= 0.3) & (a[:, 1] >= 0.08) & (a[:, 1] <= 0.12))
    single = sample_cases(SweepRange((0.25, 0.25), (0.1, 0.1)), 3, 0)
    assert np.all(single == [0.25, 0.1])
    with pytest.raises(InvalidParameterError):
        SweepRange((0.3, 0.2), (0.08, 0.12))
    with pytest.raises(InvalidParameterError):
        sample_cases(chosen, 0, 0)


def test_case_studies_are_inside_the_range_and_off_the_grid() -> None:
    fitted = SweepRange((0.2, 0.3), (0.08, 0.12))
    sizes = case_study_sizes(fitted)
    assert sizes == [(0.27, 0.11), (0.22, 0.09), (0.28, 0.085), (0.23, 0.115)]
    for length, width in sizes:
        assert fitted.contains(SweepRange((length, length), (width, width)))
        assert not on_doe_grid(length, width)
    assert on_doe_grid(0.25, 0.10)


def test_write_json_atomic_replaces_and_leaves_no_temporary(tmp_path: Path) -> None:
    target = tmp_path / "out.json"
    target.write_text("old")
    write_json_atomic(target, {"a": float("nan"), "b": (1, 2), "c": np.float64(0.5)})
    assert json.loads(target.read_text()) == {"a": None, "b": [1, 2], "c": 0.5}
    assert sorted(os.listdir(tmp_path)) == ["out.json"]


# --------------------------------------------------------------------------------------------
# Runs on the paper's Eq. 9 (needs pipeline.offline.coefficients and pipeline.online.generator).


def test_json_schema_and_summary(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    out_file = tmp_path / "sweep.json"
    status, out, _ = run_main(
        capsys, "--coefficients", "paper", "--n", "5", "--seed", "3", *FAST, "--json", str(out_file)
    )
    data = json.loads(out_file.read_text())
    assert set(data) >= {"cases", "summary", "provenance"}
    assert len(data["cases"]) == 5
    for case in data["cases"]:
        for key in CASE_KEYS:
            assert key in case
        assert case["certified_clearance_m"] <= case["clearance_m"]
    summary = data["summary"]
    assert summary["n_cases"] == 5 and summary["n_passed"] == sum(c["passed"] for c in data["cases"])
    for key in (
        "pass_rate",
        "clearance_min_m",
        "clearance_median_m",
        "endpoint_error_median_m",
        "endpoint_error_p99_m",
        "endpoint_error_max_m",
        "tracking_max_m",
        "keep_margin_fraction",
        "worst_clearance",
        "failing",
    ):
        assert key in summary
    provenance = data["provenance"]
    assert provenance["seed"] == 3 and len(provenance["coefficients"]["sha256"]) == 64
    assert provenance["packages"]["pin"] and provenance["packages"]["coal"] and provenance["packages"]["numpy"]
    assert status == (EXIT_OK if summary["all_passed"] else EXIT_FAILED)
    assert "PASSED" in out and "endpoint error" in out and "clearance" in out
    if status == EXIT_FAILED:  # failing cases are listed with their (L, W)
        for case in (c for c in data["cases"] if not c["passed"]):
            assert f"L = {case['L']:.4f} m, W = {case['W']:.4f} m" in out


def test_failing_cases_are_listed_and_exit_1(capsys: pytest.CaptureFixture[str]) -> None:
    status, out, _ = run_main(capsys, "--coefficients", "paper", "--n", "3", *FAST, "--max-endpoint-error", "1e-6")
    assert status == EXIT_FAILED
    assert "FAILED: 3 case(s)" in out and out.count("endpoint error at") >= 3 and "verdict: FAIL" in out


def test_determinism_with_seed() -> None:
    settings = MeasureSettings(time_samples=200)
    a = run_sweep("paper", n=4, seed=11, settings=settings, case_studies=False).to_json()
    b = run_sweep("paper", n=4, seed=11, settings=settings, case_studies=False).to_json()
    c = run_sweep("paper", n=4, seed=12, settings=settings, case_studies=False).to_json()
    assert a["cases"] == b["cases"] and a["summary"] == b["summary"]
    assert [x["L"] for x in a["cases"]] != [x["L"] for x in c["cases"]]


def test_results_do_not_depend_on_jobs() -> None:
    cases = sample_cases(SweepRange((0.2, 0.3), (0.08, 0.12)), 6, 21)
    settings = MeasureSettings(time_samples=200)
    serial = run_cases("paper", cases, settings, jobs=1)
    parallel = run_cases("paper", cases, settings, jobs=2)
    assert [r.to_json() for r in serial] == [r.to_json() for r in parallel]
    assert [r.index for r in parallel] == list(range(6))


def test_extrapolation_is_reported(capsys: pytest.CaptureFixture[str]) -> None:
    status, out, _ = run_main(
        capsys, "--coefficients", "paper", "--n", "3", *FAST, "--range", "0.31", "0.33", "0.13", "0.14"
    )
    assert "EXTRAPOLATION" in out and "3 / 3 cases outside the fitted range" in out
    assert status in (EXIT_OK, EXIT_FAILED)


def test_compare_prints_both_on_the_same_cases(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    out_file = tmp_path / "compare.json"
    status, out, _ = run_main(
        capsys,
        "--compare",
        "paper",
        "paper",
        "--n",
        "2",
        *FAST,
        "--json",
        str(out_file),
        "--plots",
        str(tmp_path / "p"),
    )
    assert "comparison on the same 2 cases" in out and "verdicts:" in out
    runs = json.loads(out_file.read_text())["runs"]
    assert len(runs) == 2 and runs[0]["cases"] == runs[1]["cases"]
    pngs = sorted(p.name for p in (tmp_path / "p").rglob("*.png"))
    assert pngs.count("clearance_map.png") == 2 and pngs.count("case_studies.png") == 2
    assert status in (EXIT_OK, EXIT_FAILED)


@pytest.mark.parametrize(
    "argv",
    [["--json", "/proc/x"], ["--plots", "/proc/x"], ["--html", "/proc/x"], ["--json", "/proc/x", "--n", "100000"]],
)
def test_output_paths_are_refused_before_any_work(capsys, tmp_path: Path, monkeypatch, argv: list[str]) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sweep, "run_sweep", lambda *a, **k: pytest.fail("the sweep ran despite a bad output path"))
    status, out, err = run_main(capsys, "--coefficients", "paper", *argv, "--no-progress")
    assert status == EXIT_USAGE and out == "" and "verdict" not in out
    lines = err.strip().splitlines()
    assert len(lines) == 1 and argv[0] in lines[0] and lines[0].startswith("python -m verify.sweep: error:")
    assert ".tmp" not in err and "Traceback" not in err and list(tmp_path.iterdir()) == []


def test_the_coefficients_in_use_are_named_first(capsys) -> None:
    status, out, _ = run_main(capsys, "--coefficients", "paper", "--n", "1", *FAST)
    assert status in (EXIT_OK, EXIT_FAILED)
    assert out.splitlines()[0].startswith("coefficients: paper (paper, sha256 ")


# --------------------------------------------------------------------------------------------
# The region map (range certificate): reported, cross-checked, drawn.


@pytest.fixture(scope="module")
def paper_map_file(tmp_path_factory) -> Path:
    """The paper's Eq. 9 certified at a coarse setting (256 leaves, about 2 s), as one file of the JSON
    format (its leaves in the document, so that a test can edit them)."""
    from pipeline import load_coefficients
    from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
    from pipeline.certify.region_map import save_region_map_json

    path = tmp_path_factory.mktemp("map") / "paper_map.json"
    save_region_map_json(
        certify_range(load_coefficients("paper"), RangeCertificateConfig(min_cell=1 / 16, boundary_cell=1 / 8)), path
    )
    return path


def _edited_map(source: Path, target: Path, edit) -> Path:
    document = json.loads(source.read_text())
    edit(document)
    target.write_text(json.dumps(document))
    return target


def test_the_map_is_reported_checked_written_and_drawn(capsys, tmp_path: Path, paper_map_file: Path) -> None:
    out_file, plots = tmp_path / "sweep.json", tmp_path / "plots"
    status, out, _ = run_main(
        capsys,
        "--coefficients",
        "paper",
        "--n",
        "6",
        *FAST,
        "--region-map",
        str(paper_map_file),
        "--json",
        str(out_file),
        "--plots",
        str(plots),
    )
    data = json.loads(out_file.read_text())
    report = data["region_map"]
    assert report["belongs_to_coefficients"] is True and report["path"] == str(paper_map_file)
    assert set(report["area_fraction"]) == {"margin", "collision_free", "infeasible", "undecided"}
    check = report["cross_check"]
    assert check["checked"] and check["passed"] and check["violations"] == [] and check["n_cases"] == 6
    assert check["endpoint_error"]["checked"] == check["sampled_clearance"]["checked"] == 6
    # Decide mode (the default): only the bounds below the margin are tight enough to compare.
    assert check["certified_clearance"]["checked"] + check["n_certificate_decided"] == 6
    assert data["passed"] == data["summary"]["all_passed"]  # the map holds: the verdict is the cases'
    assert status == (EXIT_OK if data["passed"] else EXIT_FAILED)
    for text in ("region map", "belongs to these coefficients", "map bounds", "map check       PASS"):
        assert text in out
    assert f"clearance bound min {report['clearance_bound_min_m'] * 1e3:.3f} mm" in out
    png = plots / "region_map.png"
    assert png.is_file() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and f"wrote {png}" in out


def test_a_contradicted_map_fails_the_run(capsys, tmp_path: Path, paper_map_file: Path) -> None:
    def raise_all(document: dict) -> None:
        bounds = document["cells"]["clearance_bound_m"]
        document["cells"]["clearance_bound_m"] = [0.2 for _ in bounds]  # 20 cm: above every clearance

    wrong = _edited_map(paper_map_file, tmp_path / "wrong.json", raise_all)
    out_file = tmp_path / "sweep.json"
    status, out, _ = run_main(
        capsys, "--coefficients", "paper", "--n", "3", *FAST, "--region-map", str(wrong), "--json", str(out_file)
    )
    data = json.loads(out_file.read_text())
    assert status == EXIT_FAILED and data["passed"] is False
    assert data["region_map"]["cross_check"]["violations"] == [0, 1, 2]
    assert "REGION MAP CONTRADICTED by 3 case(s)" in out and "the region map is contradicted" in out
    assert "map: clearance >= 200.000 mm" in out


def test_a_map_of_other_coefficients_is_reported_not_used(capsys, tmp_path: Path, paper_map_file: Path) -> None:
    def other(document: dict) -> None:
        document["coefficients"]["sha256"] = "ab" * 32
        document["cells"]["clearance_bound_m"] = [0.2 for _ in document["cells"]["clearance_bound_m"]]

    stale = _edited_map(paper_map_file, tmp_path / "other.json", other)
    out_file = tmp_path / "sweep.json"
    status, out, _ = run_main(
        capsys, "--coefficients", "paper", "--n", "2", *FAST, "--region-map", str(stale), "--json", str(out_file)
    )
    data = json.loads(out_file.read_text())
    assert "does NOT belong to these coefficients (made for sha256 abababababab)" in out
    assert (
        data["region_map"]["belongs_to_coefficients"] is False and data["region_map"]["cross_check"]["checked"] is False
    )
    assert data["passed"] == data["summary"]["all_passed"] and status in (EXIT_OK, EXIT_FAILED)


def test_the_map_beside_the_coefficients_is_found_and_can_be_skipped(capsys, tmp_path: Path, paper_map_file) -> None:
    from pipeline import load_coefficients
    from pipeline.certify.map_files import load_region_map
    from pipeline.offline.coefficients import save_coefficients

    source = tmp_path / "coefficients.json"
    save_coefficients(load_coefficients("paper"), source)  # the same bytes as the paper's: the map belongs
    (tmp_path / "region_map.json").write_bytes(paper_map_file.read_bytes())
    status, out, _ = run_main(capsys, "--coefficients", str(source), "--n", "1", *FAST)
    cells = load_region_map(paper_map_file).size
    assert f"region map      {tmp_path / 'region_map.json'} ({cells} cells, belongs" in out
    status, out, _ = run_main(capsys, "--coefficients", str(source), "--n", "1", *FAST, "--no-region-map")
    assert "region map" not in out and status in (EXIT_OK, EXIT_FAILED)
    status, out, _ = run_main(capsys, "--coefficients", "paper", "--n", "1", *FAST)  # Eq. 9: no default map
    assert "region map" not in out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--region-map", "/nonexistent/map.json"], "--region-map"),
        (["--region-map", "m.json", "--no-region-map"], "not allowed with"),
    ],
)
def test_bad_region_map_options_are_one_line_and_status_2(capsys, argv: list[str], message: str) -> None:
    status, out, err = run_main(capsys, "--coefficients", "paper", *argv)
    assert status == EXIT_USAGE and out == "" and message in err and "Traceback" not in err


def test_decide_mode_gives_the_tight_modes_verdicts() -> None:
    """The default certificate (decide the margin, tighten below it) answers "collision-free?" and
    "keeps the margin?" as the tight certificate does, and its bounds below the margin are as tight;
    every bound is a lower bound of the case's own Coal samples."""
    cases = sample_cases(SweepRange((0.2, 0.3), (0.08, 0.12)), 40, 5)
    decide = run_cases("paper", cases, MeasureSettings(), jobs=1)
    tight = run_cases("paper", cases, MeasureSettings(certificate_mode="tight"), jobs=1)
    assert any(not r.certificate.keeps_margin for r in tight) and any(r.certificate.keeps_margin for r in tight)
    for d, t in zip(decide, tight, strict=True):
        assert (d.certificate.collision_free, d.certificate.keeps_margin, d.passed) == (
            t.certificate.collision_free,
            t.certificate.keeps_margin,
            t.passed,
        )
        assert d.certified_clearance_m <= d.clearance_m and t.certified_clearance_m <= t.clearance_m
        if d.certificate.tight:
            assert d.certified_clearance_m == pytest.approx(t.certified_clearance_m, abs=1e-12)
        else:
            assert d.certificate.keeps_margin and d.certified_clearance_m <= t.certified_clearance_m + 2e-5


def test_certificate_mode_is_checked() -> None:
    with pytest.raises(InvalidParameterError, match="certificate_mode"):
        MeasureSettings(certificate_mode="loose")


def test_a_malformed_map_beside_the_coefficients_names_the_way_past_it(capsys, tmp_path: Path) -> None:
    """A broken region_map.json the sweep found on its own stops it with one line that says
    --no-region-map skips it; with that flag the same sweep runs."""
    from pipeline.offline.coefficients import paper_data_path

    coefficients = tmp_path / "coefficients.json"
    coefficients.write_text(paper_data_path("paper_eq9_coefficients.json").read_text())
    (tmp_path / "region_map.json").write_text("{not json")
    status, _, err = run_main(capsys, "--coefficients", str(coefficients), "--n", "2", *FAST)
    assert status == EXIT_USAGE
    assert len(err.strip().splitlines()) == 1 and "region_map.json" in err and "--no-region-map" in err
    status, out, err = run_main(capsys, "--coefficients", str(coefficients), "--n", "2", "--no-region-map", *FAST)
    assert status in (EXIT_OK, EXIT_FAILED) and "Traceback" not in err and "region map" not in out


def test_a_map_beside_of_other_coefficients_is_a_one_line_warning_and_not_used(
    capsys, tmp_path: Path, paper_map_file: Path
) -> None:
    from pipeline.offline.coefficients import paper_data_path

    source = tmp_path / "coefficients.json"
    source.write_text(paper_data_path("paper_eq9_coefficients.json").read_text() + "\n")  # other sha256
    (tmp_path / "region_map.json").write_bytes(paper_map_file.read_bytes())
    status, out, err = run_main(capsys, "--coefficients", str(source), "--n", "1", *FAST)
    assert status in (EXIT_OK, EXIT_FAILED) and "region map" not in out
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("python -m verify.sweep: warning: ")
    assert str(tmp_path / "region_map.json") in lines[0] and "python -m pipeline.certify_range" in lines[0]


# --------------------------------------------------------------------------------------------
# The arm recorded with the coefficients; progress.


@pytest.fixture
def own_arm_coefficients(tmp_path: Path) -> Path:
    """The paper's Eq. 9 saved as a build of another URDF would leave it: fitted (by its record)
    for arm.urdf beside it, here the shipped arm's geometry under other bytes."""
    import dataclasses
    import hashlib

    from pipeline import load_coefficients
    from pipeline.model.arm import DEFAULT_URDF
    from pipeline.offline.coefficients import save_coefficients

    urdf = tmp_path / "arm.urdf"
    urdf.write_text(DEFAULT_URDF.read_text() + "\n<!-- the arm of this build -->\n")
    paper = load_coefficients("paper", region_map=None)
    record = {"urdf": "arm.urdf", "urdf_sha256": hashlib.sha256(urdf.read_bytes()).hexdigest()}
    source = tmp_path / "coefficients.json"
    save_coefficients(dataclasses.replace(paper, extra={**paper.extra, "provenance": record}), source)
    return source


def test_the_arm_recorded_with_the_coefficients_is_measured_and_recorded(
    capsys, tmp_path: Path, own_arm_coefficients: Path
) -> None:
    out_file = tmp_path / "sweep.json"
    argv = ["--coefficients", str(own_arm_coefficients), "--n", "2", *FAST, "--json", str(out_file)]
    status, _, err = run_main(capsys, *argv)
    assert status in (EXIT_OK, EXIT_FAILED) and err == ""
    assert json.loads(out_file.read_text())["provenance"]["urdf"]["path"] == str(tmp_path / "arm.urdf")
    from pipeline.model.arm import DEFAULT_URDF

    status, _, _ = run_main(capsys, *argv, "--urdf", str(DEFAULT_URDF))  # the same links: accepted
    assert json.loads(out_file.read_text())["provenance"]["urdf"]["path"] == str(DEFAULT_URDF)
    (tmp_path / "arm.urdf").unlink()
    status, _, err = run_main(capsys, *argv)
    assert status == EXIT_USAGE and len(err.strip().splitlines()) == 1 and "--urdf" in err and "arm.urdf" in err


def test_worker_processes_load_the_arm_the_sweep_resolved(monkeypatch, own_arm_coefficients: Path) -> None:
    """With --jobs > 1 the workers get the resolved URDF (arm.urdf beside the coefficients), in
    chunks small enough for the progress bar to advance."""
    import verify.acceptance.run as run_module

    seen = {}

    def in_process(function, items, *, jobs, chunk_size, on_done):
        seen.update(urdf=function.args[0].urdf_path, jobs=jobs, chunk_size=chunk_size)
        results = [function(item) for item in items]
        on_done(results)
        return results

    monkeypatch.setattr(run_module, "process_map", in_process)
    cases = sample_cases(SweepRange((0.2, 0.3), (0.08, 0.12)), 3, 0)
    results = run_cases(str(own_arm_coefficients), cases, MeasureSettings(time_samples=200), jobs=2)
    assert seen == {"urdf": str(own_arm_coefficients.with_name("arm.urdf")), "jobs": 2, "chunk_size": 1}
    assert len(results) == 3


def test_chunks_are_small_enough_for_the_bar_to_advance() -> None:
    from verify.acceptance.run import chunk_size

    assert chunk_size(20_000, 2) == 16  # 1,250 chunks
    assert chunk_size(1000, 2) == 8 and chunk_size(3, 4) == 1  # about 64 chunks per process


def test_no_progress_bar_when_stderr_is_not_a_terminal(capsys) -> None:
    status, _, err = run_main(capsys, "--coefficients", "paper", "--n", "2", "--samples", "200")  # bars requested
    assert status in (EXIT_OK, EXIT_FAILED) and err == ""
    status, _, err = run_main(capsys, "--coefficients", "paper", "--n", "2", "--samples", "200", "--progress")
    assert err == ""
