"""The scene variables of a fit (pipeline.offline.variables): the vocabulary and its canonical
order, one-line refusals of unknown names, the quadratic basis for k = 2, 3, 4 (for (L, W) the
paper's basis to the bit), the values a fit requires, and the scene an answer is placed in."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.exceptions import InvalidParameterError
from pipeline.model.scene import Scene
from pipeline.offline.regression import BASIS, design_matrix
from pipeline.offline.variables import DEFAULT_VARIABLES, NAMES, Variables, check_name, quadratic_design


def test_the_vocabulary_and_its_canonical_order() -> None:
    assert NAMES == ("L", "W", "x", "d")
    assert Variables(("x", "W", "L")).names == ("L", "W", "x")
    assert Variables(("d", "x", "L", "W")) == Variables(("L", "W", "x", "d"))
    assert Variables.of(None) is DEFAULT_VARIABLES
    assert Variables.of(["W", "L"]) == DEFAULT_VARIABLES
    assert DEFAULT_VARIABLES.is_size_only and DEFAULT_VARIABLES.extra == ()
    three = Variables(("L", "W", "x"))
    assert not three.is_size_only and three.extra == ("x",) and three.k == 3
    assert three.index("x") == 2


@pytest.mark.parametrize(
    ("names", "named", "suggestion"),
    [
        (("L", "W", "X"), "'X'", "'x'"),
        (("L", "W", "centre"), "'centre'", None),
        (("L", "w"), "'w'", "'W'"),
        (("L", "W", "xx"), "'xx'", "'x'"),
    ],
)
def test_unknown_names_are_refused_in_one_line(names, named, suggestion) -> None:
    with pytest.raises(InvalidParameterError) as info:
        Variables(names)
    message = str(info.value)
    assert "\n" not in message
    assert named in message and "L, W, x, d" in message
    if suggestion is not None:
        assert f"did you mean {suggestion}?" in message


def test_empty_repeated_and_non_string_names_are_refused() -> None:
    with pytest.raises(InvalidParameterError, match="at least one"):
        Variables(())
    with pytest.raises(InvalidParameterError, match="each name once"):
        Variables(("L", "W", "L"))
    with pytest.raises(InvalidParameterError, match="variable"):
        check_name(3)


@pytest.mark.parametrize(
    ("names", "basis"),
    [
        (("L", "W"), ("1", "L", "W", "L^2", "L*W", "W^2")),
        (("L", "W", "x"), ("1", "L", "W", "x", "L^2", "L*W", "L*x", "W^2", "W*x", "x^2")),
        (
            ("L", "W", "x", "d"),
            ("1", "L", "W", "x", "d", "L^2", "L*W", "L*x", "L*d", "W^2", "W*x", "W*d", "x^2", "x*d", "d^2"),
        ),
    ],
)
def test_basis_order_and_size(names, basis) -> None:
    variables = Variables(names)
    k = len(names)
    assert variables.basis == basis
    assert variables.basis_size == len(basis) == 1 + k + k * (k + 1) // 2
    rng = np.random.default_rng(k)
    points = rng.uniform(-1.0, 1.0, (7, k))
    design = variables.design(points)
    assert design.shape == (7, len(basis))
    # Each column is the term its name says, evaluated directly.
    column = dict(zip(names, points.T, strict=True))
    for j, term in enumerate(basis):
        if term == "1":
            expected = np.ones(7)
        elif "^" in term:
            expected = column[term[0]] * column[term[0]]
        elif "*" in term:
            a, b = term.split("*")
            expected = column[a] * column[b]
        else:
            expected = column[term]
        np.testing.assert_array_equal(design[:, j], expected)


def test_the_two_variable_basis_is_the_papers_to_the_bit() -> None:
    assert DEFAULT_VARIABLES.basis == BASIS
    rng = np.random.default_rng(0)
    L, W = rng.uniform(0.15, 0.35, (4, 5)), rng.uniform(0.06, 0.14, (4, 5))
    assert np.array_equal(quadratic_design(np.stack([L, W], -1)), design_matrix(L, W))
    assert np.array_equal(DEFAULT_VARIABLES.design(np.array([0.27, 0.09])), design_matrix(0.27, 0.09))


def test_design_refuses_the_wrong_number_of_columns() -> None:
    with pytest.raises(InvalidParameterError, match="points"):
        Variables(("L", "W", "x")).design(np.zeros((4, 2)))


def test_take_requires_exactly_the_extra_variables() -> None:
    three = Variables(("L", "W", "x"))
    assert three.take({"x": 0.05, "d": None}) == {"x": 0.05}
    assert DEFAULT_VARIABLES.take({"x": None, "d": None}) == {}
    with pytest.raises(InvalidParameterError, match=r"^x = None is invalid: expected a value: .*x= is required"):
        three.take({"x": None})
    with pytest.raises(InvalidParameterError, match=r"^x = 0\.05 is invalid: .*vary L, W only"):
        DEFAULT_VARIABLES.take({"x": 0.05})
    with pytest.raises(InvalidParameterError, match=r"^d = 0\.5 is invalid"):
        three.take({"x": 0.0, "d": 0.5})


def test_scene_for_and_values_of() -> None:
    variables = Variables(("L", "W", "x", "d"))
    base = Scene()
    moved = variables.scene_for(base, {"x": -0.03, "d": 0.55})
    assert (moved.centre_x_m, moved.top_y_m) == (-0.03, 0.55)
    assert moved.speed_m_s == base.speed_m_s and moved.start_dx_m == base.start_dx_m
    assert variables.values_of(moved) == {"x": -0.03, "d": 0.55}
    assert variables.scene_for(base, {}) is base
    assert DEFAULT_VARIABLES.values_of(moved) == {}
