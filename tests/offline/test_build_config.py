"""The build as a library (:func:`pipeline.offline.build.run_build`) and its convergence check:
the configuration is validated on construction with the command-line option in the message,
a build that did not converge writes nothing and says which experiments failed (exit 1 on
the command line), ``--allow-unconverged`` writes marked files that warn when loaded."""

from __future__ import annotations

import dataclasses
import json
import os
import warnings
from pathlib import Path

import numpy as np
import pytest

from pipeline import load_coefficients
from pipeline.build import BuildConfig, run_build
from pipeline.build import doe_fit as build_library
from pipeline.build import run as build_run
from pipeline.build.range_stage import CertifiedCoefficients
from pipeline.commands import build, regress
from pipeline.exceptions import (
    BuildNotConvergedError,
    InfeasibleSceneError,
    InvalidParameterError,
    UnconvergedCoefficientsWarning,
)
from pipeline.io import file_set
from pipeline.model.scene import Scene
from pipeline.motion.families import EXACT_ENDPOINTS, PAPER
from pipeline.motion.trajectory import PARAMETER_NAMES
from pipeline.offline.coefficients import paper_data_path
from pipeline.offline.convergence import (
    ConvergenceCriteria,
    end_pose_collisions,
    experiment_problems,
    grid_problems,
    regression_collisions,
    regression_problems,
)
from pipeline.offline.doe import load_doe
from pipeline.offline.endpoint_regression import EndpointConstraint
from pipeline.offline.experiment import ExperimentResult
from pipeline.offline.fitness import FitnessConfig

TINY = {"swarm_size": 8, "iterations": 5, "restarts": 1, "endpoint_tolerance_m": None}
TINY_ARGV = ["--levels", "3", "--swarm-size", "8", "--iterations", "5", "--restarts", "1", "--plain", "--quiet"]


@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """One tiny build (it does not converge: optima this rough miss P1/P5 by centimetres)."""
    out = tmp_path_factory.mktemp("tiny") / "out"
    with pytest.raises(BuildNotConvergedError) as info:
        run_build(BuildConfig.from_settings(out_folder=out, **TINY))
    return {"out": out, "error": info.value, "result": info.value.result}


# --------------------------------------------------------------------------------------------
# BuildConfig


def test_defaults_are_the_command_lines() -> None:
    """The command line's defaults are the library's: both use every CPU (the files do not depend
    on it), the library by ``jobs=0``, the command by resolving ``--jobs 0``; both certify the range."""
    args = build.parser().parse_args([])
    assert build.config_from_args(args) == BuildConfig().with_settings(jobs=os.cpu_count() or 1)
    assert BuildConfig().execution.jobs == 0 and BuildConfig().execution.workers == (os.cpu_count() or 1)
    assert BuildConfig.from_settings(jobs=3).execution.workers == 3
    assert BuildConfig().range_map.enabled and BuildConfig().certifiable_refit


@pytest.mark.parametrize(
    ("changes", "option"),
    [
        ({"seed": -1}, "--seed"),
        ({"seed": 1.5}, "--seed"),
        ({"jobs": -1}, "--jobs"),
        ({"jobs": 1.5}, "--jobs"),
        ({"clearance_rounds": -1}, "--clearance-rounds"),
        ({"range_map": "yes"}, "--no-range-map"),
        ({"levels": 2}, "--levels"),
        ({"length_range_m": (0.3, 0.2)}, "--L-range"),
        ({"width_range_m": (float("nan"), 0.1)}, "--W-range"),
        ({"width_range_m": (0.1,)}, "--W-range"),
        ({"family": "spline"}, "--family"),
        ({"swarm_size": 1}, "--swarm-size"),
        ({"iterations": 0}, "--iterations"),
        ({"restarts": 0}, "--restarts"),
        ({"n_points": 3}, "--n-points"),
        ({"endpoint_weight": -1.0}, "--endpoint-weight"),
        ({"penalty_weight": float("inf")}, "--penalty-weight"),
        ({"margin_buffer_m": -0.001}, "--margin-buffer"),
        ({"endpoint_tolerance_m": 0.0}, "--endpoint-tolerance"),
        ({"doe_endpoint_error_max_m": float("nan")}, "--max-doe-endpoint-error"),
        ({"scene": {"top_y_m": 0.54}}, "--scene"),
        ({"polish": "yes"}, "--no-polish"),
    ],
)
def test_bad_values_are_refused_naming_the_option(changes: dict, option: str) -> None:
    with pytest.raises(InvalidParameterError) as info:
        BuildConfig.from_settings(**changes)
    assert info.value.name == option
    assert str(info.value).startswith(f"{option} = ")
    assert "\n" not in str(info.value)


def test_family_by_name_and_paths_as_strings() -> None:
    config = BuildConfig.from_settings(
        family="exact-endpoints", out_folder="somewhere", urdf_path=str(BuildConfig().urdf_path)
    )
    assert config.family is EXACT_ENDPOINTS and config.out_folder == Path("somewhere")
    assert config.endpoint_constraint() is None  # exact by construction: nothing to constrain
    assert BuildConfig().endpoint_constraint().tolerance_m == 0.002
    assert BuildConfig.from_settings(endpoint_tolerance_m=None).endpoint_constraint() is None
    assert BuildConfig.from_settings(urdf_path=None) == BuildConfig()


# --------------------------------------------------------------------------------------------
# Convergence


def _result(clearance_m: float, start_m: float, end_m: float, family=PAPER) -> ExperimentResult:
    parameters = dict(zip(("A1", "w1", "phi1", "gamma1", "A2", "w2", "phi2", "gamma2"), [0.0] * 8, strict=True))
    return ExperimentResult(
        length_m=0.25,
        width_m=0.1,
        family=family,
        parameters=parameters,
        free_parameters=parameters,
        fitness=0.0,
        tracking_fitness=0.0,
        clearance_m=clearance_m,
        endpoint_error_start_m=start_m,
        endpoint_error_end_m=end_m,
        duration_s=3.0,
        solver="pso",
        pso_fitness=0.0,
        objective_evaluations=0,
        coal_queries=0,
        seconds=0.0,
    )


def test_thresholds_pass_the_default_build_and_name_what_failed(arm) -> None:
    """Optima like the default build's (clearance >= 11.8 mm, endpoint errors <= 6.2 mm) pass with
    room; a margin miss and a 120 mm endpoint miss are named with their numbers and Test numbers."""
    results = [_result(0.0118, 0.0028, 0.0062), _result(0.0099, 0.001, 0.001), _result(0.02, 0.12, 0.003)]
    problems = experiment_problems(results, arm, Scene(), FitnessConfig(), ConvergenceCriteria())
    assert [p.test for p in problems] == [2, 3]
    assert str(problems[0]) == "Test 2 (L = 0.250 m, W = 0.100 m): clearance 9.90 mm < the margin 10.00 mm"
    assert "endpoint errors 120.0 mm at P1 and 3.0 mm at P5 > 50.0 mm" in str(problems[1])
    assert not experiment_problems(results[:1], arm, Scene(), FitnessConfig(), ConvergenceCriteria(0.0062))
    assert experiment_problems(results[:1], arm, Scene(), FitnessConfig(), ConvergenceCriteria(0.006))


def test_a_family_pinned_at_its_end_poses_is_held_to_their_clearance(arm, monkeypatch) -> None:
    """Exact endpoints: no trajectory can be clearer than its end poses, so an optimum at
    the pose's clearance (below the margin) converged; one below it did not."""
    monkeypatch.setattr("pipeline.offline.convergence.end_pose_clearance_m", lambda *args: 0.008)
    criteria, scene = ConvergenceCriteria(), Scene()
    assert not experiment_problems([_result(0.008, 0, 0, EXACT_ENDPOINTS)], arm, scene, FitnessConfig(), criteria)
    (problem,) = experiment_problems([_result(0.007, 0, 0, EXACT_ENDPOINTS)], arm, scene, FitnessConfig(), criteria)
    assert "clearance 7.00 mm < the end poses' clearance 8.00 mm" in str(problem)
    # The paper family does not pin its end poses: the margin applies.
    assert experiment_problems([_result(0.008, 0, 0, PAPER)], arm, scene, FitnessConfig(), criteria)


def test_regression_problems() -> None:
    report = {"tolerance_m": 0.002, "grid_points": 21, "grid_endpoint_error_max_m": 0.002 + 2e-16, "converged": True}
    assert regression_problems({"endpoint_constraint": report}) == []
    assert regression_problems({"regression": "least squares"}) == []
    (problem,) = regression_problems({"endpoint_constraint": {**report, "grid_endpoint_error_max_m": 0.675}})
    assert str(problem) == "regression: endpoint error on the 21x21 grid 675.0000 mm > tolerance 2.00 mm"
    checked = {**report, "check_grid_points": 101, "check_grid_endpoint_error_max_m": 0.0020045}
    (problem,) = regression_problems({"endpoint_constraint": checked})
    assert str(problem) == "regression: endpoint error on the 101x101 grid 2.0045 mm > tolerance 2.00 mm"
    assert regression_problems({"endpoint_constraint": {**checked, "check_grid_endpoint_error_max_m": 0.00197}}) == []
    (problem,) = regression_problems({"endpoint_constraint": {**report, "converged": False}})
    assert "SLSQP did not converge" in str(problem)


# --------------------------------------------------------------------------------------------
# run_build


def test_an_unconverged_build_writes_nothing_and_names_the_experiments(tiny: dict) -> None:
    assert not tiny["out"].exists()  # not even the folder
    error, result = tiny["error"], tiny["result"]
    assert result is not None and not result.converged and result.written == ()
    assert error.problems == list(result.problems)
    experiments = [p for p in error.problems if p.test is not None]
    assert experiments and all(1 <= p.test <= 9 for p in experiments)
    assert all(str(p).startswith("regression: ") for p in error.problems if p.test is None)
    assert "\n" not in str(error) and "Test " in str(error)


def test_allow_unconverged_writes_marked_files_that_warn(tiny: dict, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setattr(build_library, "run_doe", lambda *args, **kwargs: list(tiny["result"].experiments))
    result = run_build(BuildConfig.from_settings(out_folder=tmp_path, allow_unconverged=True, **TINY))
    assert [written.path.name for written in result.written] == ["doe.json", "coefficients.json", "build_timing.json"]
    document = json.loads((tmp_path / "coefficients.json").read_text())
    reasons = [str(p) for p in tiny["error"].problems]
    assert document["converged"] is False and document["unconverged_reasons"] == reasons
    assert json.loads((tmp_path / "doe.json").read_text())["converged"] is False
    with pytest.warns(UnconvergedCoefficientsWarning, match="did not converge"):
        coefficients = load_coefficients(tmp_path / "coefficients.json")
    assert not coefficients.converged and coefficients.unconverged_reasons == tuple(reasons)


def _table2_optima(tiny: dict) -> list[ExperimentResult]:
    """The tiny build's experiments with the paper's Table 2 parameters, scored as meeting the
    thresholds (Eq. 9, their regression, is collision-free over the range)."""
    table2 = load_doe(paper_data_path("paper_table2_doe.json")).parameters
    return [
        dataclasses.replace(
            r,
            parameters=dict(zip(PARAMETER_NAMES, row, strict=True)),
            free_parameters=dict(zip(PARAMETER_NAMES, row, strict=True)),
            clearance_m=0.0101,
            endpoint_error_start_m=0.008,
            endpoint_error_end_m=0.008,
        )
        for r, row in zip(tiny["result"].experiments, table2, strict=True)
    ]


def test_a_converged_build_carries_no_mark(tiny: dict, tmp_path: Path, monkeypatch) -> None:
    """Optima that meet the thresholds (the paper's Table 2, whose Eq. 9 is collision-free over
    the range) give a converged build: no mark, no warning (so the default build's files stay
    byte-identical to those written before the check existed)."""
    good = _table2_optima(tiny)
    monkeypatch.setattr(build_library, "run_doe", lambda *args, **kwargs: good)
    result = run_build(BuildConfig.from_settings(out_folder=tmp_path, range_map=False, **TINY))  # the mark, not the map
    assert result.converged
    document = json.loads((tmp_path / "coefficients.json").read_text())
    assert "converged" not in document and "unconverged_reasons" not in document
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert load_coefficients(tmp_path / "coefficients.json").converged
    # The same optima, one of them 1 um short of the margin: not converged.
    good[4] = dataclasses.replace(good[4], clearance_m=0.01 - 2e-6)
    with pytest.raises(BuildNotConvergedError, match=r"Test 5 \(L = 0.250 m, W = 0.100 m\): clearance 10.00 mm"):
        run_build(BuildConfig.from_settings(out_folder=tmp_path / "second", **TINY))


def test_regressed_trajectories_that_collide_are_a_problem(arm) -> None:
    """The sampled check after the regression: coefficients that hold the arm upright through
    the obstacle (centred on x = 0, y in [d - W, d]) are named; pointing down, they are not."""
    grid = grid_problems(arm, Scene(), FitnessConfig(), PAPER, (0.2, 0.3), (0.08, 0.12), grid_points=3)
    # theta1 = pi/2 (link 1 along +y), theta2 = 0: the arm stands straight up through y = 0.65 m > d.
    upright = np.array([0.0, 1.0, 0.0, np.pi / 2, 0.0, 1.0, 0.0, 0.0])
    (problem,) = regression_collisions(lambda L, W: upright, grid)
    assert str(problem).startswith("regression: its trajectories collide at 9 of 9 grid obstacles")
    # Pointing away from the obstacle (down): no collision anywhere.
    assert regression_collisions(lambda L, W: upright * np.array([1, 1, 1, -1, 1, 1, 1, 1]), grid) == []


def test_the_collision_check_judges_the_certifiable_regressions_coefficients(
    tiny: dict, tmp_path: Path, monkeypatch
) -> None:
    """Where the certifiable regression runs, its coefficients are written, and the sampled
    collision check waits for it and judges them: the first fit is not checked (an obstacle it
    crosses is the refit's to move), and a refit whose trajectories collide is refused, naming
    them, with nothing written (with ``allow_unconverged``: written marked, without a map); one
    that does not collide is written, converged."""
    monkeypatch.setattr(build_library, "run_doe", lambda *args, **kwargs: _table2_optima(tiny))

    def first_fit_checked(*args):
        raise AssertionError("the first fit's trajectories were checked before the certifiable regression")

    monkeypatch.setattr(build_library, "grid_collisions", first_fit_checked)
    # theta1 = pi/2, theta2 = 0 throughout: the arm stands straight up through the obstacle.
    upright = {name: (0.0,) * 6 for name in PARAMETER_NAMES}
    upright.update(w1=(1.0,) + (0.0,) * 5, w2=(1.0,) + (0.0,) * 5, gamma1=(np.pi / 2,) + (0.0,) * 5)
    refit = {}

    def certified(config, doe, coefficients, text, arm, progress):
        refit["first"] = coefficients
        written = dataclasses.replace(coefficients, parameters=refit.get("parameters", coefficients.parameters))
        return CertifiedCoefficients(written, text, None, {}, None, {"stages_s": {}})

    monkeypatch.setattr(build_run, "certify_coefficients", certified)
    config = BuildConfig.from_settings(out_folder=tmp_path / "out", **{**TINY, "endpoint_tolerance_m": 0.002})
    assert config.certifiable_refit
    refit["parameters"] = upright
    with pytest.raises(BuildNotConvergedError, match=r"regression: its trajectories collide at 441 of 441") as info:
        run_build(config)
    assert info.value.result.coefficients.parameters == upright and not (tmp_path / "out").exists()
    marked = run_build(config.with_settings(allow_unconverged=True))  # written marked, without a map
    assert not marked.converged and marked.region_map is None
    document = json.loads((tmp_path / "out" / "coefficients.json").read_text())
    assert document["converged"] is False and "collide at 441 of 441" in document["unconverged_reasons"][0]
    assert not (tmp_path / "out" / "region_map.json").exists()
    del refit["parameters"]  # the refit keeps the first fit, which Table 2's optima keep off the obstacle
    result = run_build(config)
    assert result.converged and result.coefficients.parameters == refit["first"].parameters
    assert (tmp_path / "out" / "coefficients.json").exists()


def test_a_range_whose_end_pose_collides_is_refused_before_any_work(arm) -> None:
    """top_y_m = 0.54 with W up to 0.12 m: the pose at P5 is inside the obstacle's corner."""
    with pytest.raises(InfeasibleSceneError, match=r"pose at P5 collides .* narrow --L-range/--W-range") as info:
        end_pose_collisions(grid_problems(arm, Scene(top_y_m=0.54), FitnessConfig(), PAPER, (0.2, 0.3), (0.08, 0.12)))
    assert info.value.point_name == "P5" and info.value.width_m == pytest.approx(0.12)
    assert info.value.clearance_m < -0.005
    end_pose_collisions(grid_problems(arm, Scene(top_y_m=0.54), FitnessConfig(), PAPER, (0.2, 0.3), (0.08, 0.10)))


def test_progress_starts_after_the_checks(tiny: dict, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setattr(build_library, "run_doe", lambda *args, **kwargs: list(tiny["result"].experiments))
    calls = []
    run_build(
        BuildConfig.from_settings(out_folder=tmp_path, allow_unconverged=True, **TINY),
        progress=lambda *a: calls.append(a),
    )
    assert calls == [("DOE", 0, 9)]  # run_doe is replayed here, so only the start is reported
    with pytest.raises(InvalidParameterError):
        run_build(
            BuildConfig.from_settings(out_folder=tmp_path / "doe.json", **TINY), progress=lambda *a: calls.append(a)
        )
    assert calls == [("DOE", 0, 9)]


# --------------------------------------------------------------------------------------------
# The command lines


def test_cli_exits_1_naming_the_failing_experiments(
    tiny: dict, tmp_path: Path, monkeypatch, capsys: pytest.CaptureFixture
) -> None:
    monkeypatch.setattr(build_library, "run_doe", lambda *args, **kwargs: list(tiny["result"].experiments))
    out = tmp_path / "out"
    assert build.main([*TINY_ARGV, "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("python -m pipeline.build: error: the build did not converge, nothing written")
    for problem in tiny["error"].problems:
        assert f"  {problem}\n" in err
    assert "Traceback" not in err and not out.exists()
    assert build.main([*TINY_ARGV, "--out", str(out), "--allow-unconverged"]) == 0
    assert 'warning: the build did not converge; written with "converged": false' in capsys.readouterr().err
    # regress keeps the mark: the DOE file says it did not converge.
    assert regress.main([str(out / "doe.json"), "-o", str(tmp_path / "c.json"), "--quiet"]) == 1
    assert "nothing written" in capsys.readouterr().err and not (tmp_path / "c.json").exists()
    assert regress.main([str(out / "doe.json"), "-o", str(tmp_path / "c.json"), "--allow-unconverged"]) == 0
    with pytest.warns(UnconvergedCoefficientsWarning):
        assert not load_coefficients(tmp_path / "c.json").converged


def test_cli_tiny_build_really_fails(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """No replay: a too-short PSO (as ``--iterations 2 --restarts 1``, here smaller still) exits 1."""
    out = tmp_path / "out"
    assert build.main([*TINY_ARGV, "--seed", "0", "--out", str(out), "--jobs", "0"]) == 1
    assert "did not converge" in capsys.readouterr().err and not out.exists()


def test_unconverged_regression_in_regress(tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch) -> None:
    """A constrained fit that misses its tolerance (SLSQP given one iteration) exits 1."""
    monkeypatch.setattr(regress, "endpoint_constraint", lambda args, family: EndpointConstraint(0.002, 21, 1))
    out = tmp_path / "c.json"
    assert regress.main(["paper", "--endpoint-tolerance", "0.002", "-o", str(out), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "regression: " in err and "> tolerance 2.00 mm" in err and not out.exists()


def test_a_crash_while_writing_removes_the_folders_the_build_created(
    tiny: dict, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(build_library, "run_doe", lambda *args, **kwargs: list(tiny["result"].experiments))
    real_stage = file_set._stage

    def crash(path, *args, **kwargs):
        if Path(path).name == "coefficients.json":
            raise OSError("disk full")
        return real_stage(path, *args, **kwargs)

    monkeypatch.setattr(file_set, "_stage", crash)
    with pytest.raises(OSError, match="disk full"):
        run_build(BuildConfig.from_settings(out_folder=tmp_path / "out", allow_unconverged=True, **TINY))
    assert list(tmp_path.iterdir()) == []  # neither out/ nor its lock is left (its parent must exist)


@pytest.mark.parametrize("command", [build, regress])
def test_help_states_units_rules_and_only_meaningful_defaults(command, capsys: pytest.CaptureFixture) -> None:
    assert command.main(["--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "(default: None)" not in text and "(default: False)" not in text
    assert "replaced atomically" in text and "Exit status: 0 written, 1 not converged" in text
    if command is build:
        assert "--max-doe-endpoint-error M largest endpoint error of a DOE optimum [m]" in text
        assert "(default: 0.05)" in text and "0 = every CPU" in text and "(default: 0)" in text
        assert "top_y_m = 0.54" in text and "an unknown key is refused" in text
