"""Design of experiments (pipeline.offline.doe): Table 1 order, larger designs, bad designs, run_doe
reproducible and independent of the number of worker processes, and malformed DOE files."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pipeline.exceptions import DataFileError, InvalidParameterError
from pipeline.model.arm import PlanarArm
from pipeline.model.scene import Scene
from pipeline.motion.trajectory import PARAMETER_NAMES
from pipeline.offline.coefficients import paper_data_path
from pipeline.offline.doe import Design, doe_document, load_doe, run_doe
from pipeline.offline.experiment import ExperimentResult, SolverConfig
from pipeline.offline.fitness import FitnessConfig
from pipeline.offline.pso import PsoConfig

# Table 1 of the paper: Test i at (L, W).
TABLE1 = [
    (0.30, 0.12),
    (0.25, 0.12),
    (0.20, 0.12),
    (0.30, 0.10),
    (0.25, 0.10),
    (0.20, 0.10),
    (0.30, 0.08),
    (0.25, 0.08),
    (0.20, 0.08),
]
TINY = SolverConfig(
    fitness=FitnessConfig(n_points=15, clearance_samples=31),
    pso=PsoConfig(swarm_size=16, iterations=15, restarts=1),
    verify_samples=50,
)
SEED = 6
# PSO alone (no least_squares polish): a fraction of the time, same random streams.
PSO_ONLY = SolverConfig(fitness=TINY.fitness, pso=TINY.pso, verify_samples=TINY.verify_samples, polish=False)
SMALL_DESIGN = Design(3, (0.24, 0.26), (0.095, 0.105))


def as_records(results: list[ExperimentResult]) -> list[dict]:
    """Everything deterministic about the results (wall time excluded)."""
    return [r.to_json() for r in results]


# --------------------------------------------------------------------------------------------
# Designs.


def test_paper_design_is_in_table_1_order() -> None:
    points = Design().points()
    assert len(points) == 9
    assert points == TABLE1  # exactly, not just approximately: they label the tests
    assert points[0] == (0.30, 0.12) and points[1] == (0.25, 0.12) and points[8] == (0.20, 0.08)


def test_paper_design_matches_the_paper_doe_file(table2: np.ndarray) -> None:
    doe = load_doe(paper_data_path("paper_table2_doe.json"))
    assert_allclose(np.array(Design().points()), np.c_[doe.lengths_m, doe.widths_m], rtol=0, atol=0)
    assert_allclose(np.array(Design().points()), table2[:, 8:], rtol=0, atol=0)


def test_five_levels() -> None:
    points = np.array(Design(levels=5).points())
    assert points.shape == (25, 2)
    assert len({tuple(p) for p in points}) == 25
    assert_allclose(sorted(set(points[:, 0])), np.linspace(0.20, 0.30, 5), rtol=0, atol=1e-12)
    assert_allclose(sorted(set(points[:, 1])), np.linspace(0.08, 0.12, 5), rtol=0, atol=1e-12)
    assert tuple(points[0]) == (0.30, 0.12) and tuple(points[-1]) == (0.20, 0.08)
    # W descending by rows, L descending within a row.
    assert np.all(np.diff(points[:5, 0]) < 0) and np.all(points[:5, 1] == 0.12)
    assert np.all(np.diff(points[::5, 1]) < 0)


def test_design_json() -> None:
    document = Design(4, (0.21, 0.29), (0.09, 0.11)).to_json()
    assert document["levels"] == 4
    assert document["L_range"] == [0.21, 0.29] and document["W_range"] == [0.09, 0.11]


@pytest.mark.parametrize(
    "kwargs",
    [
        {"levels": 2},
        {"levels": 1},
        {"levels": 0},
        {"levels": 3.0},
        {"length_range_m": (0.3, 0.2)},
        {"length_range_m": (0.2, 0.2)},
        {"width_range_m": (0.12, 0.08)},
        {"length_range_m": (-0.1, 0.2)},
        {"width_range_m": (0.0, 0.1)},
        {"width_range_m": (float("nan"), 0.1)},
        {"length_range_m": (0.2, float("inf"))},
    ],
)
def test_bad_designs_raise(kwargs: dict) -> None:
    with pytest.raises(InvalidParameterError):
        Design(**kwargs)


# --------------------------------------------------------------------------------------------
# run_doe.


@pytest.fixture(scope="module")
def serial(arm: PlanarArm, scene: Scene) -> list[ExperimentResult]:
    return run_doe(arm, SMALL_DESIGN, scene, TINY, seed=SEED, jobs=1)


def test_run_doe_results_in_design_order(serial: list[ExperimentResult]) -> None:
    assert [(r.length_m, r.width_m) for r in serial] == SMALL_DESIGN.points()
    for r in serial:
        assert set(r.parameters) == set(PARAMETER_NAMES)
        assert np.isfinite(r.fitness) and r.fitness >= r.tracking_fitness - 1e-15
    # Each experiment has its own stream: not all experiments find the same PSO value.
    assert len({r.pso_fitness for r in serial}) == len(serial)


def test_run_doe_does_not_depend_on_jobs(arm: PlanarArm, scene: Scene, serial: list[ExperimentResult]) -> None:
    """The same seed with 2 worker processes: the same results, polish included, bit for bit."""
    seen = []
    parallel = run_doe(arm, SMALL_DESIGN, scene, TINY, seed=SEED, jobs=2, progress=seen.append)
    assert as_records(parallel) == as_records(serial)
    assert sorted((r.length_m, r.width_m) for r in seen) == sorted(SMALL_DESIGN.points())


def test_run_doe_same_seed_twice_same_results(arm: PlanarArm, scene: Scene, serial: list[ExperimentResult]) -> None:
    seen = []
    a = run_doe(arm, SMALL_DESIGN, scene, PSO_ONLY, seed=SEED, jobs=1, progress=seen.append)
    b = run_doe(arm, SMALL_DESIGN, scene, PSO_ONLY, seed=SEED, jobs=1)
    assert as_records(a) == as_records(b)
    assert [r.solver for r in a] == ["pso"] * 9
    assert [r.length_m for r in seen] == [r.length_m for r in a]  # progress sees every result, in order
    # The same random streams as the polished run: the same PSO optimum per experiment.
    assert [r.pso_fitness for r in a] == [r.pso_fitness for r in serial]


def test_run_doe_different_seed_differs(arm: PlanarArm, scene: Scene) -> None:
    a = run_doe(arm, SMALL_DESIGN, scene, PSO_ONLY, seed=SEED, jobs=1)
    b = run_doe(arm, SMALL_DESIGN, scene, PSO_ONLY, seed=SEED + 1, jobs=1)
    assert all(x.pso_fitness != y.pso_fitness for x, y in zip(a, b, strict=True))


def test_run_doe_rejects_bad_jobs(arm: PlanarArm, scene: Scene) -> None:
    for jobs in (0, -1, 1.5):
        with pytest.raises(InvalidParameterError):
            run_doe(arm, SMALL_DESIGN, scene, TINY, seed=0, jobs=jobs)


def test_doe_document_round_trips_through_load_doe(
    arm: PlanarArm, scene: Scene, serial: list[ExperimentResult], tmp_path: Path
) -> None:
    document = doe_document(serial, SMALL_DESIGN, scene, arm, TINY, {"seed": SEED}, 1)
    path = tmp_path / "doe.json"
    path.write_text(json.dumps(document), encoding="utf-8")
    doe = load_doe(path)
    assert_allclose(doe.lengths_m, [r.length_m for r in serial], rtol=0, atol=0)
    assert_allclose(doe.widths_m, [r.width_m for r in serial], rtol=0, atol=0)
    assert_allclose(doe.parameters, [[r.parameters[n] for n in PARAMETER_NAMES] for r in serial], rtol=0, atol=1e-15)
    assert doe.scene == scene
    assert doe.link_lengths_m == arm.link_lengths_m
    assert [e["test"] for e in doe.document["experiments"]] == list(range(1, 10))


# --------------------------------------------------------------------------------------------
# Malformed DOE files.


def paper_doe_document() -> dict:
    return json.loads(paper_data_path("paper_table2_doe.json").read_text(encoding="utf-8"))


def _bad_documents() -> list[tuple[str, object]]:
    def edit(function):
        def apply():
            document = paper_doe_document()
            function(document)
            return document

        return apply

    def set_experiment(index, key, value):
        return edit(lambda d: d["experiments"][index].__setitem__(key, value))

    def set_parameter(index, name, value):
        return edit(lambda d: d["experiments"][index]["parameters"].__setitem__(name, value))

    return [
        ("wrong format", edit(lambda d: d.__setitem__("format", "twolink-coefficients/1"))),
        ("unknown family", edit(lambda d: d.__setitem__("family", "bezier"))),
        ("no experiments", edit(lambda d: d.__setitem__("experiments", []))),
        ("experiments not a list", edit(lambda d: d.__setitem__("experiments", {"1": {}}))),
        ("experiment not an object", edit(lambda d: d["experiments"].__setitem__(3, [0.25, 0.1]))),
        ("missing L", edit(lambda d: d["experiments"][2].pop("L"))),
        ("negative W", set_experiment(4, "W", -0.1)),
        ("string L", set_experiment(0, "L", "0.30")),
        ("boolean W", set_experiment(0, "W", True)),
        ("NaN parameter", set_parameter(5, "phi1", float("nan"))),
        ("string parameter", set_parameter(5, "A2", "1.4")),
        ("missing parameter", edit(lambda d: d["experiments"][7]["parameters"].pop("gamma2"))),
        ("scene not an object", edit(lambda d: d.__setitem__("scene", [0.56]))),
        ("bad scene value", edit(lambda d: d["scene"].__setitem__("speed_m_s", 0.0))),
        ("one link length", edit(lambda d: d["scene"].__setitem__("link_lengths_m", [0.3]))),
        (
            "exact-endpoints without free parameters",
            edit(lambda d: d.__setitem__("family", "exact-endpoints")),
        ),
    ]


@pytest.mark.parametrize(("label", "make"), _bad_documents(), ids=[label for label, _ in _bad_documents()])
def test_load_doe_rejects_malformed_files(tmp_path: Path, label: str, make) -> None:
    path = tmp_path / "doe.json"
    path.write_text(json.dumps(make(), allow_nan=True), encoding="utf-8")
    with pytest.raises(DataFileError) as info:
        load_doe(path)
    assert str(path) in str(info.value), label


def test_unmodified_paper_doe_loads(tmp_path: Path) -> None:
    path = tmp_path / "doe.json"
    path.write_text(json.dumps(paper_doe_document()), encoding="utf-8")
    assert load_doe(path).parameters.shape == (9, 8)


@pytest.mark.parametrize(
    ("content", "needle"), [(None, "no such file"), ("{oops", "not valid JSON"), ("[1, 2]", "list")]
)
def test_load_doe_rejects_missing_invalid_and_non_object_files(
    tmp_path: Path, content: str | None, needle: str
) -> None:
    path = tmp_path / "doe.json"
    if content is not None:
        path.write_text(content, encoding="utf-8")
    with pytest.raises(DataFileError) as info:
        load_doe(path)
    assert str(path) in str(info.value) and needle in str(info.value)
