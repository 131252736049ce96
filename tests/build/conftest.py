"""Fixtures of the build's tests: one real DOE of the paper's design (default PSO settings),
replayed by the tests so that each build runs only the regression, the refit and a coarse map."""

from __future__ import annotations

from dataclasses import replace

import pytest

from pipeline.build import BuildConfig, doe_fit, range_stage
from pipeline.build.doe_fit import fit_doe
from pipeline.model.arm import load_planar_arm

#: A coarse range certificate for the tests: cells of 1/64, resolved to 1/32 where undecided.
COARSE = {"min_cell": 1 / 64, "boundary_cell": 1 / 32, "strip_split": 0}
#: Near-optimal cells per axis for the tests' builds (the default's 64 x 64 take about 40 s).
COARSE_CELLS = 2


@pytest.fixture(scope="session")
def doe_results() -> list:
    """The default build's DOE optima (seed 0), computed once for the session."""
    captured: list = []
    original = doe_fit.run_doe

    def recording(*args, **kwargs):
        captured.extend(original(*args, **kwargs))
        return list(captured)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(doe_fit, "run_doe", recording)
        fit = fit_doe(BuildConfig(), load_planar_arm())
    assert not fit.problems, fit.problems
    return captured


@pytest.fixture
def replayed(doe_results: list, monkeypatch: pytest.MonkeyPatch) -> list:
    """The DOE replayed (no PSO) and the range certificate coarse, for every build of the test."""
    monkeypatch.setattr(doe_fit, "run_doe", lambda *args, **kwargs: list(doe_results))
    real_default_config = range_stage.default_config
    monkeypatch.setattr(
        range_stage, "default_config", lambda *args, **kwargs: replace(real_default_config(*args, **kwargs), **COARSE)
    )
    real_cells = range_stage.near_optimal_cells

    def coarse_cells(coefficients, dynamics, limits, cells_per_axis=None, **kwargs):
        return real_cells(
            coefficients, dynamics, limits, COARSE_CELLS if cells_per_axis is None else cells_per_axis, **kwargs
        )

    monkeypatch.setattr(range_stage, "near_optimal_cells", coarse_cells)
    return doe_results
