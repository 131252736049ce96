"""The scene without code: ``python -m pipeline.build --scene FILE`` (TOML or JSON, keys as the
scene's fields in coefficients.json) and the scene options; the scene lands in the coefficients."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pipeline import load_coefficients
from pipeline.build import doe_fit as build_library
from pipeline.build import scene_from_options
from pipeline.commands import build
from pipeline.exceptions import DataFileError, InvalidParameterError
from pipeline.model.scene import SCENE_FIELDS, Scene, read_scene_file

TINY_ARGV = ["--swarm-size", "8", "--iterations", "5", "--restarts", "1", "--plain", "--quiet", "--allow-unconverged"]


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_toml_and_json_give_the_same_scene(tmp_path: Path) -> None:
    toml = write(tmp_path, "s.toml", "top_y_m = 0.54\nspeed_m_s = 0.25\napex_dy_m = 0.09\n")
    as_json = write(tmp_path, "s.json", json.dumps({"top_y_m": 0.54, "speed_m_s": 0.25, "apex_dy_m": 0.09}))
    assert read_scene_file(toml) == read_scene_file(as_json) == {"top_y_m": 0.54, "speed_m_s": 0.25, "apex_dy_m": 0.09}
    scene = scene_from_options(toml)
    assert scene == Scene(top_y_m=0.54, speed_m_s=0.25, apex_dy_m=0.09)


def test_every_field_of_a_stored_scene_is_a_key(tmp_path: Path) -> None:
    """A coefficients file's scene block, without the arm's keys, is a valid scene file."""
    stored = {k: v for k, v in Scene(top_y_m=0.55).to_dict().items()}
    assert set(stored) == set(SCENE_FIELDS)
    path = write(tmp_path, "s.json", json.dumps(stored))  # start_y_m is null: y1 = d
    assert scene_from_options(path) == Scene(top_y_m=0.55)


def test_options_override_the_file(tmp_path: Path) -> None:
    path = write(tmp_path, "s.toml", "top_y_m = 0.54\nmargin_m = 0.02\n")
    scene = scene_from_options(path, top_y_m=0.55, margin_m=None)
    assert scene.top_y_m == 0.55 and scene.margin_m == 0.02


@pytest.mark.parametrize(
    ("name", "text", "needle"),
    [
        ("misspelt.toml", "top_y = 0.54\n", "unknown key 'top_y' (did you mean 'top_y_m'?)"),
        ("unknown.json", '{"colour": 1}', "unknown key 'colour'"),
        ("arm.json", '{"link_lengths_m": [0.3, 0.35]}', "'link_lengths_m' comes from the arm's URDF"),
        ("string.toml", 'top_y_m = "0.54"\n', "top_y_m = '0.54' is not a number"),
        ("bool.json", '{"margin_m": true}', "margin_m = True is not a number"),
        ("broken.toml", "top_y_m = \n", "not valid TOML"),
        ("broken.json", "{", "not valid JSON"),
        ("list.json", "[1]", "expected a table of scene keys"),
        ("scene.yaml", "top_y_m: 0.54\n", "must end in .toml or .json"),
    ],
)
def test_bad_scene_files_name_the_file_and_key(tmp_path: Path, name: str, text: str, needle: str) -> None:
    path = write(tmp_path, name, text)
    with pytest.raises(DataFileError) as info:
        scene_from_options(path)
    message = str(info.value)
    assert message.startswith(f"--scene {path}: ") and needle in message and "\n" not in message


def test_missing_scene_file(tmp_path: Path) -> None:
    with pytest.raises(DataFileError, match="no such file"):
        scene_from_options(tmp_path / "none.toml")


def test_bad_values_name_the_option_or_the_files_key(tmp_path: Path) -> None:
    path = write(tmp_path, "s.toml", "speed_m_s = -1.0\n")
    with pytest.raises(InvalidParameterError, match=r"^--scene .*s\.toml: speed_m_s = -1\.0 is invalid"):
        scene_from_options(path)
    with pytest.raises(InvalidParameterError, match=r"^--speed = 0\.0 is invalid"):
        scene_from_options(path, speed_m_s=0.0)


def test_cli_refuses_a_misspelt_key_before_any_work(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    monkeypatch.setattr(build_library, "run_doe", lambda *args, **kwargs: pytest.fail("the DOE ran"))
    path = write(tmp_path, "s.toml", "top_y_m = 0.54\napex_dy = 0.1\n")
    out = tmp_path / "out"
    assert build.main([*TINY_ARGV, "--scene", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown key 'apex_dy' (did you mean 'apex_dy_m'?)" in err[0]
    assert not out.exists()


def test_cli_refuses_an_unreachable_scene_before_any_work(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    monkeypatch.setattr(build_library, "run_doe", lambda *args, **kwargs: pytest.fail("the DOE ran"))
    assert build.main([*TINY_ARGV, "--top-y", "0.9", "--out", str(tmp_path / "out")]) == 2
    assert "cannot pass this obstacle" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_the_scene_goes_into_the_coefficients(tmp_path: Path) -> None:
    """A (tiny) build in a moved scene: both files carry it, and loading gives it back."""
    path = write(tmp_path, "s.toml", "top_y_m = 0.54\napproach_dy_m = 0.035\n")
    out = tmp_path / "out"
    # W up to 0.10 m: with d = 0.54 m and W = 0.12 m the pose at P5 is inside the obstacle.
    argv = [*TINY_ARGV, "--scene", str(path), "--margin", "0.012", "--W-range", "0.08", "0.10", "--out", str(out)]
    assert build.main(argv) == 0
    with pytest.warns(UserWarning):  # tiny: not converged
        coefficients = load_coefficients(out / "coefficients.json")
    assert coefficients.scene == Scene(top_y_m=0.54, approach_dy_m=0.035, margin_m=0.012)
    document = json.loads((out / "doe.json").read_text())
    assert document["scene"]["top_y_m"] == 0.54
    # Not the paper's scene: the paper's Table 2 is not scored beside our rows.
    assert all("paper_table2" not in row for row in document["experiments"])
