"""The build over more scene variables than (L, W) (``--vary``, ``--design``): bad inputs refused in one
line before any work, a tiny (L, W, x) build whose coefficients name x and generate with it, and no
trace of the new keys in an (L, W) build's files."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import pytest

from pipeline import BuildConfig, generate, load_coefficients
from pipeline.build import doe_fit, range_stage
from pipeline.certify.certifiable_regression import REFIT_POINTS_PER_ROUND
from pipeline.certify.map_for_coefficients import default_config
from pipeline.commands import build, regress
from pipeline.exceptions import InvalidParameterError, PipelineError
from pipeline.model.scene import Scene
from pipeline.offline.designs import BoxBehnken, CentralComposite, FullFactorial

#: A PSO small enough for 27 runs in seconds (its optima miss the thresholds: --allow-unconverged).
TINY = ["--swarm-size", "8", "--iterations", "5", "--restarts", "1", "--no-polish", "--quiet", "--no-progress"]
TINY += ["--near-optimal-cells", "2"]

BAD = [
    (["--vary", "xc", "-0.03", "0.03"], "did you mean 'x'?"),
    (["--vary", "centre_x_m", "-0.03", "0.03"], "did you mean 'x'?"),
    (["--vary", "L", "0.2", "0.3"], "--L-range"),
    (["--vary", "x", "-0.03", "0.03", "--vary", "x", "-0.01", "0.01"], "each name once"),
    (["--vary", "x", "0.03", "-0.03"], "min < max"),
    (["--vary", "x", "0.03", "0.03"], "min < max"),
    (["--vary", "x", "zero", "0.03"], "a number"),
    (["--vary", "x", "0.03"], "NAME MIN MAX"),
    (["--vary", "d", "--L-range", "0.2", "0.5"], "no d (the obstacle's far edge y, --top-y) fits"),  # no window
    (["--vary", "x", "0.05", "0.07"], "a range the arm reaches"),
    (["--vary", "x", "-0.1", "0.0"], "P5"),
    # A corner of the box that is no Box-Behnken run: the grid over the box refuses it.
    (["--vary", "x", "-0.05", "0.05", "--vary", "d", "0.55", "0.57", "--design", "box-behnken"], "(L, W) range at"),
    (["--design", "box-behnken"], "3 or more factors"),
    (["--vary", "x", "--design", "central-composite", "--levels", "4"], "--levels"),
]


@pytest.mark.parametrize(("arguments", "needle"), BAD, ids=[" ".join(a) for a, _ in BAD])
def test_bad_variables_are_refused_in_one_line_before_any_work(
    arguments: list[str], needle: str, tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(doe_fit, "run_doe", lambda *a, **k: pytest.fail("the DOE ran despite bad input"))
    status = build.main([*TINY, "--out", str(tmp_path / "out"), *arguments])
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert status == 2, captured.err
    assert len(lines) == 1 and lines[0].startswith("python -m pipeline.build: error: "), captured.err
    assert needle in lines[0], lines[0]
    assert "Traceback" not in captured.err + captured.out
    assert list(tmp_path.iterdir()) == []


def test_build_config_takes_factors_and_design_classes() -> None:
    config = BuildConfig.from_settings(vary=(("x", -0.03, 0.03),), design_kind="box-behnken")
    assert config.design.kind is BoxBehnken and config.variables.names == ("L", "W", "x")
    assert len(config.design.scaled_design().points()) == 13
    assert (
        len(
            BuildConfig.from_settings(vary=config.design.vary, design_kind=CentralComposite)
            .design.scaled_design()
            .points()
        )
        == 15
    )
    assert len(BuildConfig.from_settings(vary=config.design.vary).design.scaled_design().points()) == 27
    assert config.certifiable_refit  # the range certificate covers x
    assert BuildConfig.from_settings(vary=(("d", 0.55, 0.57),)).certifiable_refit  # and d, with y1 = d
    assert not BuildConfig.from_settings(vary=(("d", 0.55, 0.57),), scene=Scene(start_y_m=0.5)).certifiable_refit
    with pytest.raises(InvalidParameterError, match="--design"):
        BuildConfig.from_settings(design_kind="latin-square")
    with pytest.raises(PipelineError, match="a range the arm reaches"):
        from pipeline.model.arm import load_planar_arm

        doe_fit.fit_doe(BuildConfig.from_settings(vary=(("x", 0.0, 0.08),)), load_planar_arm())


def test_paper_build_has_none_of_the_new_keys() -> None:
    """The (L, W) design writes the old doe.json block (the byte checks of tests/build cover the rest)."""
    design = BuildConfig().design.scaled_design()
    assert isinstance(design, FullFactorial) and design.variables.is_size_only
    assert design.to_json() == {
        "levels": 3,
        "L_range": [0.2, 0.3],
        "W_range": [0.08, 0.12],
        "order": "Table 1: W descending by rows, L descending within a row",
    }


def test_replayed_paper_build_writes_no_variables(replayed: list, tmp_path: Path) -> None:
    assert build.main(["--out", str(tmp_path), "--quiet", "--no-progress", "--jobs", "1"]) == 0
    doe = json.loads((tmp_path / "doe.json").read_text())
    coefficients = json.loads((tmp_path / "coefficients.json").read_text())
    assert "variables" not in doe and "variables" not in coefficients
    assert "design" not in coefficients["provenance"] and (tmp_path / "region_map.json").is_file()
    assert list(doe["experiments"][0])[:4] == ["test", "L", "W", "parameters"]


def test_tiny_build_over_L_W_x(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "out"
    argv = [*TINY, "--jobs", "1", "--vary", "x", "-0.03", "0.03", "--allow-unconverged", "--out", str(out)]
    assert build.main(argv) == 0
    stdout = capsys.readouterr().out
    skipped = [line for line in stdout.splitlines() if line.startswith("range certificate: skipped")]
    assert skipped == ["range certificate: skipped, the build did not converge"]  # the tiny PSO's
    assert sorted(p.name for p in out.iterdir()) == ["build_timing.json", "coefficients.json", "doe.json"]

    doe = json.loads((out / "doe.json").read_text())
    assert doe["variables"] == ["L", "W", "x"] and doe["design"]["kind"] == "full-factorial"
    runs = [(e["L"], e["W"], e["x"]) for e in doe["experiments"]]
    assert (
        runs
        == FullFactorial(BuildConfig.from_settings(vary=(("x", -0.03, 0.03),)).design.scaled_design().factors).points()
    )
    assert len(runs) == 27 and {x for _, _, x in runs} == {-0.03, 0.0, 0.03}

    document = json.loads((out / "coefficients.json").read_text())
    assert document["variables"] == ["L", "W", "x"]
    assert document["fitted_range"]["x"] == [-0.03, 0.03] and len(document["basis"]) == 10
    assert document["provenance"]["design"] == "full-factorial"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the tiny PSO did not converge: loading warns
        coefficients = load_coefficients(out / "coefficients.json")
    assert coefficients.variables.names == ("L", "W", "x") and coefficients.region_map is None
    answer = generate(coefficients, 0.25, 0.10, x=0.02)
    assert answer.centre_x_m == pytest.approx(0.02)
    assert answer.path.points_m[2][0] == pytest.approx(0.02)  # P3 above the moved obstacle's centre
    with pytest.raises(PipelineError, match="x"):
        generate(coefficients, 0.25, 0.10)

    # python -m pipeline.regress on the same doe.json fits over its three variables, as the build did.
    refit = tmp_path / "refit.json"
    assert regress.main([str(out / "doe.json"), "-o", str(refit), "--quiet", "--allow-unconverged"]) == 0
    again = json.loads(refit.read_text())
    assert again["variables"] == ["L", "W", "x"] and again["fitted_range"]["x"] == [-0.03, 0.03]
    assert len(again["basis"]) == 10 and len(again["parameters"]["A1"]) == 10


def test_refit_points_per_round_follow_the_number_of_variables(over_x) -> None:
    """The build's certifiable regression adds REFIT_POINTS_PER_ROUND[k] points per round: 400 over
    (L, W), which the default build's coefficients depend on, more over (L, W, x), whose band below
    the margin is a surface across L and x."""
    paper = load_coefficients("paper")
    for coefficients, vary in ((paper, ()), (over_x(paper), (("x", -0.03, 0.03),))):
        config = BuildConfig.from_settings(vary=vary)
        map_config = default_config(coefficients)
        refit = range_stage._refit_config(config, coefficients, map_config)
        assert refit.points_per_round == REFIT_POINTS_PER_ROUND[coefficients.variables.k]
    assert REFIT_POINTS_PER_ROUND[2] == 400 and min(REFIT_POINTS_PER_ROUND[3], REFIT_POINTS_PER_ROUND[4]) > 400
