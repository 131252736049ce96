"""The benchmark's command line (verify.bench) and library (verify.benchmark): it runs on tiny
settings and writes the JSON schema, reports build timing files, skips OMPL cleanly when it is
missing, and gives one clear line and exit status 2 on bad input. No timing is asserted: these machines are noisy."""

from __future__ import annotations

import contextlib
import io
import json
import math
import warnings
from pathlib import Path

import pytest

from pipeline.cli import EXIT_OK, EXIT_USAGE, HelpFormatter
from pipeline.exceptions import EndpointConstraintWarning
from pipeline.io.jsonio import write_json_atomic
from verify.bench import build_parser, main
from verify.benchmark import ompl_planner as planner
from verify.benchmark import results as bench_results
from verify.benchmark import run as bench_run

#: Tiny settings: 3 obstacles, a 4-particle 2-iteration PSO without polish on one of them.
TINY = [
    "--coefficients",
    "paper",
    "--n",
    "3",
    "--repeats",
    "3",
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
def tiny_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[int, str, dict]:
    """One tiny benchmark run, with a build timing file to report and a tiny 3 x 3 build run by the
    benchmark; (status, stdout, JSON)."""
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
        status = main([*TINY, "--build-timing", str(timing), "--run-build", "3", "--json", str(out_json)])
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
    for key in ("command", "coefficients", "settings", "margin_m", "cases", "methods", "sweep", "build", "machine"):
        assert key in data
    assert data["command"].startswith("python -m verify.bench --coefficients paper")
    assert len(data["cases"]) == 3
    keys = [m["key"] for m in data["methods"]]
    expected = ["a", "a_batch", "b", "c"] + (["d", "d_cert"] if planner.ompl_available() else [])
    assert keys == expected
    for method in data["methods"]:
        for key in METHOD_KEYS:
            assert key in method, (method["key"], key)
        assert method["median_s"] > 0
        assert 0.0 <= method["answered_fraction"] <= 1.0
        if method["answered"]:
            assert 0.0 <= method["certified_fraction"] <= 1.0
            assert method["keeps_margin"] <= method["certified_collision_free"] <= method["answered"]
        assert method["label"] in out
    a, b = data["methods"][0], data["methods"][2]
    assert math.isclose(a["ratio_to_a"], 1.0) and math.isclose(b["ratio_to_b"], 1.0)
    assert a["timed_runs"] == 3 * 3  # 3 passes over 3 obstacles
    c = data["methods"][3]
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


def test_missing_ompl_skips_d_with_a_clear_line(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setattr(planner, "ompl_available", lambda: False)
    status, out, _ = run_main(
        capsys,
        "--coefficients",
        "paper",
        "--n",
        "2",
        "--repeats",
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
        (["--pso-swarm-size", "1"], "--pso-swarm-size"),
        (["--n", "three"], "--n"),
        (["--run-build", "2"], "--run-build"),
        (["--json", "/proc/x"], "--json"),
        (["--json", "/etc/passwd/x.json"], "--json"),
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
    from pipeline.offline.coefficients import load_coefficients

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
