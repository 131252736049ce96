"""Loading coefficients with their region map (:func:`pipeline.load_coefficients`), and the online
step without Pinocchio or Coal."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pytest

import pipeline
from pipeline import (
    InvalidParameterError,
    RegionMapMismatchError,
    RegionMapMismatchWarning,
    generate,
    generate_batch,
    load_coefficients,
)
from pipeline.certify.cell_timings import near_optimal_cells
from pipeline.certify.map_files import save_region_map, table_name
from pipeline.certify.near_optimal_cells import cells_files
from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
from pipeline.certify.region_map import DEFAULT_MAP_NAME
from pipeline.offline.coefficients import paper_data_path
from pipeline.online.query_state import state_of

COARSE = RangeCertificateConfig(min_cell=1 / 16, boundary_cell=1 / 8, strip_split=0)


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder as a build leaves it: coefficients.json (the paper's Eq. 9 as a file) and the
    (coarse) region map of exactly those bytes beside it."""
    folder = tmp_path_factory.mktemp("results")
    shutil.copyfile(paper_data_path("paper_eq9_coefficients.json"), folder / "coefficients.json")
    coefficients = load_coefficients(folder / "coefficients.json")
    assert coefficients.region_map is None
    save_region_map(certify_range(coefficients, COARSE), folder / DEFAULT_MAP_NAME)
    return folder


def test_the_map_beside_is_attached_and_answers_carry_its_bounds(built: Path) -> None:
    coefficients = load_coefficients(built / "coefficients.json")
    assert coefficients.region_map is not None and coefficients.region_map.belongs_to(coefficients)
    answer = generate(coefficients, 0.27, 0.09)
    assert answer.certificate_source == "range"
    cell = coefficients.region_map.cell_at(0.27, 0.09)
    assert answer.certified_clearance_m == cell.clearance_bound_m
    assert answer.endpoint_error_bound_m == cell.endpoint_bound_m
    batch = generate_batch(coefficients, [0.27, 0.21], [0.09, 0.11])
    assert batch.certified_clearance_m[0] == cell.clearance_bound_m
    assert generate(coefficients, 0.27, 0.09, region_map=None).certificate_source is None


def test_region_map_none_skips_it_and_a_path_names_another(built: Path, tmp_path: Path) -> None:
    assert load_coefficients(built / "coefficients.json", region_map=None).region_map is None
    elsewhere = tmp_path / "my_map.json"
    shutil.copyfile(built / DEFAULT_MAP_NAME, elsewhere)
    shutil.copyfile(built / table_name(DEFAULT_MAP_NAME), tmp_path / table_name(DEFAULT_MAP_NAME))
    named = load_coefficients(built / "coefficients.json", region_map=elsewhere)
    assert named.region_map is not None
    assert named.region_map.coefficients_sha256 == named.source_sha256
    again = load_coefficients(built / "coefficients.json", region_map=named.region_map)
    assert again.region_map is named.region_map


def test_a_map_of_other_coefficients_beside_warns_and_is_not_attached(built: Path, tmp_path: Path) -> None:
    document = json.loads((built / "coefficients.json").read_text())
    document["note"] = "other bytes, other coefficients as far as the map knows"
    (tmp_path / "coefficients.json").write_text(json.dumps(document), encoding="utf-8")
    for name in (DEFAULT_MAP_NAME, table_name(DEFAULT_MAP_NAME)):
        shutil.copyfile(built / name, tmp_path / name)
    with pytest.warns(RegionMapMismatchWarning, match="not attached"):
        coefficients = load_coefficients(tmp_path / "coefficients.json")
    assert coefficients.region_map is None
    assert generate(coefficients, 0.27, 0.09).certificate_source is None
    with pytest.raises(RegionMapMismatchError):  # named explicitly: refused
        load_coefficients(tmp_path / "coefficients.json", region_map=tmp_path / DEFAULT_MAP_NAME)


def test_a_matching_map_loads_silently(built: Path) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_coefficients(built / "coefficients.json")


@pytest.mark.parametrize("bad", [42, None, b"coefficients.json", 0.5])
def test_a_source_that_is_not_a_path_is_refused(bad: object) -> None:
    with pytest.raises(InvalidParameterError, match="coefficients") as info:
        load_coefficients(bad)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("bad", [42, "beside", object()])
def test_a_region_map_argument_of_another_kind_is_refused(built: Path, bad: object) -> None:
    if bad == "beside":  # a string is a path: one that does not exist
        with pytest.raises(pipeline.DataFileError):
            load_coefficients(built / "coefficients.json", region_map=bad)
        return
    with pytest.raises(InvalidParameterError, match="region_map"):
        load_coefficients(built / "coefficients.json", region_map=bad)


def test_the_online_step_needs_neither_pinocchio_nor_coal(built: Path, tmp_path: Path) -> None:
    """With ``coal`` and ``pinocchio`` unimportable: import pipeline, load the coefficients and their
    map, generate one and many answers with the map's bounds."""
    code = textwrap.dedent(
        f"""
        import sys
        sys.modules["coal"] = None  # import coal -> ImportError
        sys.modules["pinocchio"] = None
        sys.modules["hppfcl"] = None
        import numpy as np
        from pipeline import generate, generate_batch, load_coefficients

        coefficients = load_coefficients({str(built / "coefficients.json")!r})
        answer = generate(coefficients, 0.27, 0.09)
        assert answer.certificate_source == "range", answer.certificate_source
        assert answer.certified_clearance_m == coefficients.region_map.cell_at(0.27, 0.09).clearance_bound_m
        batch = generate_batch(coefficients, np.array([0.22, 0.27]), np.array([0.1, 0.09]))
        assert np.all(np.isfinite(batch.certified_clearance_m))
        heavy = sorted(m for m in sys.modules if m.split(".")[0] in ("coal", "pinocchio") and sys.modules[m])
        print(answer.certified_clearance_m, heavy)
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=tmp_path, env=dict(os.environ)
    )
    assert done.returncode == 0, done.stderr
    bound, heavy = done.stdout.split(" ", 1)
    cell = load_coefficients(built / "coefficients.json").region_map.cell_at(0.27, 0.09)
    assert float(bound) == cell.clearance_bound_m
    assert heavy.strip() == "[]"


def test_loading_cells_leaves_the_builds_machinery_out(built: Path, tmp_path: Path) -> None:
    """A results folder with near-optimal cells beside its map: ``pipeline.load`` attaches the
    cells, and neither their certification nor the worker pools it runs on are imported."""
    folder = tmp_path / "results"
    shutil.copytree(built, folder)
    coefficients = load_coefficients(folder / "coefficients.json")
    state = state_of(coefficients)
    cells = near_optimal_cells(coefficients, state.dynamics, state.limits.with_servo_defaults(), cells_per_axis=2)
    for name, data in cells_files(cells).items():
        (folder / name).write_bytes(data)
    build_only = ("pipeline.certify.cell_timings", "pipeline.certify.execution_range", "pipeline.io.executor")
    code = (
        f"import sys, pipeline\ng = pipeline.load({str(folder)!r})\n"
        "print(g.coefficients.region_map.near_optimal_cells is not None, "
        f"sorted(m for m in {build_only!r} if m in sys.modules))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "True []"


def test_the_heavy_names_load_on_first_use() -> None:
    code = (
        "import sys\nimport pipeline\n"
        "assert 'pinocchio' not in sys.modules and 'coal' not in sys.modules\n"
        "pipeline.load_planar_arm\nassert 'pinocchio' in sys.modules\n"
        "assert set(pipeline.__all__) <= set(dir(pipeline))\n"
        "print(sorted(n for n in pipeline.__all__ if getattr(pipeline, n) is None))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"
    with pytest.raises(AttributeError, match="no_such_name"):
        pipeline.no_such_name  # noqa: B018


def test_generate_refuses_what_is_not_coefficients(built: Path) -> None:
    for bad in (None, str(built / "coefficients.json"), 42, {"L": 1}):
        with pytest.raises(InvalidParameterError, match="coefficients") as info:
            generate(bad, 0.27, 0.09)
        assert "load_coefficients" in str(info.value) and "\n" not in str(info.value)
        with pytest.raises(InvalidParameterError, match="coefficients"):
            generate_batch(bad, [0.27], [0.09])
    with pytest.raises(InvalidParameterError, match="region_map"):
        generate(load_coefficients(built / "coefficients.json"), 0.27, 0.09, region_map="map.json")


def test_generate_batch_refuses_two_dimensional_input(built: Path) -> None:
    coefficients = load_coefficients(built / "coefficients.json")
    L, W = np.meshgrid(np.linspace(0.2, 0.3, 3), np.linspace(0.08, 0.12, 4))
    with pytest.raises(InvalidParameterError, match="one-dimensional") as info:
        generate_batch(coefficients, L, W)
    assert "ravel" in str(info.value)
    flat = generate_batch(coefficients, L.ravel(), W.ravel())
    assert flat.parameters.shape == (12, 8)
    one = generate_batch(coefficients, 0.27, 0.09)  # a scalar is one obstacle
    assert one.parameters.shape == (1, 8)
