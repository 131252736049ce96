"""Coefficients files over more scene variables than (L, W) (pipeline.offline.coefficients): the
file names its variables only when they are not exactly (L, W), round-trips byte for byte, and
its fitted range has one entry per variable; an (L, W) file keeps its bytes; predict_free and
in_range take the extra variables by name and refuse a missing or unexpected one."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pipeline.exceptions import DataFileError, InvalidParameterError
from pipeline.io.jsonio import dumps
from pipeline.model.scene import Scene
from pipeline.offline.coefficients import (
    Coefficients,
    coefficients_from_json,
    fit_coefficients,
    paper_data_path,
    read_coefficients,
    save_coefficients,
)
from pipeline.offline.doe import load_doe
from pipeline.offline.regression import predict_points
from pipeline.offline.variables import Variables

LWX = Variables(("L", "W", "x"))
#: Positions of the (L, W) basis's six terms in the (L, W, x) basis.
LW_TERMS_IN_LWX = (0, 1, 2, 4, 5, 7)


def with_x(coefficients: Coefficients, x_range=(-0.03, 0.03), seed: int = 1) -> Coefficients:
    """``coefficients`` over (L, W, x): the same (L, W) terms and small random x terms."""
    rng = np.random.default_rng(seed)
    parameters = {}
    for name, b in coefficients.parameters.items():
        lifted = np.zeros(LWX.basis_size)
        lifted[list(LW_TERMS_IN_LWX)] = b
        lifted[[3, 6, 8, 9]] = rng.normal(0.0, 0.1, 4)
        parameters[name] = tuple(float(v) for v in lifted)
    return replace(
        coefficients,
        parameters=parameters,
        fitted_range_m={**coefficients.fitted_range_m, "x": x_range},
        variables=LWX,
        source="",
        source_sha256="",
    )


@pytest.fixture(scope="module")
def paper() -> Coefficients:
    return read_coefficients(paper_data_path("paper_eq9_coefficients.json"))


def test_a_file_over_l_w_x_names_them_and_round_trips_byte_for_byte(paper, tmp_path: Path) -> None:
    moved = with_x(paper)
    document = moved.to_json()
    assert list(document)[:5] == ["format", "family", "variables", "basis", "parameters"]
    assert document["variables"] == ["L", "W", "x"]
    assert document["basis"] == ["1", "L", "W", "x", "L^2", "L*W", "L*x", "W^2", "W*x", "x^2"]
    assert document["fitted_range"] == {"L": [0.2, 0.3], "W": [0.08, 0.12], "x": [-0.03, 0.03]}
    assert "centre_x_m" not in document["scene"]  # the base scene: x is an input
    first, second = tmp_path / "a.json", tmp_path / "b.json"
    save_coefficients(moved, first)
    again = read_coefficients(first)
    assert again.variables == LWX and again.parameters == moved.parameters
    assert again.fitted_range_m == moved.fitted_range_m
    save_coefficients(again, second)
    assert first.read_bytes() == second.read_bytes()


def test_an_l_w_file_has_no_variables_key_and_keeps_its_bytes(paper, tmp_path: Path) -> None:
    """The shipped Eq. 9 and a file written here from a fit: read and written back, the same bytes."""
    shipped = paper_data_path("paper_eq9_coefficients.json")
    assert "variables" not in paper.to_json()
    copy = tmp_path / "eq9.json"
    save_coefficients(paper, copy)
    assert copy.read_bytes() == dumps(json.loads(shipped.read_text(encoding="utf-8"))).encode("utf-8")
    fitted, _ = fit_coefficients(load_doe(paper_data_path("paper_table2_doe.json")))
    written, rewritten = tmp_path / "fit.json", tmp_path / "fit2.json"
    save_coefficients(fitted, written)
    assert "variables" not in json.loads(written.read_text(encoding="utf-8"))
    save_coefficients(read_coefficients(written), rewritten)
    assert written.read_bytes() == rewritten.read_bytes()
    # An explicit ["L", "W"] is read as the default (and not written back).
    document = paper.to_json()
    explicit = coefficients_from_json({**document, "variables": ["L", "W"]}, "memory", "")
    assert explicit.variables == Variables() and dumps(explicit.to_json()) == dumps(document)


def test_the_extra_variables_are_taken_by_name(paper) -> None:
    moved = with_x(paper)
    L, W, x = np.array([0.22, 0.27]), np.array([0.09, 0.11]), np.array([-0.01, 0.02])
    ordered = {name: moved.parameters[name] for name in moved.family.free_parameter_names}
    expected = predict_points(ordered, np.stack([L, W, x], -1))
    assert np.array_equal(moved.predict_free(L, W, x=x), expected)
    assert np.array_equal(
        moved.predict_free(0.22, 0.09, x=-0.01), predict_points(ordered, np.array([0.22, 0.09, -0.01]))
    )
    np.testing.assert_allclose(moved.predict_free(0.22, 0.09, x=-0.01), expected[0], rtol=0, atol=1e-15)
    assert np.array_equal(moved.predict_free(L, W, x=0.0), predict_points(ordered, np.stack([L, W, [0, 0]], -1)))
    # With x = 0 the x terms vanish: the (L, W) prediction, to rounding.
    np.testing.assert_allclose(moved.predict_free(L, W, x=0.0), paper.predict_free(L, W), rtol=0, atol=1e-14)
    with pytest.raises(InvalidParameterError, match=r"^x = None is invalid: .*x= is required"):
        moved.predict_free(L, W)
    with pytest.raises(InvalidParameterError, match=r"^x = 0\.01 is invalid: .*vary L, W only"):
        paper.predict_free(0.25, 0.1, x=0.01)
    assert moved.in_range(0.25, 0.1, x=0.03) and not moved.in_range(0.25, 0.1, x=0.031)
    assert paper.in_range(0.25, 0.1)
    with pytest.raises(InvalidParameterError, match="x"):
        moved.in_range(0.25, 0.1)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"variables": ["L", "x"]}, r"L and W first"),
        ({"variables": ["x", "L", "W"]}, r"in the order \['L', 'W', 'x'\]"),
        ({"variables": ["L", "W", "X"]}, r"did you mean 'x'\?"),
        ({"variables": "L, W, x"}, r"'variables' must be a list of names"),
        ({"basis": ["1", "L", "W", "L^2", "L*W", "W^2"]}, r"basis is .*expected \['1', 'L', 'W', 'x'"),
        ({"fitted_range": {"L": [0.2, 0.3], "W": [0.08, 0.12]}}, r"'x' must be a list of two finite numbers"),
        ({"fitted_range": {"L": [0.2, 0.3], "W": [0.08, 0.12], "x": [0.03, -0.03]}}, r"x = \[0\.03, -0\.03\]"),
    ],
)
def test_malformed_variables_are_refused_naming_the_file(paper, change: dict, message: str) -> None:
    document = {**with_x(paper).to_json(), **change}
    with pytest.raises(DataFileError, match=message) as info:
        coefficients_from_json(document, "c.json", "")
    assert "c.json" in str(info.value) and "\n" not in str(info.value)


def test_six_coefficients_for_three_variables_are_refused(paper) -> None:
    document = with_x(paper).to_json()
    document["parameters"] = paper.to_json()["parameters"]
    with pytest.raises(DataFileError, match="must be 10 finite numbers"):
        coefficients_from_json(document, "c.json", "")


def test_a_scene_centre_is_still_refused_with_x_as_a_variable(paper) -> None:
    document = replace(with_x(paper), scene=Scene(centre_x_m=0.01)).to_json()
    with pytest.raises(DataFileError, match=r"centre_x_m = 0\.01, expected 0"):
        coefficients_from_json(document, "c.json", "")
