"""Smoke test of scripts/near_optimal_soundness.py: a few obstacles per limit set, no violation,
the right counts; and a certificate with a lowered bound is caught."""

from __future__ import annotations

import importlib.util
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

_SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "near_optimal_soundness.py"


@pytest.fixture(scope="module")
def script():
    spec = importlib.util.spec_from_file_location("near_optimal_soundness", _SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_three_obstacles_per_set_no_violation(script, tmp_path, capsys):
    report = tmp_path / "audit.json"
    argv = ["--coefficients", "paper", "--n", "3", "--samples", "501", "--jobs", "1", "--json", str(report)]
    assert script.main(argv) == 0
    out = capsys.readouterr().out
    assert "total: 0 violations, 0 errors" in out
    data = json.loads(report.read_text())
    assert [s["set"] for s in data["summaries"]] == ["a", "b", "c"]
    for summary in data["summaries"]:
        assert summary["obstacles"] == 3
        assert summary["audited"] + summary["refused"] == 3 and summary["errors"] == 0
        assert summary["violations"] == 0
        for ratios in summary.get("ratios", {}).values():
            assert 0.0 < ratios["to_bound_max"] <= 1.0 + 1e-12 and ratios["to_limit_max"] <= 1.0 + 1e-12
    assert data["violations"] == []


def test_a_lowered_bound_is_a_violation(script):
    from pipeline import generate, load_coefficients
    from pipeline.motion.near_optimal import near_optimal_timing
    from pipeline.online.arm_check import arm_for
    from pipeline.online.execution import dynamics_of

    coefficients = load_coefficients("paper", region_map=None)
    arm = arm_for(coefficients)
    dynamics = dynamics_of(arm)
    limits = script.limit_sets(arm)["a"]
    result = near_optimal_timing(generate(coefficients, 0.25, 0.1, region_map=None).trajectory, dynamics, limits)
    certificate = result.certificate
    rng = np.random.default_rng(0)
    honest = script._audit(result.executed, certificate, limits, dynamics, arm, 501, 2, rng)
    assert honest["violations"] == []
    lowered = replace(certificate, jerk_bound_rad_s3=0.5 * np.asarray(certificate.jerk_bound_rad_s3))
    found = script._audit(result.executed, lowered, limits, dynamics, arm, 501, 2, rng)["violations"]
    assert {"above bound", "mean value"} <= {v["kind"] for v in found}
    assert {v["quantity"] for v in found if v["kind"] == "above bound"} == {"jerk1", "jerk2"}
