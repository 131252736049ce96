"""The build's printed tables (pipeline.offline.report): Eq. 9 over any basis, with R^2 and the
LOO error or n/a where the design leaves too few runs for it."""

from __future__ import annotations

import math

from pipeline.offline.report import equation9, table2
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


def test_table2_shows_each_runs_extra_variables() -> None:
    """A DOE over (L, W, x) prints each run's x beside L and W; the (L, W) table has no such column."""
    names = ("A1", "w1", "phi1", "gamma1", "A2", "w2", "phi2", "gamma2")
    row = {
        "parameters": dict.fromkeys(names, 0.5),
        "L": 0.3,
        "W": 0.12,
        "x": -0.03,
        "fitness": 0.05,
        "clearance_m": 0.0119,
        "endpoint_error_start_m": 0.0078,
        "endpoint_error_end_m": 0.0051,
    }
    header, line = table2([row], None, ("x",)).splitlines()
    assert header.split()[10:13] == ["L", "W", "x"]
    assert line.split()[10:13] == ["0.300", "0.120", "-0.030"]
    plain_header, plain = table2([row], None).splitlines()
    assert plain_header.split()[10:13] == ["L", "W", "fitness"] and "-0.030" not in plain
