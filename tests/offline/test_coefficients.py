"""Coefficients files (pipeline.offline.coefficients): the paper's Eq. 9 loads, save/load round trips
byte for byte, malformed files raise DataFileError naming the file, and saving is atomic."""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pipeline import load_coefficients
from pipeline.exceptions import DataFileError, OutputExistsError
from pipeline.model.scene import Scene
from pipeline.motion.families import EXACT_ENDPOINTS
from pipeline.motion.trajectory import PARAMETER_NAMES
from pipeline.offline.coefficients import FORMAT, Coefficients, fit_coefficients, paper_data_path, save_coefficients
from pipeline.offline.doe import load_doe
from pipeline.offline.regression import BASIS


def paper_document() -> dict:
    return json.loads(paper_data_path("paper_eq9_coefficients.json").read_text(encoding="utf-8"))


def write(path: Path, document) -> Path:
    path.write_text(json.dumps(document), encoding="utf-8")
    return path


def exact_endpoints_coefficients() -> Coefficients:
    return Coefficients(
        family=EXACT_ENDPOINTS,
        parameters={
            "w1": (0.9, 0.1, 0.2, 0.0, 0.0, 0.0),
            "phi1": (0.4, 0.0, 0.5, 0.0, 0.0, 0.0),
            "A2": (1.5, -0.5, 0.0, 0.0, 0.0, 1.0),
            "w2": (0.8, 0.0, 0.0, 0.0, 0.3, 0.0),
        },
        fitted_range_m={"L": (0.2, 0.3), "W": (0.08, 0.12)},
        scene=Scene(margin_m=0.012, speed_m_s=0.25),
        link_lengths_m=(0.3, 0.35),
        link_radii_m=(0.005, 0.005),
        elbow=-1,
        extra={"provenance": {"seed": 3, "note": "synthetic"}, "fit": {"experiments": 9}},
    )


# --------------------------------------------------------------------------------------------
# The paper's Eq. 9.


def test_load_paper(table2: np.ndarray, paper_eq9) -> None:
    paper = load_coefficients("paper")
    assert paper.family.name == "paper"
    assert paper.source == "paper"
    assert list(paper.parameters) == list(PARAMETER_NAMES)
    for name in PARAMETER_NAMES:
        assert_allclose(paper.parameters[name], paper_eq9[name], rtol=0, atol=0)
    assert paper.fitted_range_m == {"L": (0.2, 0.3), "W": (0.08, 0.12)}
    assert paper.scene.is_close(Scene())
    assert paper.link_lengths_m == (0.3, 0.35)
    assert paper.elbow == 1
    assert (
        paper.source_sha256 == hashlib.sha256(paper_data_path("paper_eq9_coefficients.json").read_bytes()).hexdigest()
    )
    # Eq. 9 at the DOE points is close to Table 2 (the paper's own regression).
    predicted = paper.predict_free(table2[:, 8], table2[:, 9])
    assert predicted.shape == (9, 8)
    assert np.max(np.abs(predicted - table2[:, :8])) < 0.1
    assert paper.in_range(0.25, 0.1) and paper.in_range(0.2, 0.12) and not paper.in_range(0.31, 0.1)


def test_fit_coefficients_of_the_paper_doe_is_a_valid_paper_file(tmp_path: Path) -> None:
    coefficients, fit = fit_coefficients(load_doe(paper_data_path("paper_table2_doe.json")), {"provenance": {"x": 1}})
    assert coefficients.family.name == "paper"
    assert coefficients.fitted_range_m == {"L": (0.2, 0.3), "W": (0.08, 0.12)}
    assert coefficients.extra["fit"]["experiments"] == 9
    assert coefficients.provenance == {"x": 1}
    save_coefficients(coefficients, tmp_path / "c.json")
    loaded = load_coefficients(tmp_path / "c.json")
    for name in PARAMETER_NAMES:
        assert loaded.parameters[name] == fit.coefficients[name]


# --------------------------------------------------------------------------------------------
# Round trip.


@pytest.mark.parametrize("make", [lambda: load_coefficients("paper"), exact_endpoints_coefficients])
def test_save_load_round_trip_is_byte_identical(tmp_path: Path, make) -> None:
    original = make()
    first, second = tmp_path / "first.json", tmp_path / "second.json"
    assert save_coefficients(original, first) is False  # nothing replaced
    loaded = load_coefficients(first)
    assert save_coefficients(loaded, second) is False
    assert first.read_bytes() == second.read_bytes()
    assert loaded.source == str(first)
    assert loaded.source_sha256 == hashlib.sha256(first.read_bytes()).hexdigest()
    assert loaded.family == original.family
    assert loaded.parameters == {n: original.parameters[n] for n in original.family.free_parameter_names}
    assert loaded.fitted_range_m == original.fitted_range_m
    assert loaded.scene == original.scene
    assert loaded.link_lengths_m == original.link_lengths_m
    assert loaded.link_radii_m == original.link_radii_m
    assert loaded.elbow == original.elbow
    assert loaded.provenance == original.provenance
    assert json.loads(first.read_text())["format"] == FORMAT
    # Saving again over the file replaces it with the same bytes.
    assert save_coefficients(loaded, first) is True
    assert first.read_bytes() == second.read_bytes()


def test_paper_file_resaves_to_itself(tmp_path: Path) -> None:
    save_coefficients(load_coefficients("paper"), tmp_path / "paper.json")
    assert (tmp_path / "paper.json").read_bytes() == paper_data_path("paper_eq9_coefficients.json").read_bytes()


def test_save_refuses_to_overwrite_when_asked(tmp_path: Path) -> None:
    path = tmp_path / "c.json"
    path.write_text("keep me", encoding="utf-8")
    with pytest.raises(OutputExistsError):
        save_coefficients(load_coefficients("paper"), path, overwrite=False)
    assert path.read_text(encoding="utf-8") == "keep me"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.json"]


def test_saved_file_gets_the_usual_permissions(tmp_path: Path) -> None:
    """A coefficients file is an ordinary output: created with the mode a plain write would give
    (0o666 minus the umask), not the owner-only 0o600 of a temporary file."""
    plain = tmp_path / "plain.json"
    plain.write_text("{}", encoding="utf-8")
    save_coefficients(load_coefficients("paper"), tmp_path / "c.json")
    assert oct((tmp_path / "c.json").stat().st_mode & 0o777) == oct(plain.stat().st_mode & 0o777)


def test_replacing_a_file_keeps_its_permissions(tmp_path: Path) -> None:
    path = tmp_path / "c.json"
    save_coefficients(load_coefficients("paper"), path)
    path.chmod(0o640)
    assert save_coefficients(exact_endpoints_coefficients(), path) is True
    assert oct(path.stat().st_mode & 0o777) == oct(0o640)
    assert load_coefficients(path).family.name == "exact-endpoints"


# --------------------------------------------------------------------------------------------
# Malformed files.


def _mutations() -> list[tuple[str, object]]:
    def set_key(key, value):
        def apply(doc):
            doc[key] = value
            return doc

        return apply

    def delete_parameter(doc):
        del doc["parameters"]["phi2"]
        return doc

    def nan_coefficient(doc):
        doc["parameters"]["A1"][3] = float("nan")
        return doc

    def string_coefficient(doc):
        doc["parameters"]["w2"][0] = "1.2"
        return doc

    def short_coefficients(doc):
        doc["parameters"]["w1"] = doc["parameters"]["w1"][:5]
        return doc

    def bool_coefficient(doc):
        doc["parameters"]["A2"][1] = True
        return doc

    def reversed_range(doc):
        doc["fitted_range"]["L"] = [0.3, 0.2]
        return doc

    def missing_range(doc):
        del doc["fitted_range"]["W"]
        return doc

    def negative_range(doc):
        doc["fitted_range"]["W"] = [-0.1, 0.12]
        return doc

    def bad_scene(doc):
        doc["scene"]["speed_m_s"] = -0.2
        return doc

    def bad_links(doc):
        doc["scene"]["link_lengths_m"] = [0.3]
        return doc

    def bad_elbow(doc):
        doc["scene"]["elbow"] = 0
        return doc

    return [
        ("wrong format", set_key("format", "twolink-coefficients/2")),
        ("missing format", lambda doc: {k: v for k, v in doc.items() if k != "format"}),
        ("unknown family", set_key("family", "splines")),
        ("wrong basis", set_key("basis", ["1", "W", "L", "L^2", "L*W", "W^2"])),
        ("parameters not an object", set_key("parameters", [1, 2])),
        ("missing parameter", delete_parameter),
        ("NaN coefficient", nan_coefficient),
        ("string coefficient", string_coefficient),
        ("five coefficients", short_coefficients),
        ("boolean coefficient", bool_coefficient),
        ("fitted_range lo > hi", reversed_range),
        ("fitted_range missing W", missing_range),
        ("fitted_range negative", negative_range),
        ("fitted_range not an object", set_key("fitted_range", None)),
        ("bad scene", bad_scene),
        ("scene not an object", set_key("scene", "paper")),
        ("one link length", bad_links),
        ("bad elbow", bad_elbow),
    ]


@pytest.mark.parametrize(("label", "mutate"), _mutations(), ids=[label for label, _ in _mutations()])
def test_malformed_documents_raise_data_file_error(tmp_path: Path, label: str, mutate) -> None:
    path = tmp_path / "bad_coefficients.json"
    path.write_text(json.dumps(mutate(paper_document()), allow_nan=True), encoding="utf-8")
    with pytest.raises(DataFileError) as info:
        load_coefficients(path)
    message = str(info.value)
    assert str(path) in message, label
    assert "\n" not in message
    assert info.value.reason in message


def test_unmodified_paper_document_loads(tmp_path: Path) -> None:
    """The malformed-file tests start from a valid document."""
    loaded = load_coefficients(write(tmp_path / "ok.json", paper_document()))
    assert loaded.parameters == load_coefficients("paper").parameters


def test_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "nowhere" / "coefficients.json"
    with pytest.raises(DataFileError) as info:
        load_coefficients(path)
    assert str(path) in str(info.value)
    assert "no such file" in str(info.value)


def test_invalid_json(tmp_path: Path) -> None:
    path = tmp_path / "broken.json"
    path.write_text('{"format": "twolink-coefficients/1", "family": ', encoding="utf-8")
    with pytest.raises(DataFileError) as info:
        load_coefficients(path)
    assert str(path) in str(info.value)
    assert "not valid JSON" in str(info.value)


@pytest.mark.parametrize(("content", "kind"), [("[1, 2, 3]", "list"), ('"paper"', "str"), ("3.5", "float")])
def test_json_that_is_not_an_object(tmp_path: Path, content: str, kind: str) -> None:
    path = tmp_path / "array.json"
    path.write_text(content, encoding="utf-8")
    with pytest.raises(DataFileError) as info:
        load_coefficients(path)
    assert str(path) in str(info.value)
    assert kind in str(info.value)


def test_binary_file(tmp_path: Path) -> None:
    path = tmp_path / "binary.json"
    path.write_bytes(b"\xff\xfe\x00\x81")
    with pytest.raises(DataFileError) as info:
        load_coefficients(path)
    assert str(path) in str(info.value)


def test_a_directory(tmp_path: Path) -> None:
    with pytest.raises(DataFileError) as info:
        load_coefficients(tmp_path)
    assert str(tmp_path) in str(info.value)


# --------------------------------------------------------------------------------------------
# Atomic save.


@pytest.mark.parametrize("exception", [OSError("disk full"), KeyboardInterrupt()])
def test_save_is_atomic(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, exception: BaseException) -> None:
    path = tmp_path / "coefficients.json"
    save_coefficients(exact_endpoints_coefficients(), path)
    before = path.read_bytes()
    calls = []

    def failing_replace(src, dst):
        calls.append((Path(src), Path(dst)))
        assert Path(src).read_text(encoding="utf-8").endswith("\n")  # the new text was fully written
        raise exception

    monkeypatch.setattr(os, "replace", failing_replace)
    with pytest.raises(type(exception)):
        save_coefficients(load_coefficients("paper"), path)
    monkeypatch.undo()
    assert len(calls) == 1 and calls[0][1] == path
    assert calls[0][0].parent == path.parent
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["coefficients.json"]
    # The untouched file still loads.
    assert load_coefficients(path).family.name == "exact-endpoints"


def test_failed_first_save_leaves_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def failing_replace(src, dst):
        raise OSError("no space left on device")

    monkeypatch.setattr(os, "replace", failing_replace)
    with pytest.raises(OSError):
        save_coefficients(load_coefficients("paper"), tmp_path / "out" / "coefficients.json")
    monkeypatch.undo()
    assert list((tmp_path / "out").iterdir()) == []


def test_basis_constant_matches_the_paper() -> None:
    assert list(BASIS) == paper_document()["basis"]
