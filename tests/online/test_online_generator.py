"""``pipeline.load`` and :class:`OnlineGenerator`: one object per set of coefficients whose methods
equal the online functions on the same coefficients, sharing one query state; the arm, its
limits and its dynamics are loaded on first use; a folder, a file and "paper" load; bad sources
are refused with the value named."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_array_equal

import pipeline
from pipeline.certify.map_files import save_region_map
from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
from pipeline.certify.region_map import DEFAULT_MAP_NAME
from pipeline.exceptions import DataFileError, InvalidParameterError
from pipeline.model.arm import DEFAULT_URDF, load_planar_arm
from pipeline.model.dynamics import identify_dynamics
from pipeline.offline.coefficients import paper_data_path
from pipeline.online.online_generator import OnlineGenerator, load
from pipeline.online.query_state import state_of

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A results folder: the paper's Eq. 9 as coefficients.json with a coarse region map beside."""
    folder = tmp_path_factory.mktemp("results")
    shutil.copyfile(paper_data_path("paper_eq9_coefficients.json"), folder / "coefficients.json")
    coefficients = pipeline.load_coefficients(folder / "coefficients.json")
    config = RangeCertificateConfig(min_cell=1 / 8, boundary_cell=1 / 4, strip_split=0)
    save_region_map(certify_range(coefficients, config), folder / DEFAULT_MAP_NAME)
    return folder


def test_a_folder_and_its_file_load_the_same_coefficients_with_the_map(results: Path) -> None:
    by_folder, by_file = load(results), load(results / "coefficients.json")
    assert pipeline.load is load and isinstance(by_folder, pipeline.OnlineGenerator)
    for g in (by_folder, by_file):
        assert g.region_map is not None and g.region_map.belongs_to(g.coefficients)
    assert by_folder.coefficients.source_sha256 == by_file.coefficients.source_sha256
    assert "a region map" in repr(by_folder) and "(L, W)" in repr(by_folder)
    assert load("paper").region_map is None


@pytest.mark.parametrize(("L", "W"), [(0.25, 0.1), (0.27, 0.09), (0.21, 0.115)])
def test_the_methods_are_the_functions_on_the_same_coefficients(results: Path, L: float, W: float) -> None:
    g = load(results)
    ours, theirs = g(L, W), pipeline.generate(g.coefficients, L, W)
    assert ours.trajectory.parameters == theirs.trajectory.parameters and ours.duration_s == theirs.duration_s
    assert ours.certified_clearance_m == theirs.certified_clearance_m is not None
    lengths, widths = np.array([L, 0.24]), np.array([W, 0.1])
    batch, function_batch = g.batch(lengths, widths), pipeline.generate_batch(g.coefficients, lengths, widths)
    assert_array_equal(batch.parameters, function_batch.parameters)
    with pytest.raises(InvalidParameterError) as method_error:  # this map has no execution bounds
        g.execution_batch(batch)
    with pytest.raises(InvalidParameterError) as function_error:
        pipeline.execution_batch(g.coefficients, batch)
    assert str(method_error.value) == str(function_error.value)


def test_the_state_is_shared_and_the_arm_is_loaded_on_first_use(results: Path) -> None:
    g = load(results)
    state = state_of(g.coefficients)
    g(0.25, 0.1)
    assert "arm" not in state.__dict__ and "dynamics" not in state.__dict__  # a query needs neither
    assert g.arm is state.arm is g.arm  # loaded once
    assert g.arm.link_lengths_m == load_planar_arm(DEFAULT_URDF).link_lengths_m
    assert g.limits is state.limits and g.limits.velocity_rad_s == g.arm.velocity_limits_rad_s
    assert g.dynamics is g.arm.derived(identify_dynamics)
    certified = g.certified(0.25, 0.1, timing=pipeline.NEAR_OPTIMAL)
    function = pipeline.generate_certified(g.coefficients, 0.25, 0.1, timing=pipeline.NEAR_OPTIMAL)
    assert certified.duration_s == function.duration_s and certified.execution.limits == g.limits.with_servo_defaults()


@pytest.mark.parametrize("source", [3, None, b"results", ["results"]])
def test_a_source_that_is_not_a_path_is_refused(source: object) -> None:
    with pytest.raises(InvalidParameterError, match="source"):
        load(source)


def test_a_folder_without_coefficients_is_refused(tmp_path: Path) -> None:
    with pytest.raises(DataFileError, match=r"coefficients\.json"):
        load(tmp_path)


def test_an_online_generator_needs_coefficients() -> None:
    with pytest.raises(InvalidParameterError, match="coefficients"):
        OnlineGenerator("results")


def test_load_and_a_query_need_neither_pinocchio_nor_coal(results: Path) -> None:
    """``pipeline.load`` and ``g(L, W)`` with ``coal`` and ``pinocchio`` unimportable (the online step
    needs NumPy and Numba only); the certifying methods load them on first use."""
    code = (
        "import sys\n"
        "sys.modules['coal'] = None\n"
        "sys.modules['pinocchio'] = None\n"
        "import pipeline\n"
        f"g = pipeline.load({str(results)!r})\n"
        "answer = g(0.25, 0.1)\n"
        "assert answer.certified_clearance_m is not None\n"
        "assert g.batch([0.25, 0.22], [0.1, 0.11]).parameters.shape == (2, 8)\n"
        "assert not any(name.split('.')[0] in ('coal', 'pinocchio') and sys.modules[name] for name in sys.modules)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert done.returncode == 0, done.stderr
