"""A battery of bad inputs to ``python -m pipeline.build``, ``python -m pipeline.regress`` and the
public API: each is refused with a non-zero exit (or the project's error), exactly one line
naming the offending option or value, no traceback, and nothing left on disk; the build's
cases are refused before any work (the DOE is replaced by a function that fails the test)."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import pipeline
from pipeline.build import BuildConfig, run_build, scene_from_options
from pipeline.build import doe_fit as build_library
from pipeline.cli import EXIT_PIPE_CLOSED
from pipeline.commands import build, regress
from pipeline.exceptions import (
    ExecutionRefusedError,
    InfeasibleSceneError,
    NoCertifiedTrajectoryError,
    OutOfFittedRangeError,
    PipelineError,
    UnreachableObstacleError,
    format_number,
)
from pipeline.model.arm import DEFAULT_URDF
from pipeline.offline.doe import Design, load_doe

TINY = ["--swarm-size", "8", "--iterations", "5", "--restarts", "1", "--quiet", "--near-optimal-cells", "2"]


def files_under(folder: Path) -> set[Path]:
    return {p for p in folder.rglob("*")}


@pytest.fixture
def place(tmp_path: Path) -> dict[str, Path]:
    """Files the bad inputs point at: a regular file, a misspelt scene, a broken JSON, a text 'URDF',
    the shipped arm without its joint limits and with a continuous shoulder."""
    (tmp_path / "a_file").write_text("not a folder", encoding="utf-8")
    (tmp_path / "misspelt.toml").write_text("top_y = 0.54\n", encoding="utf-8")
    (tmp_path / "broken.json").write_text("{", encoding="utf-8")
    (tmp_path / "text.urdf").write_text("not xml", encoding="utf-8")
    shipped = DEFAULT_URDF.read_text(encoding="utf-8")
    limit = '<limit lower="-3.14159" upper="3.14159" effort="10" velocity="3.0"/>'
    assert shipped.count(limit) == 2
    (tmp_path / "no_limits.urdf").write_text(shipped.replace(limit, ""), encoding="utf-8")
    continuous = shipped.replace('name="joint1" type="revolute"', 'name="shoulder" type="continuous"')
    assert continuous != shipped
    (tmp_path / "continuous.urdf").write_text(continuous, encoding="utf-8")
    (tmp_path / "folder").mkdir()
    return {"tmp": tmp_path}


def substitute(arguments: list[str], tmp: Path) -> list[str]:
    return [a.replace("TMP", str(tmp)) for a in arguments]


BUILD_CASES = [
    (["--seed", "-1"], "--seed"),
    (["--seed", "one"], "--seed"),
    (["--jobs", "-1"], "--jobs"),
    (["--jobs", "two"], "--jobs"),
    (["--levels", "2"], "--levels"),
    (["--L-range", "0.3", "0.2"], "--L-range"),
    (["--W-range", "nan", "0.1"], "--W-range"),
    (["--family", "spline"], "--family"),
    (["--swarm-size", "1"], "--swarm-size"),
    (["--iterations", "0"], "--iterations"),
    (["--restarts", "0"], "--restarts"),
    (["--n-points", "3"], "--n-points"),
    (["--penalty-weight", "nan"], "--penalty-weight"),
    (["--speed", "0"], "--speed"),
    (["--margin", "-0.01"], "--margin"),
    (["--corner-radius", "0.5"], "--corner-radius"),
    (["--top-y", "inf"], "--top-y"),
    (["--top-y", "0.9"], "P1"),
    (["--top-y", "0.54"], "pose at P5 collides"),
    (["--endpoint-tolerance", "0"], "--endpoint-tolerance"),
    (["--max-doe-endpoint-error", "0"], "--max-doe-endpoint-error"),
    (["--scene", "TMP/misspelt.toml"], "'top_y' (did you mean 'top_y_m'?)"),
    (["--scene", "TMP/none.toml"], "none.toml"),
    (["--scene", "TMP/broken.json"], "broken.json"),
    (["--urdf", "TMP/none.urdf"], "none.urdf"),
    (["--urdf", "TMP/text.urdf"], "text.urdf"),
    (["--out", "TMP/a_file"], "--out"),
    (["--out", "TMP/a_file/under"], "--out"),
    (["--out", "/proc/twolink-out"], "--out"),
    (["--unknown-option"], "--unknown-option"),
]


@pytest.mark.parametrize(("arguments", "needle"), BUILD_CASES, ids=[" ".join(a) for a, _ in BUILD_CASES])
def test_build_refuses_before_any_work(
    arguments: list[str], needle: str, place: dict, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    tmp = place["tmp"]
    monkeypatch.setattr(build_library, "run_doe", lambda *a, **k: pytest.fail("the DOE ran despite bad input"))
    before = files_under(tmp)
    arguments = substitute(arguments, tmp)
    argv = [*TINY, "--out", str(tmp / "out"), *arguments]  # a later --out wins
    status = build.main(argv)
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert status == 2, captured.err
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("python -m pipeline.build: error: ") and needle in lines[0], lines[0]
    assert "Traceback" not in captured.err + captured.out and ".tmp" not in lines[0]
    assert files_under(tmp) == before  # no --out folder, no temporary file


REGRESS_CASES = [
    (["TMP/none.json", "-o", "TMP/c.json"], "none.json"),
    (["TMP/broken.json", "-o", "TMP/c.json"], "broken.json"),
    (["TMP/a_file", "-o", "TMP/c.json"], "a_file"),
    (["paper", "-o", "/proc/twolink-c.json"], "-o"),
    (["paper", "-o", "TMP/folder"], "-o"),
    (["paper", "-o", "TMP/a_file/c.json"], "-o"),
    (["paper", "-o", "TMP/c.json", "--endpoint-tolerance", "-1"], "--endpoint-tolerance"),
    (["paper"], "-o"),
]


@pytest.mark.parametrize(("arguments", "needle"), REGRESS_CASES, ids=[" ".join(a) for a, _ in REGRESS_CASES])
def test_regress_refuses(arguments: list[str], needle: str, place: dict, capsys: pytest.CaptureFixture) -> None:
    tmp = place["tmp"]
    before = files_under(tmp)
    status = regress.main([*substitute(arguments, tmp), "--quiet"])
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert status == 2 and len(lines) == 1, captured.err
    assert lines[0].startswith("python -m pipeline.regress: error: ") and needle in lines[0], lines[0]
    assert "Traceback" not in captured.err + captured.out
    assert files_under(tmp) == before


def _api_cases(tmp: Path) -> list[tuple[str, object, str]]:
    return [
        ("load_coefficients missing", lambda: pipeline.load_coefficients(tmp / "none.json"), "none.json"),
        ("load_coefficients broken", lambda: pipeline.load_coefficients(tmp / "broken.json"), "broken.json"),
        ("load_planar_arm missing", lambda: pipeline.load_planar_arm(tmp / "none.urdf"), "none.urdf"),
        ("load_planar_arm text", lambda: pipeline.load_planar_arm(tmp / "text.urdf"), "text.urdf"),
        ("load_doe broken", lambda: load_doe(tmp / "broken.json"), "broken.json"),
        ("Design levels", lambda: Design(levels=2), "levels"),
        ("BuildConfig seed", lambda: BuildConfig.from_settings(seed=-1), "--seed"),
        ("BuildConfig family", lambda: BuildConfig.from_settings(family="spline"), "spline"),
        ("scene misspelt", lambda: scene_from_options(tmp / "misspelt.toml"), "top_y"),
        ("scene option", lambda: scene_from_options(speed_m_s=-1.0), "--speed"),
        ("run_build out", lambda: run_build(BuildConfig.from_settings(out_folder=tmp / "a_file")), "--out"),
        ("BuildConfig jobs", lambda: BuildConfig.from_settings(jobs=-1), "--jobs"),
        ("load_coefficients 42", lambda: pipeline.load_coefficients(42), "coefficients"),
        ("load_coefficients region_map", lambda: pipeline.load_coefficients("paper", region_map=3), "region_map"),
        ("generate None", lambda: pipeline.generate(None, 0.27, 0.09), "load_coefficients"),
        ("generate path", lambda: pipeline.generate(str(tmp / "c.json"), 0.27, 0.09), "load_coefficients"),
        (
            "generate_batch 2-D",
            lambda: pipeline.generate_batch(_paper(), [[0.2, 0.3]], [[0.1, 0.1]]),
            "one-dimensional",
        ),
        ("generate_certified arm", lambda: pipeline.generate_certified(_paper(), 0.27, 0.09, arm="a"), "PlanarArm"),
        ("generate_certified config", lambda: pipeline.generate_certified(_paper(), 0.27, 0.09, config=1), "config"),
        ("certify_batch arrays", lambda: pipeline.certify_batch(_paper(), [0.27], [0.09]), "generate_batch"),
        ("load_planar_arm continuous", lambda: pipeline.load_planar_arm(tmp / "continuous.urdf"), "'shoulder'"),
        ("answer.q text", lambda: pipeline.generate(_paper(), 0.27, 0.09).q("1.2"), "t_s = '1.2'"),
        ("answer.dq None", lambda: pipeline.generate(_paper(), 0.27, 0.09).dq(None), "expected a time [s]"),
        ("answer.ddq complex", lambda: pipeline.generate(_paper(), 0.27, 0.09).ddq(0.5j), "t_s = 0.5j"),
    ]


def _paper():
    return pipeline.load_coefficients("paper")


def test_jobs_0_means_every_cpu() -> None:
    assert BuildConfig.from_settings(jobs=0).execution.workers == (os.cpu_count() or 1)


@pytest.mark.parametrize("index", range(len(_api_cases(Path(".")))))
def test_public_api_raises_the_projects_error(index: int, place: dict) -> None:
    tmp = place["tmp"]
    name, call, needle = _api_cases(tmp)[index]
    before = files_under(tmp)
    with pytest.raises(PipelineError) as info:
        call()
    message = str(info.value)
    assert needle in message and "\n" not in message, (name, message)
    assert files_under(tmp) == before


@pytest.mark.parametrize(
    ("module", "arguments", "needle"),
    [
        (
            "pipeline.generate",
            ["--L", "0.27", "--W", "0.09", "--coefficients", "paper", "--rate", "1e9", "--out", "t.csv"],
            "--rate",
        ),
        (
            "pipeline.generate",
            ["--L", "0.27", "--W", "0.09", "--coefficients", "paper", "--out", "nodir/x.json"],
            "does not exist",
        ),
        (
            "pipeline.generate",
            ["--L", "0.27", "--W", "0.09", "--coefficients", "paper", "--out", "x.json/"],
            "separator",
        ),
        ("pipeline.generate", ["--L", "0.27", "--W", "0.09", "--coefficients", "TMP/broken.json"], "broken.json"),
        ("pipeline.generate", ["--L", "0.27", "--W", "0.09", "--acceleration-limit", "0", "2"], "must be > 0"),
        (
            "pipeline.generate",
            ["--L", "0.27", "--W", "0.09", "--coefficients", "paper", "--urdf", "TMP/no_limits.urdf"],
            "cannot be parsed as URDF: Joint [joint1] is of type REVOLUTE but it does not specify limits",
        ),
        (
            "pipeline.generate",
            ["--L", "0.27", "--W", "0.09", "--coefficients", "paper", "--urdf", "TMP/text.urdf"],
            "text.urdf: cannot be parsed as URDF: not well-formed XML (XML_ERROR_PARSING_TEXT at line 1)",
        ),
        (
            "pipeline.generate",
            ["--L", "0.27", "--W", "0.09", "--coefficients", "paper", "--urdf", "TMP/continuous.urdf"],
            "continuous.urdf: joint 'shoulder' is continuous (nq = 2 per joint in Pinocchio); the arm needs 2 revolute",
        ),
        ("pipeline.build", ["--urdf", "TMP/no_limits.urdf"], "it does not specify limits"),
        ("pipeline.build", ["--urdf", "TMP/text.urdf"], "not well-formed XML"),
        ("pipeline.build", ["--acceleration-limit", "nan", "1"], "--acceleration-limit"),
        ("pipeline.build", ["--seed", "-1"], "--seed"),
        ("pipeline.build", ["--out", "/proc/twolink-out"], "--out"),
        ("pipeline.build", ["--scene", "TMP/misspelt.toml"], "top_y"),
        ("pipeline.regress", ["paper", "-o", "/proc/twolink-c.json"], "-o"),
    ],
)
def test_as_a_process_no_traceback(module: str, arguments: list[str], needle: str, place: dict) -> None:
    tmp = place["tmp"]
    before = files_under(tmp)
    # Run in the scratch folder (so a default --out would land there) with this checkout's pipeline.
    root = str(Path(pipeline.__file__).resolve().parents[1])
    environment = {**os.environ, "PYTHONPATH": root + os.pathsep + os.environ.get("PYTHONPATH", "")}
    done = subprocess.run(
        [sys.executable, "-m", module, *substitute(arguments, tmp)],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
        cwd=tmp,
        env=environment,
    )
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1, done.stderr
    assert lines[0].startswith(f"python -m {module}: error: ") and needle in lines[0]
    assert "Traceback" not in done.stderr and files_under(tmp) == before
    assert not (tmp / "results").exists()


def test_every_command_that_names_its_coefficients_flags_an_unconverged_file() -> None:
    from pipeline.cli import describe_coefficients

    coefficients = pipeline.load_coefficients("paper")
    assert "NOT CONVERGED" not in describe_coefficients(coefficients)
    flagged = describe_coefficients(coefficients.marked_unconverged(["Test 1 missed P5 by 168 mm"]))
    assert "NOT CONVERGED" in flagged and "Test 1 missed P5 by 168 mm" in flagged


@pytest.mark.parametrize("unbuffered", ["1", ""])
def test_a_reader_that_goes_away_stops_the_output_without_a_traceback(unbuffered: str, tmp_path: Path) -> None:
    """``python -m pipeline.generate ... | head -1``: the reader closes the pipe before the command
    writes (its stdout unbuffered or block-buffered); the command stops with the shell's status of
    a closed pipe and writes nothing to stderr."""
    root = str(Path(pipeline.__file__).resolve().parents[1])
    environment = {**os.environ, "PYTHONPATH": root + os.pathsep + os.environ.get("PYTHONPATH", "")}
    environment.pop("PYTHONUNBUFFERED", None)
    if unbuffered:
        environment["PYTHONUNBUFFERED"] = unbuffered
    command = [sys.executable, "-m", "pipeline.generate", "--coefficients", "paper", "--L", "0.27", "--W", "0.09"]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=tmp_path, env=environment)
    process.stdout.close()  # before the command has imported anything, so before its first line
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == EXIT_PIPE_CLOSED == 141, stderr
    assert stderr == b"", stderr


# --------------------------------------------------------------------------------------------
# Huge and tiny values: every number of a message reads in general format (1e+300), never as a
# 300-digit fixed-point number nor rounded to 0.

LONG_NUMBER = re.compile(r"\d{16,}")


def _run(module: str, arguments: list[str], cwd: Path) -> subprocess.CompletedProcess:
    root = str(Path(pipeline.__file__).resolve().parents[1])
    environment = {**os.environ, "PYTHONPATH": root + os.pathsep + os.environ.get("PYTHONPATH", "")}
    return subprocess.run(
        [sys.executable, "-m", module, *arguments],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        cwd=cwd,
        env=environment,
    )


EXTREME_CASES = [
    (["--L", "1e300", "--W", "0.09"], 2, "L = 1e+300 m, W = 0.09 m: constraint point P1 is at 5e+299 m from the base"),
    (["--L", "0.27", "--W", "1e300"], 2, "W = 1e+300 m: invalid obstacle size"),
    (["--L", "1e-300", "--W", "0.09"], 2, "L = 1e-300 m, W = 0.09 m: invalid obstacle size"),
    (["--L", "0.27", "--W", "1e-300"], 2, "W = 1e-300 m: invalid obstacle size"),
    (["--L", "1e300", "--W", "0.09", "--certify", "--out-of-range", "error"], 2, "P1 is at 5e+299 m"),
    (["--L", "0.27", "--W", "0.09", "--certify", "--margin", "1e300"], 1, "< margin 1e+303 mm"),
]


@pytest.mark.parametrize(
    ("arguments", "status", "needle"), EXTREME_CASES, ids=[" ".join(a) for a, _, _ in EXTREME_CASES]
)
def test_generate_prints_extreme_values_readably(
    arguments: list[str], status: int, needle: str, tmp_path: Path
) -> None:
    done = _run("pipeline.generate", ["--coefficients", "paper", *arguments], tmp_path)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == status and len(lines) == 1, done.stderr
    assert lines[0].startswith("python -m pipeline.generate: ") and needle in lines[0], lines[0]
    assert LONG_NUMBER.search(lines[0]) is None and len(lines[0]) < 400, lines[0]


@pytest.mark.parametrize("x", ["1e300", "-1e300"])
def test_generate_prints_an_extreme_x_readably(x: str, over_x, tmp_path: Path) -> None:
    """--x for coefficients that vary x (the paper's, lifted to (L, W, x) as the tests' conftest does)."""
    coefficients = tmp_path / "coefficients_x.json"
    coefficients.write_text(json.dumps(over_x(pipeline.load_coefficients("paper")).to_json()), encoding="utf-8")
    done = _run(
        "pipeline.generate", ["--coefficients", str(coefficients), "--L", "0.27", "--W", "0.09", f"--x={x}"], tmp_path
    )
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1, done.stderr
    shown = x.replace("e", "e+")
    assert f"x = {shown} m: constraint point P1 is at 1e+300 m from the base" in lines[0], lines[0]
    assert LONG_NUMBER.search(lines[0]) is None, lines[0]


def _errors_at(value: float) -> list[PipelineError]:
    """Every error whose message formats lengths, positions or clearances, built with ``value``."""
    return [
        UnreachableObstacleError("P1", value, (0.05, value), (value, 0.09), {"x": value}),
        OutOfFittedRangeError("x", value, (-value, value)),
        NoCertifiedTrajectoryError(value, value, value, value, "a reason", {"x": value}),
        InfeasibleSceneError(value, value, "P5", -value, 4, 441),
        ExecutionRefusedError(value, value, "paper", ("a reason",), {"x": value}),
    ]


@pytest.mark.parametrize(("value", "shown"), [(1e300, "e+30"), (-1e300, "e+30"), (1e-300, "e-30"), (2.5e-9, "e-0")])
def test_error_messages_print_extreme_values_in_general_format(value: float, shown: str) -> None:
    for error in _errors_at(value):
        message = str(error)
        assert LONG_NUMBER.search(message) is None and "\n" not in message, message
        assert shown in message and " 0.0000 m" not in message, message


def test_format_number_is_fixed_point_for_ordinary_values_and_general_beyond() -> None:
    """Ordinary values read as before (the fixed-point messages other tests and users rely on)."""
    assert format_number(0.05) == "0.0500" and format_number(-123.456, 2) == "-123.46" and format_number(0) == "0.0000"
    assert format_number(1e-4) == "0.0001" and format_number(999999.0, 1) == "999999.0"
    assert format_number(1e300) == "1e+300" and format_number(-5e299) == "-5e+299"
    assert format_number(1e-300) == "1e-300" and format_number(2.5e-7, 3) == "2.5e-07"
    assert format_number(1234567.0) == "1.235e+06"
    assert format_number(10**400) == "1.0000e+400"  # an integer no float holds
    assert format_number(float("nan")) == "nan" and format_number(float("-inf")) == "-inf"
    assert format_number(np.float64(0.65)) == "0.6500" and format_number("abc") == "'abc'"
