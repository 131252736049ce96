"""Every build setting declared once (:data:`pipeline.build.options.BUILD_OPTIONS`): each field of
:class:`BuildConfig` and of its sections has exactly one option, the parser holds every option
with its unit and default, and parsed options give the configuration the same settings give."""

from __future__ import annotations

import dataclasses
import os

import pytest

from pipeline.build import BuildConfig, DesignSettings, ExecutionSettings, RegressionSettings
from pipeline.build.config import SECTIONS
from pipeline.build.options import BUILD_OPTIONS, OPTIONS, SCENE_OPTIONS, SCENE_SECTION, SETTINGS
from pipeline.commands import build
from pipeline.exceptions import InvalidParameterError
from pipeline.model.scene import Scene


def test_every_field_has_one_option_and_every_option_a_field() -> None:
    declared = [(option.section, option.attribute) for option in SETTINGS.values()]
    assert len(declared) == len(set(declared)) == len(OPTIONS)
    own = {(("", f.name)) for f in dataclasses.fields(BuildConfig) if f.name not in SECTIONS}
    nested = {(name, f.name) for name, section in SECTIONS.items() for f in dataclasses.fields(section)}
    assert set(declared) == own | nested
    assert set(SCENE_OPTIONS) <= {f.name for f in dataclasses.fields(Scene)}
    flags = [option.flag for option in BUILD_OPTIONS]
    assert len(flags) == len(set(flags))


def test_the_parser_holds_every_option_with_its_unit_and_default() -> None:
    actions = {action.option_strings[0]: action for action in build.parser()._actions if action.option_strings}
    for option in BUILD_OPTIONS:
        action = actions[option.flag]
        assert action.help == option.help_text()
        if option.kind in ("int", "float", "count", "jobs", "timeout", "positive"):
            assert f"[{option.unit}]" in action.help, option.flag
    help_text = " ".join(build.parser().format_help().split())
    assert "--swarm-size SWARM_SIZE PSO particles per swarm [count] (default: 40)" in help_text
    assert "--worker-timeout SECONDS with --scheduler" in help_text and "(default: 30.0)" in help_text
    assert "--top-y M d, the y of the obstacle's far edge [m] (default: 0.56, or the scene file's)" in help_text


def test_parsed_options_give_the_configuration_their_settings_give() -> None:
    argv = ["--out", "elsewhere", "--seed", "3", "--levels", "4", "--L-range", "0.21", "0.29", "--vary", "x"]
    argv += ["--jobs", "2", "--swarm-size", "9", "--no-polish", "--plain", "--allow-unconverged"]
    argv += ["--clearance-rounds", "0", "--no-range-map", "--near-optimal-cells", "4", "--top-y", "0.55"]
    argv += ["--acceleration-limit", "5", "6", "--worker-timeout", "7"]
    expected = BuildConfig.from_settings(
        out_folder="elsewhere",
        seed=3,
        levels=4,
        length_range_m=(0.21, 0.29),
        vary=(("x", -0.05, 0.05),),
        jobs=2,
        swarm_size=9,
        polish=False,
        endpoint_tolerance_m=None,
        allow_unconverged=True,
        clearance_rounds=0,
        range_map=False,
        near_optimal_cells=4,
        scene=Scene(top_y_m=0.55),
        acceleration_limits_rad_s2=(5.0, 6.0),
        worker_timeout_s=7.0,
    )
    assert build.config_from_args(build.parser().parse_args(argv)) == expected
    assert build.config_from_args(build.parser().parse_args([])) == BuildConfig().with_settings(
        jobs=os.cpu_count() or 1
    )


def test_settings_by_name_and_by_section_are_one_configuration() -> None:
    flat = BuildConfig.from_settings(jobs=1, clearance_rounds=0, width_range_m=(0.08, 0.10))
    nested = BuildConfig(
        execution=ExecutionSettings(jobs=1),
        regression=RegressionSettings(clearance_rounds=0),
        design=DesignSettings(width_range_m=(0.08, 0.10)),
    )
    assert flat == nested and flat.settings()["jobs"] == 1 and flat.settings()["design_kind"] is not None
    assert BuildConfig.from_settings(**flat.settings()) == flat
    assert flat.with_settings(jobs=2).execution.jobs == 2 and flat.with_settings(jobs=2).regression == flat.regression
    with pytest.raises(InvalidParameterError, match=r"^setting = 'job'"):
        BuildConfig.from_settings(job=1)
    with pytest.raises(InvalidParameterError, match=r"^design = "):
        BuildConfig(design={"levels": 3})


def test_scene_options_are_the_scene_sections() -> None:
    assert all(option.section == SCENE_SECTION for option in BUILD_OPTIONS if option.name in SCENE_OPTIONS)
    assert SCENE_OPTIONS["top_y_m"] == "--top-y" and OPTIONS["scene"] == "--scene"
