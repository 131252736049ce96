"""The benchmark's build-time line (verify.benchmark.methods.read_build_timing, report): the total
and the stages of build_timing.json, and an older file's whole-build total read from its keys."""

from __future__ import annotations

import math
from pathlib import Path

from pipeline.io.jsonio import write_json_atomic
from verify.benchmark.methods import read_build_timing
from verify.benchmark.report import _rate_lines

EXPERIMENTS = [{"test": 1, "seconds": 5.0}, {"test": 2, "seconds": 7.0}]


class _Report:
    """The part of a BenchReport that the build-time line reads."""

    def __init__(self, info: dict) -> None:
        self.build = {"file": info}
        self.sweep = None


def _line(info: dict) -> str:
    (line,) = [line for line in _rate_lines(_Report(info)) if line.startswith("Build time")]
    return line


def test_a_timing_file_gives_its_total_and_stages(tmp_path: Path) -> None:
    path = tmp_path / "build_timing.json"
    stages = {"checks": 1.0, "doe": 20.0, "regression": 0.5, "range_certificate": 30.0, "writing": 0.1, "other": 0.4}
    document = {"total_s": 52.0, "stages_s": stages, "jobs": 2, "experiments": EXPERIMENTS, "coal_queries": 1000}
    write_json_atomic(path, document)
    info = read_build_timing(path)
    assert info["total_s"] == 52.0 and info["stages_s"] == stages and not info["older_format"]
    line = _line(info)
    assert line.startswith(f"Build time ({path}): 52.0 s wall in all (checks 1.0 s, DOE 20.0 s, regression 0.5 s, ")
    assert "range certificate 30.0 s, writing 0.1 s, other 0.4 s) for 2 experiments" in line


def test_an_older_timing_file_gives_the_whole_builds_total(tmp_path: Path) -> None:
    path = tmp_path / "build_timing.json"
    older = {"doe_s": 22.1, "regression_s": 0.3, "total_s": 23.0, "jobs": 2, "experiments": EXPERIMENTS}
    older |= {"clearance_refit_s": 33.0, "range_certificate_s": 37.5, "execution_bounds_s": 9.3}
    older |= {"total_with_range_certificate_s": 102.8, "coal_queries": 1000}
    write_json_atomic(path, older)
    info = read_build_timing(path)
    assert info["total_s"] == 102.8 and info["older_format"]
    stages = ["doe", "regression", "clearance_refit", "range_certificate", "execution_bounds", "other"]
    assert list(info["stages_s"]) == stages
    assert math.isclose(sum(info["stages_s"].values()), 102.8, rel_tol=1e-12)
    older_line = f"Build time ({path}, an older file: no writing stage): 102.8 s wall in all (DOE 22.1 s"
    assert _line(info).startswith(older_line)
    del older["total_with_range_certificate_s"]  # a build without a range map: its total_s was the whole build
    for key in ("clearance_refit_s", "range_certificate_s", "execution_bounds_s"):
        del older[key]
    write_json_atomic(path, older)
    info = read_build_timing(path)
    assert info["total_s"] == 23.0 and math.isclose(info["stages_s"]["other"], 0.6, rel_tol=1e-9)
