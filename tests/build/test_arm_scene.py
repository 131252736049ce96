"""d chosen for a build's own arm (pipeline.build.arm_scene): the configuration returned passes
the build's pre-check at the recommended d, and says so in one line."""

from __future__ import annotations

from pathlib import Path

import pytest

from pipeline.build.arm_scene import scene_for_arm, window_for_build
from pipeline.build.config import BuildConfig
from pipeline.build.doe_fit import check_before_work
from pipeline.exceptions import InfeasibleSceneError, InvalidParameterError, NoSceneWindowError
from pipeline.model.arm import load_planar_arm
from pipeline.model.scene import Scene


def test_the_chosen_config_passes_the_pre_check_the_given_one_fails(tmp_path: Path, urdf_with_links) -> None:
    urdf = urdf_with_links(tmp_path, 0.40, 0.30)
    arm = load_planar_arm(urdf)
    given = BuildConfig.from_settings(urdf_path=urdf, jobs=1)
    with pytest.raises(InfeasibleSceneError):  # the paper's d = 0.56 m: the pose at P5 collides
        check_before_work(given, arm)
    chosen, note = scene_for_arm(arm, given)
    assert chosen.scene.top_y_m == pytest.approx(0.635, abs=1e-12)
    assert chosen.scene == Scene(top_y_m=chosen.scene.top_y_m)  # nothing else changed
    assert chosen.design == given.design
    assert chosen.urdf_path == given.urdf_path and chosen.seed == given.seed
    check_before_work(chosen, arm)
    assert note.startswith("--top-y 0.635 chosen for this arm") and "\n" not in note and "shrunk" not in note


def test_a_shrunk_range_is_put_into_the_config_and_said(tmp_path: Path, urdf_with_links) -> None:
    urdf = urdf_with_links(tmp_path, 0.30, 0.28)
    arm = load_planar_arm(urdf)
    chosen, note = scene_for_arm(arm, BuildConfig.from_settings(urdf_path=urdf, jobs=1))
    assert chosen.design.length_range_m != BuildConfig().design.length_range_m
    low, high = chosen.design.length_range_m
    assert f"its window is narrower, so the range is shrunk to L {low:.3f} {high:.3f}" in note
    check_before_work(chosen, arm)
    narrow, note = scene_for_arm(arm, BuildConfig.from_settings(urdf_path=urdf, jobs=1), shrink=False)
    assert narrow.design.length_range_m == BuildConfig().design.length_range_m
    assert "caution: the window is only 5.1 mm wide" in note
    check_before_work(narrow, arm)


def test_an_arm_too_short_is_refused(tmp_path: Path, urdf_with_links) -> None:
    urdf = urdf_with_links(tmp_path, 0.10, 0.10)
    with pytest.raises(NoSceneWindowError, match="P1"):
        scene_for_arm(load_planar_arm(urdf), BuildConfig.from_settings(urdf_path=urdf, jobs=1))


def test_a_build_that_varies_d_has_no_single_d_to_choose(arm) -> None:
    with pytest.raises(InvalidParameterError, match="--vary"):
        window_for_build(arm, BuildConfig.from_settings(vary=(("d", 0.55, 0.57),), jobs=1))


def test_the_build_command_chooses_d_for_its_own_arm_and_keeps_a_given_one(
    tmp_path: Path, capsys, urdf_with_links
) -> None:
    """``python -m pipeline.build --urdf`` without --top-y or --scene: d chosen and said on stderr;
    with --top-y, or the shipped arm, the scene is the user's; a missing parent is refused first."""
    from pipeline.commands import build as build_command

    urdf = urdf_with_links(tmp_path, 0.40, 0.30)

    def config(*argv: str) -> BuildConfig:
        args = build_command.parser().parse_args(["--out", str(tmp_path / "out"), *argv])
        return build_command._with_scene_for_arm(build_command.config_from_args(args), args)

    assert config("--urdf", str(urdf)).scene.top_y_m == pytest.approx(0.635, abs=1e-12)
    assert "--top-y 0.635 chosen for this arm" in capsys.readouterr().err
    assert config("--urdf", str(urdf), "--top-y", "0.62").scene.top_y_m == 0.62
    assert config().scene.top_y_m == Scene().top_y_m and capsys.readouterr().err == ""
    status = build_command.main(["--urdf", str(urdf), "--out", str(tmp_path / "missing" / "deep" / "r")])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and "missing" in err and "chosen" not in err


def test_a_bare_vary_d_takes_the_arms_window(tmp_path: Path, capsys, arm) -> None:
    """``--vary d`` without a range varies d over the arm's window over the build's (L, W, x)
    range, rounded inwards: inside the window python -m pipeline.scene finds, said on stderr;
    the build's pre-check passes over it."""
    from pipeline.commands import build as build_command

    args = build_command.parser().parse_args(
        ["--out", str(tmp_path / "r"), "--vary", "x", "-0.03", "0.03", "--vary", "d"]
    )
    rest, bare = build_command._without_bare_d(args)
    assert bare and rest.vary == [["x", "-0.03", "0.03"]] and args.vary[-1] == ["d"]
    config = build_command._with_d_for_arm(build_command.config_from_args(rest))
    assert config.variables.names == ("L", "W", "x", "d")
    window = window_for_build(arm, build_command.config_from_args(rest), shrink=False)
    low, high = config.design.scaled_design().ranges_m["d"]
    assert window.low_m <= low < high <= window.high_m and low - window.low_m < 1e-4 and window.high_m - high < 1e-4
    assert f"--vary d {low:.4f} {high:.4f} chosen for this arm" in capsys.readouterr().err
    check_before_work(config, arm)  # at its grid of d (5 levels, both ends included)
    given = build_command.parser().parse_args(["--vary", "d", "0.55", "0.57"])
    assert build_command._without_bare_d(given) == (given, False)
