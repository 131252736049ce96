"""The build as one library call (:func:`pipeline.build.run_build`): the same files as the command
line, the files written as one set, and a build stopped in any phase leaves its folder as it was."""

from __future__ import annotations

import hashlib
import json
import math
import time
from pathlib import Path

import numpy as np
import pytest

import pipeline
from pipeline import BuildConfig, load_coefficients, run_build
from pipeline.build import doe_fit, range_stage
from pipeline.build.run import STAGE_NAMES
from pipeline.certify import certifiable_regression
from pipeline.commands import build as build_command
from pipeline.exceptions import InvalidParameterError
from pipeline.io import file_set
from pipeline.offline import coefficients as coefficients_module

SET = (
    "doe.json",
    "coefficients.json",
    "region_map.npy",
    "region_map.json",
    "near_optimal_cells.npy",
    "near_optimal_cells.json",
)


def snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())} if folder.exists() else {}


def test_library_and_command_line_write_the_same_bytes(replayed: list, tmp_path: Path) -> None:
    library, command = tmp_path / "library", tmp_path / "command"
    result = run_build(BuildConfig.from_settings(out_folder=library, jobs=1))
    assert build_command.main(["--out", str(command), "--quiet", "--no-progress"]) == 0
    for name in SET:
        assert (library / name).read_bytes() == (command / name).read_bytes(), name
    # The refit ran, the map belongs to the coefficients as written, and both are in the result.
    assert result.refit_report is not None and result.refit_report["rounds"]
    digest = hashlib.sha256((library / "coefficients.json").read_bytes()).hexdigest()
    assert result.region_map.coefficients_sha256 == digest == result.coefficients.source_sha256
    assert result.coefficients.region_map is result.region_map
    assert [written.path.name for written in result.written] == [*SET, "build_timing.json"]
    assert str(result.written[0]) == f"wrote {library / 'doe.json'}"
    assert repr(result.written[0]) == f"WrittenFile({str(library / 'doe.json')!r}, replaced=False)"
    timing = json.loads((library / "build_timing.json").read_text())
    assert timing == result.timing
    stages = ["checks", "doe", "regression", "clearance_refit", "range_certificate", "execution_bounds"]
    stages += ["near_optimal_cells"]
    assert list(timing["stages_s"]) == [*stages, "writing", "other"]
    # What a user then loads carries the map and its near-optimal cells (2 x 2 in these tests).
    loaded = load_coefficients(library / "coefficients.json").region_map
    assert loaded is not None and loaded.near_optimal_cells is not None
    assert loaded.near_optimal_cells.cells_per_axis == (2, 2) and loaded.near_optimal_cells.certified.all()


def test_without_a_range_map_no_stale_map_stays(replayed: list, tmp_path: Path) -> None:
    run_build(BuildConfig.from_settings(out_folder=tmp_path, jobs=1, clearance_rounds=0))
    assert (tmp_path / "region_map.json").is_file()
    result = run_build(BuildConfig.from_settings(out_folder=tmp_path, jobs=1, range_map=False, seed=1))
    assert result.region_map is None and not (tmp_path / "region_map.json").exists()
    assert not (tmp_path / "region_map.npy").exists()
    assert load_coefficients(tmp_path / "coefficients.json").region_map is None


def _interrupt(*args, **kwargs):
    raise KeyboardInterrupt


#: Where a build can be stopped: (module, function) replaced by one that raises KeyboardInterrupt.
PHASES = {
    "DOE": (doe_fit, "run_doe"),
    "regression": (coefficients_module, "fit_points_with_endpoints"),
    "certifiable regression": (certifiable_regression, "fit_certifiable"),
    "range map": (range_stage, "certify_range"),
    "staging the files": (file_set, "_stage"),
}


@pytest.mark.parametrize("phase", [*PHASES, "renaming the last file"])
def test_a_build_stopped_in_any_phase_leaves_its_folder_as_it_was(
    replayed: list, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, phase: str
) -> None:
    out = tmp_path / "results"
    # The refit only where it is the phase stopped (with a refit round the final map is the refit's).
    rounds = 1 if phase == "certifiable regression" else 0
    run_build(BuildConfig.from_settings(out_folder=out, jobs=1, clearance_rounds=rounds))
    (out / "notes.txt").write_text("a file of the user's", encoding="utf-8")
    before = snapshot(out)
    if phase in PHASES:
        module, name = PHASES[phase]
        monkeypatch.setattr(module, name, _interrupt)
    else:
        real_replace, seen = file_set.os.replace, []

        def replace(src, dst):
            if Path(dst).name == "build_timing.json" and str(src).endswith(".tmp") and not seen:
                seen.append(dst)
                raise KeyboardInterrupt
            return real_replace(src, dst)

        monkeypatch.setattr(file_set.os, "replace", replace)
    with pytest.raises(KeyboardInterrupt):
        run_build(BuildConfig.from_settings(out_folder=out, jobs=1, seed=1, clearance_rounds=rounds))
    monkeypatch.undo()
    assert snapshot(out) == before  # no new file beside the old ones, no temporary file, nothing lost


def test_a_new_folder_is_not_left_behind(replayed: list, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(range_stage, "certify_range", _interrupt)
    with pytest.raises(KeyboardInterrupt):
        run_build(BuildConfig.from_settings(out_folder=tmp_path / "results", jobs=1, clearance_rounds=0))
    assert list(tmp_path.iterdir()) == []  # neither the folder nor its lock


def test_a_folder_whose_parent_is_missing_is_refused_before_any_work(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setattr(doe_fit, "run_doe", lambda *args, **kwargs: pytest.fail("the DOE ran"))
    out = tmp_path / "a" / "missing" / "deep" / "folder"
    with pytest.raises(InvalidParameterError) as caught:
        run_build(BuildConfig.from_settings(out_folder=out, jobs=1))
    assert caught.value.name == "--out" and f"({out.parent} does not exist)" in str(caught.value)
    assert list(tmp_path.iterdir()) == []


def test_the_timing_file_gives_the_wall_time_and_stages_that_add_up_to_it(replayed: list, tmp_path: Path) -> None:
    started = time.perf_counter()
    result = run_build(BuildConfig.from_settings(out_folder=tmp_path, jobs=1, clearance_rounds=1))
    wall = time.perf_counter() - started
    timing = json.loads((tmp_path / "build_timing.json").read_text())
    stages = timing["stages_s"]
    assert set(stages) == {*STAGE_NAMES} and all(seconds >= 0 for seconds in stages.values())
    assert math.isclose(sum(stages.values()), timing["total_s"], rel_tol=0.01)
    assert math.isclose(timing["total_s"], wall, rel_tol=0.05)
    assert timing["total_s"] <= wall
    assert stages["range_certificate"] > 0 and stages["clearance_refit"] > 0 and stages["writing"] > 0
    assert stages["other"] < 0.05 * timing["total_s"]  # every stage of weight is named
    assert result.timing == timing


def test_interrupted_command_line_exits_130_and_writes_nothing(
    replayed: list, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    monkeypatch.setattr(range_stage, "certify_range", _interrupt)
    status = build_command.main(["--out", str(tmp_path / "out"), "--quiet", "--clearance-rounds", "0"])
    assert status == 130 and "interrupted" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_another_arm_travels_with_the_coefficients(replayed: list, tmp_path: Path) -> None:
    from pipeline.exceptions import DataFileError
    from pipeline.model.arm import DEFAULT_URDF
    from pipeline.online.arm_check import arm_for

    urdf = tmp_path / "my_arm.urdf"  # the same geometry, other bytes: another arm as far as the files go
    urdf.write_text(DEFAULT_URDF.read_text(encoding="utf-8") + "<!-- my arm -->\n", encoding="utf-8")
    out = tmp_path / "results"
    run_build(BuildConfig.from_settings(out_folder=out, jobs=1, urdf_path=urdf, clearance_rounds=0))
    assert (out / "arm.urdf").read_bytes() == urdf.read_bytes()
    urdf.unlink()  # the arm now lives beside the coefficients only
    moved = tmp_path / "moved"
    out.rename(moved)
    coefficients = load_coefficients(moved / "coefficients.json")
    assert coefficients.provenance["urdf"] == "arm.urdf"
    assert arm_for(coefficients).urdf_path == moved / "arm.urdf"
    (moved / "arm.urdf").write_text(DEFAULT_URDF.read_text(encoding="utf-8"), encoding="utf-8")
    with pytest.raises(DataFileError, match=r"arm\.urdf"):
        arm_for(load_coefficients(moved / "coefficients.json"))
    assert arm_for(coefficients, DEFAULT_URDF).urdf_path == DEFAULT_URDF  # given explicitly: checked, accepted


def test_acceleration_limits_given_to_the_build_travel_with_the_coefficients(replayed: list, tmp_path: Path) -> None:
    from pipeline import REST_TO_REST, generate_certified

    run_build(
        BuildConfig.from_settings(
            out_folder=tmp_path, jobs=1, clearance_rounds=0, acceleration_limits_rad_s2=(0.5, 0.5)
        )
    )
    coefficients = load_coefficients(tmp_path / "coefficients.json")
    assert coefficients.provenance["acceleration_limits_rad_s2"] == [0.5, 0.5]
    answer = generate_certified(coefficients, 0.25, 0.10, timing=REST_TO_REST)
    assert answer.execution.limits.acceleration_rad_s2 == (0.5, 0.5)
    assert np.all(answer.execution.certificate.acceleration_bound_rad_s2 <= 0.5)
    with pytest.raises(pipeline.ExecutionRefusedError, match="acceleration"):  # the paper timing breaks them
        generate_certified(coefficients, 0.25, 0.10)
