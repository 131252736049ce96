"""``python -m verify.view``: it draws the build's coefficients by default and says which, refuses an
arm the coefficients were not fitted for, and checks its output path before any work; bad input
is one line and exit status 2."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from pipeline.offline.coefficients import paper_data_path
from verify import view


def run_view(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    status = view.main(list(argv))
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def test_default_coefficients_are_the_builds_file_and_are_named(capsys, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    status, _, err = run_view(capsys, "--L", "0.27", "--W", "0.09", "--html", "view.html")
    assert status == 2 and "results/coefficients.json" in err and "Traceback" not in err
    (tmp_path / "results").mkdir()
    shutil.copy(paper_data_path("paper_eq9_coefficients.json"), tmp_path / "results" / "coefficients.json")
    status, out, err = run_view(capsys, "--L", "0.27", "--W", "0.09", "--html", "view.html")
    assert status == 0, err
    assert "coefficients: results/coefficients.json (paper, sha256 " in out
    assert "min clearance" in out and "sampled times" in out and (tmp_path / "view.html").is_file()


@pytest.mark.parametrize("flag", ["--html", "--screenshot"])
def test_output_path_is_checked_before_any_work(capsys, monkeypatch, flag: str) -> None:
    monkeypatch.setattr(view, "_run", lambda *a, **k: pytest.fail("the view was built despite a bad output path"))
    status, out, err = run_view(capsys, "--coefficients", "paper", "--L", "0.27", "--W", "0.09", flag, "/proc/x")
    assert status == 2 and out == "" and flag in err and len(err.strip().splitlines()) == 1
    assert "Traceback" not in err and ".tmp" not in err


@pytest.mark.parametrize("mode", [["--coefficients", "paper", "--L", "0.27", "--W", "0.09"], ["--paper-test1"]])
def test_another_arm_is_refused_naming_both(capsys, tmp_path: Path, double_pendulum_urdf, mode) -> None:
    status, _, err = run_view(capsys, *mode, "--urdf", str(double_pendulum_urdf), "--html", str(tmp_path / "v.html"))
    assert status == 2 and "0.3, 0.35" in err and "0.1, 0.2" in err and "--urdf" in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "v.html").exists()


@pytest.mark.parametrize(
    ("argv", "option"),
    [
        (["--L", "0.27"], "--W"),
        (["--L", "-1", "--W", "0.1"], "--L"),
        (["--paper-test1", "--L", "0.3"], "--L"),
        (["--L", "0.27", "--W", "0.09", "--fps", "0"], "--fps"),
        (["--L", "0.27", "--W", "0.09", "--samples", "3"], "--samples"),
        (["--L", "0.27", "--W", "0.09", "--hold", "nan"], "--hold"),
        (["--L", "0.27", "--W", "0.09", "--size", "10x10"], "--size"),
    ],
)
def test_bad_input_is_one_line_naming_the_option(capsys, argv: list[str], option: str) -> None:
    status, out, err = run_view(capsys, "--coefficients", "paper", *argv)
    assert status == 2 and out == "" and "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and option in lines[0] and lines[0].startswith("python -m verify.view: error:"), err


def test_help_has_units_and_no_empty_defaults(capsys) -> None:
    status, out, _ = run_view(capsys, "--help")
    text = " ".join(out.split())
    assert status == 0 and "default: results/coefficients.json" in text and "[m]" in text
    assert "(default: None)" not in text and "(default: False)" not in text


def test_joint_plot_writes_a_png_of_the_certified_answer(tmp_path, capsys) -> None:
    from verify import view

    out = tmp_path / "joints.png"
    status = view.main(
        [
            "--L",
            "0.27",
            "--W",
            "0.09",
            "--coefficients",
            "paper",
            "--joint-plot",
            str(out),
            "--acceleration-limit",
            "2",
            "2",
        ]
    )
    assert status == 0, capsys.readouterr().err
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "near-optimal timing, T' = " in capsys.readouterr().out
    slow = tmp_path / "slow.urdf"
    from pipeline.model.arm import DEFAULT_URDF

    slow.write_text(DEFAULT_URDF.read_text().replace('velocity="3.0"', 'velocity="0.3"'))
    refused = tmp_path / "refused.png"
    argv = ["--L", "0.27", "--W", "0.09", "--coefficients", "paper", "--urdf", str(slow), "--timing", "paper"]
    assert view.main([*argv, "--joint-plot", str(refused)]) == 1  # the paper timing breaks 0.3 rad/s
    assert "certification refused" in capsys.readouterr().err and not refused.exists()
