"""``python -m pipeline.scene``: the window of d for an arm, the recommended value and the build
command; one line and exit 2 on bad input or when no d fits."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from pipeline.commands import scene

ROOT = Path(__file__).resolve().parents[2]


def run(capsys: pytest.CaptureFixture, *argv: str) -> tuple[int, str, str]:
    status = scene.main(list(argv))
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def one_line_error(status: int, err: str) -> str:
    assert status == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("python -m pipeline.scene: error: "), err
    assert "Traceback" not in err
    return lines[0]


def test_a_040_030_arm_gets_a_window_and_the_build_command(tmp_path: Path, capsys, urdf_with_links) -> None:
    urdf = urdf_with_links(tmp_path, 0.40, 0.30)
    status, out, _ = run(capsys, "--urdf", str(urdf))
    assert status == 0
    assert "window of d (the obstacle's far edge y) over L in [0.200, 0.300] m, W in [0.080, 0.120] m" in out
    assert "above 0.6458 m: P1 at 0.7000 m from the base is outside the arm's reach" in out
    assert "the arm's pose at P5" in out and "recommended d = 0.635 m" in out
    assert "the build's pre-checks pass at d = 0.635 m" in out
    assert f"build: python -m pipeline.build --urdf {urdf} --top-y 0.635\n" in out


def test_a_narrow_window_shrinks_the_length_range_and_says_so(tmp_path: Path, capsys, urdf_with_links) -> None:
    urdf = urdf_with_links(tmp_path, 0.30, 0.28)
    status, out, _ = run(capsys, "--urdf", str(urdf))
    assert status == 0
    assert "is only 5.1 mm wide (< 10 mm): the range is shrunk" in out.splitlines()[1]
    assert "--L-range 0.2 0.28" in out.splitlines()[-1] and "caution" not in out
    status, out, _ = run(capsys, "--urdf", str(urdf), "--no-shrink")
    assert status == 0 and "caution: the window is only 5.1 mm wide" in out
    assert "--L-range" not in out.splitlines()[-1]


def test_a_025_020_arm_is_refused_in_one_line_naming_the_end_pose(tmp_path: Path, capsys, urdf_with_links) -> None:
    urdf = urdf_with_links(tmp_path, 0.25, 0.20)
    status, out, err = run(capsys, "--urdf", str(urdf))
    line = one_line_error(status, err)
    assert out == "" and "nor a shrunk L or W range" in line and "the arm's pose at P5 collides" in line


def test_a_010_010_arm_is_refused_in_one_line_naming_p1(tmp_path: Path, capsys, urdf_with_links) -> None:
    urdf = urdf_with_links(tmp_path, 0.10, 0.10)
    started = time.perf_counter()
    status, out, err = run(capsys, "--urdf", str(urdf))
    assert time.perf_counter() - started < 5.0
    assert out == ""
    assert "no d brings P1 of every obstacle into the arm's reach" in one_line_error(status, err)


def test_the_build_command_carries_the_ranges_and_scene_options_given(tmp_path: Path, capsys, urdf_with_links) -> None:
    urdf = urdf_with_links(tmp_path, 0.40, 0.30)
    status, out, _ = run(capsys, "--urdf", str(urdf), "--W-range", "0.08", "0.10", "--margin", "0.008")
    assert status == 0
    build = out.splitlines()[-1]
    assert "--W-range 0.08 0.1" in build and "--margin 0.008" in build and "--L-range" not in build
    assert "(required 8.00 mm)" in out


@pytest.mark.parametrize(
    "argv",
    [
        ["--urdf", "no_such_arm.urdf"],
        ["--L-range", "0.30", "0.20"],
        ["--W-range", "-0.1", "0.1"],
        ["--L-range", "abc", "0.3"],
        ["--vary", "d", "0.5", "0.6"],
        ["--vary", "x", "0.03"],
        ["--end-pose-clearance", "-0.01"],
        ["--margin", "-1"],
    ],
)
def test_bad_input_is_one_line_and_exit_2(capsys, argv: list[str]) -> None:
    status, out, err = run(capsys, *argv)
    one_line_error(status, err)
    assert out == ""


def test_help_names_units_and_defaults(capsys) -> None:
    status, out, _ = run(capsys, "--help")
    assert status == 0
    for text in ("--urdf", "L range [m] (default: [0.2, 0.3])", "--end-pose-clearance", "[m]", "--no-shrink"):
        assert text in " ".join(out.split()), text


def test_the_module_runs_as_a_command() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "pipeline.scene", "--help"], capture_output=True, text=True, cwd=ROOT, timeout=120
    )
    assert done.returncode == 0 and "usage: python -m pipeline.scene" in done.stdout


def test_the_options_shared_with_the_build_are_the_builds_declaration() -> None:
    """--L-range, --W-range and the scene's options read as the build's (one declaration): the
    same help, default, type and destination; changing one in the declaration changes both."""
    from pipeline.commands import build, scene

    def actions(parser):
        return {flag: action for action in parser._actions for flag in action.option_strings}

    ours, builds = actions(scene.parser()), actions(build.parser())
    for flag in ("--L-range", "--W-range", "--scene", "--start-y", "--margin", "--corner-radius"):
        a, b = ours[flag], builds[flag]
        assert (a.help, a.default, a.dest, a.nargs, a.metavar) == (b.help, b.default, b.dest, b.nargs, b.metavar)
        assert (a.type is None) == (b.type is None)
    assert ours["--urdf"].default == builds["--urdf"].default
