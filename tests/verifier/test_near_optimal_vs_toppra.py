"""Smoke test of scripts/near_optimal_vs_toppra.py: its main on 2 obstacles per limit set, TOPP-RA at
100 gridpoints, prints the tables, writes the JSON and exits 0; bad input exits 2."""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import pytest

pytest.importorskip("toppra")

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "near_optimal_vs_toppra.py"


def _script():
    spec = importlib.util.spec_from_file_location("near_optimal_vs_toppra", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_main_on_two_obstacles_prints_the_tables_and_writes_the_json(tmp_path: Path, capsys) -> None:
    out = tmp_path / "out.json"
    argv = ["--coefficients", "paper", "--n", "2", "--gridpoints", "100", "--json", str(out)]
    assert _script().main(argv) == 0
    printed = capsys.readouterr().out
    for text in (
        "T'/T_TOPP-RA with the default jerk limit",
        "jerk limit of 50 rad/s^3",
        "jerk limit of 25 rad/s^3",
        "(a) URDF limits + 5 rad/s^2",
        "(b) speed 0.3 rad/s + 5 rad/s^2",
        "(c) effort 0.05 N m + 5 rad/s^2",
        "TOPP-RA's own largest relative excess",
        f"wrote {out}",
    ):
        assert text in printed, text
    data = json.loads(out.read_text())
    rows = data["rows"]
    assert [(r["set"], r["limits"]["jerk_rad_s3"][0]) for r in rows] == [
        (key, jerk) for key in "abc" for jerk in (100.0, 50.0, 25.0)
    ]
    assert data["toppra"]["gridpoints"] == 100 and len(data["obstacles_m"]) == 2
    for row in rows:
        assert row["obstacles"] == 2 and row["paths"] + sum(row["refusals"].values()) + len(row["toppra_failures"]) == 2
        assert len(row["ratios"]) == row["paths"]
        assert all(math.isfinite(r) and r > 0.0 for r in row["ratios"])
        assert row["limits"]["acceleration_rad_s2"] == [5.0, 5.0]
    default = {r["set"]: r for r in rows if r["jerk"] == "default"}
    assert default["b"]["limits"]["velocity_rad_s"] == [0.3, 0.3]
    assert default["c"]["limits"]["effort_n_m"] == [0.05, 0.05]
    for row in default.values():
        assert row["paths"] == 2 and all(v >= 0.0 for v in row["toppra_excess_max"].values())


@pytest.mark.parametrize(
    "argv", [["--n", "0"], ["--gridpoints", "1"], ["--jerk-limits", "0"], ["--acceleration-limit", "nan"]]
)
def test_bad_input_exits_2(argv: list[str], capsys) -> None:
    with pytest.raises(SystemExit) as info:
        _script().main(argv)
    assert info.value.code == 2 and "Traceback" not in capsys.readouterr().err


def test_missing_coefficients_exit_2(capsys) -> None:
    assert _script().main(["--coefficients", "no/such/coefficients.json", "--n", "1"]) == 2
    assert "near_optimal_vs_toppra:" in capsys.readouterr().err
