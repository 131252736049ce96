"""Designs over k scene factors (pipeline.offline.designs): the 3^k full factorial in Table 1 order
(for (L, W) the paper's design, to the bit), pyDOE's Box-Behnken and face-centred central
composite scaled into the box, the doe.json block, and bad designs."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from pipeline.exceptions import InvalidParameterError
from pipeline.offline.designs import (
    DEFAULT_RANGES_M,
    DESIGN_KINDS,
    BoxBehnken,
    CentralComposite,
    Factor,
    FullFactorial,
    design_class,
)
from pipeline.offline.doe import Design

L, W = Factor("L", (0.20, 0.30)), Factor("W", (0.08, 0.12))
X, D = Factor("x", (-0.05, 0.05)), Factor("d", (0.54, 0.58))


def in_box(design) -> bool:
    points = design.array()
    lo = np.array([f.range_m[0] for f in design.factors])
    hi = np.array([f.range_m[1] for f in design.factors])
    return bool(np.all(points >= lo) and np.all(points <= hi))


@pytest.mark.parametrize("levels", [3, 4, 5])
def test_full_factorial_over_L_W_is_the_paper_design(levels: int) -> None:
    design = FullFactorial((L, W), levels)
    old = Design(levels)
    assert design.points() == old.points()  # exactly: they label the tests
    assert design.to_json() == old.to_json()  # the doe.json block key for key
    assert old.full_factorial() == design
    assert design.variables.names == ("L", "W")


def test_full_factorial_in_three_factors() -> None:
    design = FullFactorial((X, W, L))  # given in any order, stored canonically
    assert design.variables.names == ("L", "W", "x")
    points = design.points()
    assert len(points) == 27 and len(set(points)) == 27
    # L fastest, then W, x slowest; every factor descending; each x block is the (L, W) design.
    assert points[0] == (0.30, 0.12, 0.05) and points[-1] == (0.20, 0.08, -0.05)
    for block, x in zip(range(3), (0.05, 0.0, -0.05), strict=True):
        rows = points[9 * block : 9 * block + 9]
        assert [(p[0], p[1]) for p in rows] == Design().points()
        assert {p[2] for p in rows} == {x}
    assert set(points) == set(itertools.product((0.30, 0.25, 0.20), (0.12, 0.10, 0.08), (0.05, 0.0, -0.05)))
    assert in_box(design)
    document = design.to_json()
    assert document["kind"] == "full-factorial" and document["variables"] == ["L", "W", "x"]
    assert document["ranges"]["x"] == [-0.05, 0.05] and document["runs"] == 27


def test_full_factorial_in_four_factors() -> None:
    points = FullFactorial((L, W, X, D)).points()
    assert len(set(points)) == 81 and all(len(p) == 4 for p in points)


@pytest.mark.parametrize("k", [3, 4])
def test_box_behnken_counts_and_box(k: int) -> None:
    design = BoxBehnken((L, W, X, D)[:k])
    points = design.array()
    assert points.shape == (2 * k * (k - 1) + 1, k)
    assert len({tuple(p) for p in points}) == len(points)  # one centre run, no replicate
    assert in_box(design)
    # Edge midpoints: exactly one factor at its centre... except the centre run (all at the centre).
    centre = np.array([(f.range_m[0] + f.range_m[1]) / 2 for f in design.factors])
    at_centre = np.isclose(points, centre, rtol=0, atol=1e-12).sum(1)
    assert sorted(set(at_centre)) == [k - 2, k] and (at_centre == k).sum() == 1
    assert design.to_json()["kind"] == "box-behnken" and design.to_json()["runs"] == len(points)


@pytest.mark.parametrize("k", [2, 3, 4])
def test_central_composite_counts_and_box(k: int) -> None:
    design = CentralComposite((L, W, X, D)[:k])
    points = design.array()
    assert points.shape == (2**k + 2 * k + 1, k)
    assert len({tuple(p) for p in points}) == len(points)
    assert in_box(design)  # face-centred: alpha = 1
    # Its levels are the 3-level factorial's, to the bit: the corners and faces are factorial points.
    assert {tuple(p) for p in design.points()} <= set(FullFactorial(design.factors).points())
    if k == 2:  # face-centred over (L, W): the 3 x 3 points in another order
        assert sorted(design.points()) == sorted(Design().points())


def test_design_kinds_by_name() -> None:
    assert design_class("box-behnken") is BoxBehnken
    assert set(DESIGN_KINDS) == {"full-factorial", "box-behnken", "central-composite"}
    with pytest.raises(InvalidParameterError, match="box-behnken"):
        design_class("box-benken")


def test_default_x_range_keeps_every_corner_in_reach(arm, scene) -> None:
    from dataclasses import replace

    from pipeline.model.kinematics import reach_annulus_m
    from pipeline.model.obstacle import Obstacle
    from pipeline.motion.path import desired_path

    inner, outer = reach_annulus_m(arm.link_lengths_m)
    lo, hi = DEFAULT_RANGES_M["x"]
    for length, width, x in itertools.product(L.range_m, W.range_m, (lo, hi, 0.06, -0.06)):
        moved = replace(scene, centre_x_m=x)
        radii = np.hypot(*desired_path(Obstacle.in_scene(length, width, moved), moved).points_m.T)
        # Inside the reach at the default range; at |x| = 0.06 m the largest corner reaches the rim.
        if abs(x) < 0.06:
            assert np.all((radii > inner) & (radii < outer - 0.004))
        elif length == L.range_m[1]:
            assert radii.max() >= outer - 1e-9


@pytest.mark.parametrize(
    ("make", "needle"),
    [
        (lambda: Factor("y", (0.0, 1.0)), "one of L, W, x, d"),
        (lambda: Factor("x", (0.1, -0.1)), "min < max"),
        (lambda: Factor("x", (0.1, 0.1)), "min < max"),
        (lambda: Factor("x", (float("nan"), 0.1)), "finite"),
        (lambda: Factor("L", (-0.1, 0.2)), "> 0"),
        (lambda: FullFactorial((L, X)), "W among them"),
        (lambda: FullFactorial((L, W, X, X)), "each variable once"),
        (lambda: FullFactorial((L, W), 2), "levels"),
        (lambda: BoxBehnken((L, W)), "3 or more factors"),
    ],
)
def test_bad_designs_raise(make, needle: str) -> None:
    with pytest.raises(InvalidParameterError, match=needle):
        make()
