"""The scene (pipeline.model.scene): the obstacle's centre x as a scene field, checked, read from
scene files, and written into stored scene blocks only when it is not 0."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline.build import scene_from_options
from pipeline.exceptions import DataFileError, InvalidParameterError
from pipeline.model.scene import OPTIONAL_SCENE_FIELDS, SCENE_FIELDS, SCENE_KEYS, Scene, read_scene_file

#: The scene block every stored scene had before the centre x existed, in its order.
STORED_FIELDS = (
    "top_y_m",
    "start_y_m",
    "speed_m_s",
    "margin_m",
    "corner_radius_m",
    "obstacle_height_m",
    "start_dx_m",
    "approach_dx_m",
    "approach_dy_m",
    "apex_dy_m",
)


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_centre_defaults_to_the_paper_and_is_not_stored_then() -> None:
    scene = Scene()
    assert scene.centre_x_m == 0.0
    stored = scene.to_dict()
    assert tuple(stored) == STORED_FIELDS == SCENE_FIELDS
    assert stored == {
        "top_y_m": 0.56,
        "start_y_m": None,
        "speed_m_s": 0.2,
        "margin_m": 0.01,
        "corner_radius_m": 0.01,
        "obstacle_height_m": 1.0,
        "start_dx_m": 0.12,
        "approach_dx_m": 0.03,
        "approach_dy_m": 0.03,
        "apex_dy_m": 0.10,
    }
    assert json.dumps(Scene(centre_x_m=0.0).to_dict()) == json.dumps(stored)
    assert "centre_x_m" not in Scene(centre_x_m=-0.0).to_dict()


@settings(max_examples=50, deadline=None)
@given(st.floats(-0.2, 0.2).filter(lambda x: x != 0.0))
def test_a_centre_other_than_0_is_stored_and_read_back(centre: float) -> None:
    scene = Scene(top_y_m=0.55, centre_x_m=centre)
    stored = scene.to_dict()
    assert tuple(stored) == (*STORED_FIELDS, "centre_x_m")
    assert stored["centre_x_m"] == centre
    assert Scene.from_dict(json.loads(json.dumps(stored))) == scene
    # A block without the key (every file written before it existed) reads as centre 0.
    assert Scene.from_dict({k: v for k, v in stored.items() if k != "centre_x_m"}).centre_x_m == 0.0


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_centre_must_be_finite(bad: float) -> None:
    with pytest.raises(InvalidParameterError) as info:
        Scene(centre_x_m=bad)
    assert info.value.name == "centre_x_m"


def test_is_close_sees_the_centre() -> None:
    assert Scene().is_close(Scene(centre_x_m=0.0))
    assert Scene(centre_x_m=0.02).is_close(Scene(centre_x_m=0.02 + 1e-15))
    assert not Scene().is_close(Scene(centre_x_m=1e-6))
    assert not Scene(centre_x_m=1e-6).is_close(Scene())


def test_scene_keys_are_the_stored_fields_and_the_optional_ones() -> None:
    assert OPTIONAL_SCENE_FIELDS == ("centre_x_m",)
    assert SCENE_KEYS == (*SCENE_FIELDS, "centre_x_m")


def test_scene_files_accept_the_centre(tmp_path: Path) -> None:
    toml = write(tmp_path, "s.toml", "centre_x_m = -0.03\ntop_y_m = 0.55\n")
    as_json = write(tmp_path, "s.json", json.dumps({"centre_x_m": -0.03, "top_y_m": 0.55}))
    assert read_scene_file(toml) == read_scene_file(as_json) == {"centre_x_m": -0.03, "top_y_m": 0.55}
    assert scene_from_options(toml) == Scene(top_y_m=0.55, centre_x_m=-0.03)
    # An integer is a number too.
    assert scene_from_options(write(tmp_path, "i.toml", "centre_x_m = 0\n")) == Scene()


def test_a_stored_block_with_a_centre_is_a_valid_scene_file(tmp_path: Path) -> None:
    scene = Scene(centre_x_m=0.04)
    path = write(tmp_path, "s.json", json.dumps(scene.to_dict()))
    assert scene_from_options(path) == scene


@pytest.mark.parametrize(
    ("name", "text", "needle"),
    [
        ("misspelt.toml", "centre_x = 0.01\n", "unknown key 'centre_x' (did you mean 'centre_x_m'?)"),
        ("american.json", '{"center_x_m": 0.01}', "unknown key 'center_x_m' (did you mean 'centre_x_m'?)"),
        ("unknown.json", '{"colour": 1}', "unknown key 'colour'"),
        ("string.toml", 'centre_x_m = "0.01"\n', "centre_x_m = '0.01' is not a number"),
        ("bool.json", '{"centre_x_m": false}', "centre_x_m = False is not a number"),
        ("null.json", '{"centre_x_m": null}', "centre_x_m = None is not a number"),
    ],
)
def test_bad_centre_keys_are_refused(tmp_path: Path, name: str, text: str, needle: str) -> None:
    path = write(tmp_path, name, text)
    with pytest.raises(DataFileError) as info:
        read_scene_file(path)
    message = str(info.value)
    assert needle in message
    if "unknown key" in needle:
        assert message.endswith(f"the scene's keys are {', '.join(SCENE_KEYS)}")


def test_a_non_finite_centre_in_a_file_names_the_key(tmp_path: Path) -> None:
    path = write(tmp_path, "s.toml", "centre_x_m = inf\n")
    with pytest.raises(InvalidParameterError, match=r"^--scene .*s\.toml: centre_x_m = inf is invalid"):
        scene_from_options(path)
