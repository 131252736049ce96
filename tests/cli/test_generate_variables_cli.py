"""``python -m pipeline.generate --x`` (and ``--d``) for coefficients over more scene variables than
(L, W): the value reaches the generator (the same answer as ``generate(..., x=...)``, printed with
the obstacle and recorded in the NPZ beside L and W); a variable the coefficients vary without its
flag, or a flag for one they do not vary, is one line, exit 2, before any work and with no file;
``--help`` gives the units and the default."""

from __future__ import annotations

import importlib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pipeline import load_coefficients
from pipeline.offline.coefficients import Coefficients, paper_data_path, read_coefficients, save_coefficients
from pipeline.offline.variables import Variables
from pipeline.online.generator import generate

generate_module = importlib.import_module("pipeline.commands.generate")

LWX = Variables(("L", "W", "x"))


def run(capsys, *argv: str) -> tuple[int, str, str]:
    status = generate_module.main(list(argv))
    captured = capsys.readouterr()
    return status, captured.out, captured.err


@pytest.fixture(scope="module")
def coefficients_x(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The paper's Eq. 9 lifted to (L, W, x) with small x terms, as a file."""
    paper = read_coefficients(paper_data_path("paper_eq9_coefficients.json"))
    rng = np.random.default_rng(3)
    parameters = {}
    for name, b in paper.parameters.items():
        lifted = np.zeros(LWX.basis_size)
        lifted[[0, 1, 2, 4, 5, 7]] = b  # the (L, W) terms' places in the (L, W, x) basis
        lifted[[3, 6, 8, 9]] = rng.normal(0.0, 0.05, 4)
        parameters[name] = tuple(float(v) for v in lifted)
    moved: Coefficients = replace(
        paper,
        parameters=parameters,
        fitted_range_m={**paper.fitted_range_m, "x": (-0.03, 0.03)},
        variables=LWX,
        source="",
        source_sha256="",
    )
    path = tmp_path_factory.mktemp("coefficients-x") / "coefficients.json"
    save_coefficients(moved, path)
    return path


def test_x_reaches_the_generator_and_is_printed_and_recorded(coefficients_x: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "trajectory.npz"
    argv = ["--coefficients", str(coefficients_x), "--L", "0.25", "--W", "0.1", "--x", "0.02"]
    status, stdout, err = run(capsys, *argv, "--timing", "paper", "--rate", "20", "--out", str(out))
    assert status == 0, err
    answer = generate(load_coefficients(coefficients_x), 0.25, 0.1, x=0.02)
    assert answer.centre_x_m == 0.02
    assert "obstacle L = 0.25 m, W = 0.1 m, x = 0.02 m" in stdout
    for name, value in answer.trajectory.as_dict().items():
        assert f"{name:<7s}= {value: .9f}" in stdout
    data = np.load(out)
    assert data["variable_names"].tolist() == ["L", "W", "x"]
    assert data["variables_m"].tolist() == [0.25, 0.1, 0.02]
    assert tuple(data["parameters"]) == answer.trajectory.parameters
    assert_allclose(data["q_rad"], answer.q(data["t_s"]), rtol=0, atol=0)
    # Another x, another answer.
    assert generate(load_coefficients(coefficients_x), 0.25, 0.1, x=-0.02).trajectory != answer.trajectory


def test_certify_passes_x_to_certify_or_repair(coefficients_x: Path, monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    calls: list[dict] = []
    real = generate_module.generate_certified

    def spy(*args, **kwargs):
        calls.append(kwargs)
        return real(*args, **kwargs)

    monkeypatch.setattr(generate_module, "generate_certified", spy)
    status, _, err = run(
        capsys, "--coefficients", str(coefficients_x), "--L", "0.25", "--W", "0.1", "--x", "-0.01", "--certify"
    )
    assert status in (0, 1), err  # certified, or refused with its reason
    assert "Traceback" not in err and len(calls) == 1 and calls[0]["x"] == -0.01 and "d" not in calls[0]


def test_an_lw_file_records_l_and_w_only(tmp_path: Path, capsys) -> None:
    out = tmp_path / "trajectory.npz"
    status, stdout, _ = run(capsys, "--coefficients", "paper", "--L", "0.27", "--W", "0.09", "--out", str(out))
    assert status == 0
    assert "obstacle L = 0.27 m, W = 0.09 m\n" in stdout or "obstacle L = 0.27 m, W = 0.09 m (" in stdout
    data = np.load(out)
    assert data["variable_names"].tolist() == ["L", "W"] and data["variables_m"].tolist() == [0.27, 0.09]


@pytest.mark.parametrize(
    ("coefficients", "extra", "named", "says"),
    [
        ("X", [], "--x", "--x is required"),
        ("X", ["--x", "nan"], "--x", "finite"),
        ("X", ["--x", "0.01", "--d", "0.56"], "--d", "vary L, W, x only"),
        ("paper", ["--x", "0.01"], "--x", "vary L, W only"),
        ("paper", ["--d", "0.56"], "--d", "vary L, W only"),
    ],
)
def test_a_missing_or_unexpected_variable_is_one_line_exit_2_before_any_work(
    coefficients_x: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys,
    coefficients: str,
    extra: list[str],
    named: str,
    says: str,
) -> None:
    monkeypatch.setattr(generate_module, "generate", lambda *a, **k: pytest.fail("generated despite bad input"))
    monkeypatch.setattr(generate_module, "arm_for_cli", lambda *a, **k: pytest.fail("loaded the arm despite bad input"))
    source = str(coefficients_x) if coefficients == "X" else coefficients
    out = tmp_path / "out.csv"
    argv = ["--coefficients", source, "--L", "0.25", "--W", "0.1", *extra, "--out", str(out)]
    status, stdout, err = run(capsys, *argv)
    assert status == 2 and stdout == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("python -m pipeline.generate: error:") and named in lines[0] and says in lines[0]
    assert list(tmp_path.iterdir()) == []


def test_help_gives_units_and_defaults(capsys) -> None:
    status, stdout, _ = run(capsys, "--help")
    text = " ".join(stdout.split())
    assert status == 0
    for flag, meaning in (("--x M", "centre x [m]"), ("--d M", "far edge y [m]")):
        assert flag in text and meaning in text
    assert text.count("(default: none; the coefficients' scene holds it fixed)") == 2
    assert "(default: None)" not in text
