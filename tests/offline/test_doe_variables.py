"""run_doe over (L, W, x): each run solved in its moved scene, the same results wherever they run,
and doe.json naming the variables and each run's values (read back by load_doe)."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from pipeline.io.jsonio import dumps
from pipeline.model.arm import PlanarArm
from pipeline.model.scene import Scene
from pipeline.offline.designs import CentralComposite, Factor
from pipeline.offline.doe import doe_document, doe_from_json, run_doe
from pipeline.offline.experiment import SolverConfig, solve_experiment
from pipeline.offline.fitness import FitnessConfig
from pipeline.offline.pso import PsoConfig

PSO_ONLY = SolverConfig(
    fitness=FitnessConfig(n_points=15, clearance_samples=31),
    pso=PsoConfig(swarm_size=8, iterations=5, restarts=1),
    verify_samples=50,
    polish=False,
)
DESIGN = CentralComposite((Factor("L", (0.24, 0.26)), Factor("W", (0.095, 0.105)), Factor("x", (-0.02, 0.02))))


@pytest.fixture(scope="module")
def serial(arm: PlanarArm, scene: Scene) -> list:
    return run_doe(arm, DESIGN, scene, PSO_ONLY, seed=3, jobs=1)


def test_each_run_is_solved_in_its_moved_scene(arm: PlanarArm, scene: Scene, serial: list) -> None:
    from pipeline.io.parallel import item_seeds

    assert len(serial) == 15
    streams = item_seeds(3, 15)
    for index in (0, 7, 14):
        L, W, x = DESIGN.points()[index]
        alone = solve_experiment(
            arm, L, W, replace(scene, centre_x_m=x), PSO_ONLY, np.random.default_rng(streams[index])
        )
        assert alone.to_json() == serial[index].to_json()


def test_results_do_not_depend_on_jobs(arm: PlanarArm, scene: Scene, serial: list) -> None:
    parallel = run_doe(arm, DESIGN, scene, PSO_ONLY, seed=3, jobs=2)
    assert [r.to_json() for r in parallel] == [r.to_json() for r in serial]


def test_doe_json_names_the_variables_and_reads_back(arm: PlanarArm, scene: Scene, serial: list) -> None:
    document = doe_document(serial, DESIGN, scene, arm, PSO_ONLY, {}, 1)
    assert document["variables"] == ["L", "W", "x"] and document["design"]["kind"] == "central-composite"
    assert [list(e)[:4] for e in document["experiments"][:1]] == [["test", "L", "W", "x"]]
    doe = doe_from_json(json.loads(dumps(document)), "doe.json")
    assert doe.variables.names == ("L", "W", "x")
    assert [tuple(p) for p in doe.points.tolist()] == DESIGN.points()
    assert doe.scene.centre_x_m == 0.0  # the base scene; the runs' x are in the experiments
