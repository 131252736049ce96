"""The build's printed tables (pipeline.offline.report): Eq. 9 over any basis, with R^2 and the
LOO error or n/a where the design leaves too few runs for it."""

from __future__ import annotations

import math

from pipeline.offline.report import equation9
from pipeline.offline.variables import Variables


def test_equation9_names_every_term_of_an_l_w_x_fit_and_takes_a_missing_loo() -> None:
    basis = Variables(("L", "W", "x")).basis
    ours = {"A1": tuple(float(k) for k in range(10)), "w1": tuple(0.5 * k for k in range(10))}
    quality = {"r_squared": {"A1": 0.9, "w1": 0.8}, "loo_rmse": {"A1": None, "w1": math.nan}}
    lines = equation9(ours, None, quality, basis).splitlines()
    assert lines[0].split()[2:12] == list(basis) and lines[0].split()[-2:] == ["R^2", "LOO_rmse"]
    assert [line.split()[-1] for line in lines[1:]] == ["n/a", "n/a"]
    assert lines[1].split()[:3] == ["A1", "ours", "0"] and len(lines[1].split()) == 2 + 10 + 2


def test_equation9_of_the_paper_basis_is_unchanged() -> None:
    ours = {"A1": (1.0, 2.0, 3.0, 4.0, 5.0, 6.0)}
    quality = {"r_squared": {"A1": 0.5}, "loo_rmse": {"A1": 1e-3}}
    text = equation9(ours, {"A1": (6.0, 5.0, 4.0, 3.0, 2.0, 1.0)}, quality)
    header, mine, paper = text.splitlines()
    assert header.split()[2:8] == ["1", "L", "W", "L^2", "L*W", "W^2"]
    assert mine.split()[-2:] == ["0.5000", "1.00e-03"]
    assert paper.split()[:3] == ["paper", "6", "5"]
