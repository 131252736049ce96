"""The offline CLIs, in process with tiny settings: ``python -m pipeline.build`` (deterministic
output files, one-line errors on bad input, no half-written or mismatched outputs after a
crash) and ``python -m pipeline.regress`` (Table 2 -> Eq. 9, bad input)."""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import io
import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pipeline import load_coefficients
from pipeline.build import doe_fit as build_library
from pipeline.commands import build, regress
from pipeline.io import file_set
from pipeline.io.folder_lock import LOCK_NAME
from pipeline.motion.trajectory import PARAMETER_NAMES
from pipeline.offline.coefficients import paper_data_path
from pipeline.offline.doe import load_doe
from pipeline.offline.endpoint_regression import EndpointConstraint, endpoint_targets, fit_with_endpoints
from pipeline.offline.regression import fit_quadratic, predict

# Plumbing settings: optima this rough are no data for the endpoint-constrained regression
# (tested on Table 2 below and in test_endpoint_regression.py), hence --plain.
TINY = ["--swarm-size", "8", "--iterations", "5", "--restarts", "1", "--n-points", "15", "--plain", "--quiet"]
TINY += ["--allow-unconverged", "--near-optimal-cells", "2"]  # optima this rough miss the convergence thresholds
OUTPUTS = ("doe.json", "coefficients.json")
# The tiny builds do not converge; their files are marked and warn when loaded (tested in test_build_config.py).
pytestmark = pytest.mark.filterwarnings("ignore::pipeline.exceptions.UnconvergedCoefficientsWarning")


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def assert_one_line_error(capsys: pytest.CaptureFixture, status: int) -> str:
    captured = capsys.readouterr()
    assert status == 2, captured.err
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("python -m pipeline.") and ": error: " in lines[0]
    assert "Traceback" not in captured.err + captured.out
    return lines[0]


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """One build with seed 0 (polish on); its run_doe results are kept for the crash tests."""
    out = tmp_path_factory.mktemp("reference")
    captured: dict = {}
    original = build_library.run_doe

    def recording_run_doe(*args, **kwargs):
        captured["results"] = original(*args, **kwargs)
        return captured["results"]

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(build_library, "run_doe", recording_run_doe)
        status = build.main([*TINY, "--seed", "0", "--out", str(out)])
    assert status == 0
    return {"out": out, "results": captured["results"], "files": snapshot(out)}


def replay(monkeypatch: pytest.MonkeyPatch, reference: dict) -> None:
    """Make pipeline.build reuse the reference DOE results instead of solving again."""
    monkeypatch.setattr(build_library, "run_doe", lambda *args, **kwargs: reference["results"])


# --------------------------------------------------------------------------------------------
# Output files.


def test_build_writes_doe_and_coefficients(reference: dict) -> None:
    out = reference["out"]
    assert {"doe.json", "coefficients.json", "build_timing.json"} <= set(reference["files"])
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no temporary files left
    doe = load_doe(out / "doe.json")
    assert doe.family.name == "paper" and doe.parameters.shape == (9, 8)
    document = json.loads((out / "doe.json").read_text())
    assert [e["test"] for e in document["experiments"]] == list(range(1, 10))
    assert document["provenance"]["seed"] == 0
    # The design is the paper's grid: each row carries the paper's Table 2 scored on our fitness.
    assert all("paper_table2" in e and isinstance(e["beats_paper"], bool) for e in document["experiments"])
    coefficients = load_coefficients(out / "coefficients.json")
    assert coefficients.family.name == "paper"
    assert list(coefficients.parameters) == list(PARAMETER_NAMES)
    assert coefficients.fitted_range_m == {"L": (0.2, 0.3), "W": (0.08, 0.12)}
    # The coefficients are the regression of the DOE file written beside them.
    assert coefficients.provenance["doe_sha256"] == sha256(out / "doe.json")
    assert coefficients.extra["fit"]["regression"] == "least squares"
    fit = fit_quadratic(doe.lengths_m, doe.widths_m, doe.free_parameters())
    for name in PARAMETER_NAMES:
        assert_allclose(coefficients.parameters[name], fit.coefficients[name], rtol=1e-12, atol=1e-12)


def test_build_default_regression_holds_the_endpoints(
    reference: dict, table2: np.ndarray, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """Without --plain the build fits with the endpoint constraint. The DOE is replayed with
    the paper's Table 2 as optima (real optima, unlike TINY's), so the fit converges."""
    results = [
        dataclasses.replace(
            r,
            parameters=dict(zip(PARAMETER_NAMES, row[:8], strict=True)),
            free_parameters=dict(zip(PARAMETER_NAMES, row[:8], strict=True)),
        )
        for r, row in zip(reference["results"], table2, strict=True)
    ]
    monkeypatch.setattr(build_library, "run_doe", lambda *args, **kwargs: results)
    tiny_default = [a for a in TINY if a != "--plain"]
    assert build.main([*tiny_default, "--seed", "0", "--endpoint-tolerance", "0.003", "--out", str(tmp_path)]) == 0
    coefficients = load_coefficients(tmp_path / "coefficients.json")
    fit_block = coefficients.extra["fit"]
    assert fit_block["regression"] == "least squares + endpoint constraint"
    assert fit_block["endpoint_constraint"]["converged"] is True
    assert fit_block["endpoint_constraint"]["tolerance_m"] == 0.003
    doe = load_doe(tmp_path / "doe.json")
    assert_allclose(doe.parameters, table2[:, :8], rtol=0, atol=1e-12)
    targets = endpoint_targets(coefficients.fitted_range_m, doe.scene, doe.link_lengths_m, 21)
    fit, report = fit_with_endpoints(
        doe.lengths_m, doe.widths_m, doe.free_parameters(), targets, EndpointConstraint(tolerance_m=0.003)
    )
    assert report["grid_endpoint_error_max_m"] <= 0.003 * (1 + 1e-6) < report["grid_endpoint_error_max_plain_m"]
    for name in PARAMETER_NAMES:
        assert_allclose(coefficients.parameters[name], fit.coefficients[name], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("tolerance", ["0", "-0.001", "nan"])
def test_build_bad_endpoint_tolerance_exits_2_before_the_doe(
    tolerance: str, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setattr(build_library, "run_doe", lambda *args, **kwargs: pytest.fail("the DOE ran"))
    tiny_default = [a for a in TINY if a != "--plain"]
    line = assert_one_line_error(
        capsys, build.main([*tiny_default, "--endpoint-tolerance", tolerance, "--out", str(tmp_path)])
    )
    assert "--endpoint-tolerance" in line


def test_same_seed_with_two_jobs_is_byte_identical(reference: dict, tmp_path: Path) -> None:
    assert build.main([*TINY, "--seed", "0", "--jobs", "2", "--out", str(tmp_path)]) == 0
    for name in OUTPUTS:
        assert (tmp_path / name).read_bytes() == reference["files"][name], name


def test_same_seed_twice_is_byte_identical_and_another_seed_differs(tmp_path: Path) -> None:
    runs = {}
    for label, seed in (("a", "3"), ("b", "3"), ("c", "4")):
        out = tmp_path / label
        assert build.main([*TINY, "--no-polish", "--seed", seed, "--out", str(out)]) == 0
        runs[label] = {name: (out / name).read_bytes() for name in OUTPUTS}
    assert runs["a"] == runs["b"]
    assert runs["a"]["coefficients.json"] != runs["c"]["coefficients.json"]
    assert runs["a"]["doe.json"] != runs["c"]["doe.json"]


def test_rebuild_replaces_outputs(reference: dict, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    replay(monkeypatch, reference)
    assert build.main([*TINY, "--seed", "0", "--out", str(tmp_path)]) == 0
    first = snapshot(tmp_path)
    assert build.main([*TINY, "--seed", "0", "--out", str(tmp_path)]) == 0
    for name in OUTPUTS:
        assert (tmp_path / name).read_bytes() == first[name] == reference["files"][name]


def test_report_goes_to_the_current_stdout(reference: dict, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """What build prints ("wrote ...", "solver: ...") goes to sys.stdout as it is when main runs,
    so that a caller redirecting stdout (contextlib.redirect_stdout, pytest's capsys) sees it."""
    replay(monkeypatch, reference)
    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        assert build.main([*TINY, "--seed", "0", "--out", str(tmp_path)]) == 0
    assert f"wrote {tmp_path / 'coefficients.json'}" in buffer.getvalue()
    assert "solver: pso" in buffer.getvalue()


def test_the_last_line_and_the_timing_line_quote_the_timing_files_total(
    reference: dict, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    replay(monkeypatch, reference)
    assert build.main([*(a for a in TINY if a != "--quiet"), "--out", str(tmp_path)]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    timing = json.loads((tmp_path / "build_timing.json").read_text())
    total = f"{timing['total_s']:.1f} s wall"
    assert lines[-1].startswith(f"build {total} (build_timing.json; sha256 of coefficients.json ")
    (line,) = [line for line in lines if line.startswith("Timing: ")]
    assert line.startswith(f"Timing: {total} in all (checks ") and ", DOE " in line and ", writing " in line
    assert f"wrote {tmp_path / 'coefficients.json'}" in lines


# --------------------------------------------------------------------------------------------
# Bad input: exit status 2, one line on stderr, nothing written.


NON_PLANAR_URDF = """<?xml version="1.0"?>
<robot name="not_planar">
  <link name="base_link"/>
  <link name="link1">
    <collision><origin xyz="0.15 0 0" rpy="0 1.5707963267948966 0"/>
      <geometry><cylinder radius="0.005" length="0.30"/></geometry></collision>
  </link>
  <link name="link2">
    <collision><origin xyz="0.175 0 0" rpy="0 1.5707963267948966 0"/>
      <geometry><cylinder radius="0.005" length="0.35"/></geometry></collision>
  </link>
  <link name="end_effector"/>
  <joint name="joint1" type="revolute"><parent link="base_link"/><child link="link1"/>
    <origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3.14" upper="3.14" effort="10" velocity="3"/></joint>
  <joint name="joint2" type="revolute"><parent link="link1"/><child link="link2"/>
    <origin xyz="0.30 0 0" rpy="0 0 0"/><axis xyz="1 0 0"/>
    <limit lower="-3.14" upper="3.14" effort="10" velocity="3"/></joint>
  <joint name="ee" type="fixed"><parent link="link2"/><child link="end_effector"/>
    <origin xyz="0.35 0 0" rpy="0 0 0"/></joint>
</robot>
"""


@pytest.mark.parametrize(
    ("arguments", "needle"),
    [
        (["--levels", "2"], "--levels"),
        (["--L-range", "0.3", "0.2"], "--L-range"),
        (["--L-range", "-0.1", "0.2"], "--L-range"),
        (["--W-range", "nan", "0.1"], "--W-range"),
        (["--L-range", "1.0", "1.4"], "cannot pass"),
        (["--W-range", "0.45", "0.47"], "cannot pass"),
        (["--jobs", "-1"], "--jobs"),
        (["--clearance-rounds", "-1"], "--clearance-rounds"),
        (["--swarm-size", "1"], "--swarm-size"),
        (["--margin", "-0.01"], "--margin"),
        (["--speed", "0"], "--speed"),
        (["--corner-radius", "0.5"], "--corner-radius"),
        (["--urdf", "MISSING"], "not found"),
        (["--urdf", "NON_PLANAR"], "not planar"),
    ],
)
def test_bad_input_exits_2_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch, arguments: list[str], needle: str
) -> None:
    def must_not_run(*args, **kwargs):
        raise AssertionError("bad input must be rejected before the DOE runs")

    if "--jobs" not in arguments:
        monkeypatch.setattr(build_library, "run_doe", must_not_run)
    urdf = tmp_path / "non_planar.urdf"
    urdf.write_text(NON_PLANAR_URDF, encoding="utf-8")
    arguments = [
        str(urdf) if a == "NON_PLANAR" else str(tmp_path / "missing.urdf") if a == "MISSING" else a for a in arguments
    ]
    out = tmp_path / "out"
    line = assert_one_line_error(capsys, build.main([*TINY, *arguments, "--out", str(out)]))
    assert needle in line
    assert not out.exists() or list(out.iterdir()) == []


def test_out_is_an_existing_file(
    reference: dict, tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    """--out naming a regular file is bad input like any other: one line, exit 2, file untouched."""
    replay(monkeypatch, reference)
    target = tmp_path / "results"
    target.write_text("not a folder", encoding="utf-8")
    try:
        status = build.main([*TINY, "--out", str(target)])
    except OSError as exc:
        pytest.fail(f"pipeline.build crashed with a traceback instead of exit status 2: {exc!r}")
    assert_one_line_error(capsys, status)
    assert target.read_text(encoding="utf-8") == "not a folder"


def test_a_missing_parent_folder_is_refused_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(build_library, "run_doe", lambda *args, **kwargs: pytest.fail("the DOE ran"))
    out = tmp_path / "a" / "missing" / "deep" / "folder"
    line = assert_one_line_error(capsys, build.main([*TINY, "--out", str(out)]))
    assert line == (
        f"python -m pipeline.build: error: --out = {str(out)!r} is invalid: expected a folder in an existing "
        f"folder ({out.parent} does not exist)"
    )
    assert list(tmp_path.iterdir()) == []


def test_a_folder_another_build_writes_is_refused_before_any_work(
    reference: dict, tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(build_library, "run_doe", lambda *args, **kwargs: pytest.fail("the DOE ran"))
    before = seed_outputs(tmp_path, reference)
    lock = tmp_path / LOCK_NAME
    lock.write_text(json.dumps({"pid": os.getpid(), "host": socket.gethostname()}))  # a live process
    line = assert_one_line_error(capsys, build.main([*TINY, "--out", str(tmp_path)]))
    assert line == (
        f"python -m pipeline.build: error: {tmp_path}/ is being written by the build of process {os.getpid()} "
        f"(lock {lock}); wait for it or remove the lock"
    )
    lock.unlink()  # the first build's lock stays until that build ends
    assert snapshot(tmp_path) == before


def test_a_stale_lock_is_taken_over_with_a_note(
    reference: dict, tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    replay(monkeypatch, reference)
    ended = subprocess.Popen([sys.executable, "-c", "pass"])
    ended.wait()
    lock = tmp_path / LOCK_NAME
    lock.write_text(json.dumps({"pid": ended.pid, "host": socket.gethostname()}))  # a build killed with SIGKILL
    assert build.main([*TINY, "--out", str(tmp_path)]) == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if "lock" in line]
    assert notes == [f"note: took over the lock {lock} of process {ended.pid}, which is no longer running"]
    assert not lock.exists()
    for name in OUTPUTS:
        assert (tmp_path / name).read_bytes() == reference["files"][name]


# --------------------------------------------------------------------------------------------
# Crashes mid-build.


def seed_outputs(folder: Path, reference: dict) -> dict[str, bytes]:
    """Pre-existing, consistent outputs of an earlier build."""
    folder.mkdir(parents=True, exist_ok=True)
    for name in OUTPUTS:
        (folder / name).write_bytes(reference["files"][name])
    return snapshot(folder)


def test_crash_in_run_doe_leaves_outputs_untouched(
    reference: dict, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    before = seed_outputs(tmp_path, reference)

    def crash(*args, **kwargs):
        raise RuntimeError("worker died")

    monkeypatch.setattr(build_library, "run_doe", crash)
    with pytest.raises(RuntimeError):
        build.main([*TINY, "--seed", "1", "--out", str(tmp_path)])
    assert snapshot(tmp_path) == before


def test_interrupt_in_run_doe_leaves_outputs_untouched(
    reference: dict, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    before = seed_outputs(tmp_path, reference)

    def interrupt(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(build_library, "run_doe", interrupt)
    assert build.main([*TINY, "--seed", "1", "--out", str(tmp_path)]) == 130
    assert "interrupted" in capsys.readouterr().err
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize(
    "where", ["writing coefficients.json", "os.replace of coefficients.json", "os.replace of build_timing.json"]
)
def test_crash_while_writing_leaves_no_half_written_or_mismatched_outputs(
    reference: dict, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, where: str
) -> None:
    """A crash while the outputs are written (seed 1 replacing seed 0's files) must leave the
    earlier build's doe.json and coefficients.json as they were: never half-written files, and
    never a new doe.json beside coefficients.json regressed from the old one."""
    before = seed_outputs(tmp_path, reference)
    results = reference["results"]
    # A different DOE than the files on disk (as a build with another seed would produce).
    changed = [type(r)(**{**r.__dict__, "fitness": r.fitness * 1.5}) for r in results]
    monkeypatch.setattr(build_library, "run_doe", lambda *args, **kwargs: changed)
    if where == "writing coefficients.json":
        real_stage = file_set._stage

        def crash(path, *args, **kwargs):
            if Path(path).name == "coefficients.json":
                raise OSError("disk full")
            return real_stage(path, *args, **kwargs)

        monkeypatch.setattr(file_set, "_stage", crash)
    else:
        real_replace, target, failed = os.replace, where.rpartition(" ")[2], []

        def replace(src, dst):
            # Once, as the new file goes in (for build_timing.json, the last of the set, the others
            # are in place by then); putting the old file back works.
            if Path(dst).name == target and str(src).endswith(".tmp") and not failed:
                failed.append(dst)
                raise OSError("disk full")
            return real_replace(src, dst)

        monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(OSError):
        build.main([*TINY, "--seed", "1", "--out", str(tmp_path)])
    monkeypatch.undo()
    after = {name: data for name, data in snapshot(tmp_path).items() if name in OUTPUTS}
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary files
    for name in OUTPUTS:
        json.loads(after[name])  # never half-written
    assert snapshot(tmp_path) == before  # the earlier set, nothing new beside it
    assert after["coefficients.json"] == before["coefficients.json"]
    provenance = json.loads(after["coefficients.json"])["provenance"]
    assert provenance["doe_sha256"] == sha256(tmp_path / "doe.json"), "doe.json no longer matches coefficients.json"
    assert after["doe.json"] == before["doe.json"]


# --------------------------------------------------------------------------------------------
# python -m pipeline.regress


def eq9_max_prediction_difference(coefficients_path: Path) -> float:
    ours = load_coefficients(coefficients_path).parameters
    paper = load_coefficients("paper").parameters
    L, W = np.meshgrid(np.linspace(0.2, 0.3, 101), np.linspace(0.08, 0.12, 101))
    names = list(PARAMETER_NAMES)
    return float(
        np.max(np.abs(predict({n: ours[n] for n in names}, L, W) - predict({n: paper[n] for n in names}, L, W)))
    )


@pytest.mark.parametrize("source", ["path", "paper"])
def test_regress_table_2_reproduces_eq9(tmp_path: Path, capsys: pytest.CaptureFixture, source: str) -> None:
    table2 = paper_data_path("paper_table2_doe.json")
    out = tmp_path / "coefficients.json"
    assert regress.main([str(table2) if source == "path" else "paper", "-o", str(out), "--quiet"]) == 0
    assert "wrote" in capsys.readouterr().out
    coefficients = load_coefficients(out)
    assert coefficients.family.name == "paper"
    assert coefficients.provenance["doe_sha256"] == sha256(table2)
    # Within the rounding of Table 2 (see tests/test_regression.py for the bound): < 1e-3 rad
    # between the two fits' predictions over the fitted range.
    assert eq9_max_prediction_difference(out) < 1e-3
    doe = load_doe(table2)
    fit = fit_quadratic(doe.lengths_m, doe.widths_m, doe.free_parameters())
    for name in PARAMETER_NAMES:
        assert coefficients.parameters[name] == fit.coefficients[name]


def test_regress_with_endpoint_tolerance_is_the_build_regression(tmp_path: Path, capsys) -> None:
    table2 = paper_data_path("paper_table2_doe.json")
    out = tmp_path / "c.json"
    assert regress.main(["paper", "--endpoint-tolerance", "0.002", "-o", str(out)]) == 0
    assert "plain fit) -> 1.94 mm" in capsys.readouterr().out  # the fit holds 3 % of the 2 mm free
    coefficients = load_coefficients(out)
    assert coefficients.extra["fit"]["regression"] == "least squares + endpoint constraint"
    doe = load_doe(table2)
    targets = endpoint_targets(coefficients.fitted_range_m, doe.scene, doe.link_lengths_m, 21)
    check = endpoint_targets(coefficients.fitted_range_m, doe.scene, doe.link_lengths_m, 101)
    fit, _ = fit_with_endpoints(
        doe.lengths_m, doe.widths_m, doe.free_parameters(), targets, EndpointConstraint(), check
    )
    for name in PARAMETER_NAMES:
        assert coefficients.parameters[name] == fit.coefficients[name]
    assert eq9_max_prediction_difference(out) > 1e-2  # not Eq. 9 any more: the constraint moved it
    line = assert_one_line_error(
        capsys, regress.main(["paper", "--endpoint-tolerance", "nan", "-o", str(tmp_path / "x.json")])
    )
    assert "--endpoint-tolerance" in line and not (tmp_path / "x.json").exists()


def test_regress_as_a_module(tmp_path: Path) -> None:
    out = tmp_path / "c.json"
    table2 = paper_data_path("paper_table2_doe.json")
    done = subprocess.run(
        [sys.executable, "-m", "pipeline.regress", str(table2), "-o", str(out)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert "A1" in done.stdout and "paper" in done.stdout  # the table beside the paper's Eq. 9
    assert eq9_max_prediction_difference(out) < 1e-3


def test_regress_is_deterministic_and_replaces_like_build(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """One overwrite rule for build and regress: an existing output is replaced atomically."""
    out = tmp_path / "c.json"
    assert regress.main(["paper", "-o", str(out), "--quiet"]) == 0
    first = out.read_bytes()
    capsys.readouterr()
    assert regress.main(["paper", "-o", str(out), "--quiet"]) == 0
    assert f"replaced {out}" in capsys.readouterr().out
    assert out.read_bytes() == first


def test_regress_of_a_build_doe(reference: dict, tmp_path: Path) -> None:
    out = tmp_path / "c.json"
    # The tiny reference build did not converge: its DOE file says so, and regress needs the flag.
    assert regress.main([str(reference["out"] / "doe.json"), "-o", str(out), "--quiet"]) == 1
    assert regress.main([str(reference["out"] / "doe.json"), "-o", str(out), "--quiet", "--allow-unconverged"]) == 0
    ours = load_coefficients(out)
    built = load_coefficients(reference["out"] / "coefficients.json")
    assert ours.parameters == built.parameters
    assert ours.fitted_range_m == built.fitted_range_m


def _bad_doe(tmp_path: Path, kind: str) -> Path:
    path = tmp_path / f"{kind}.json"
    document = json.loads(paper_data_path("paper_table2_doe.json").read_text())
    if kind == "missing":
        return path
    if kind == "not_json":
        path.write_text("{", encoding="utf-8")
        return path
    if kind == "array":
        path.write_text("[]", encoding="utf-8")
        return path
    if kind == "nan":
        document["experiments"][0]["parameters"]["A1"] = float("nan")
    if kind == "one_width":  # every experiment at W = 0.10: the quadratic in W is undetermined
        for experiment in document["experiments"]:
            experiment["W"] = 0.10
    if kind == "wrong_format":
        document["format"] = "twolink-doe/0"
    path.write_text(json.dumps(document, allow_nan=True), encoding="utf-8")
    return path


@pytest.mark.parametrize("kind", ["missing", "not_json", "array", "nan", "one_width", "wrong_format"])
def test_regress_bad_input_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture, kind: str) -> None:
    doe = _bad_doe(tmp_path, kind)
    out = tmp_path / "out.json"
    line = assert_one_line_error(capsys, regress.main([str(doe), "-o", str(out), "--quiet"]))
    if kind != "one_width":
        assert str(doe) in line
    assert not out.exists()


def test_regress_output_is_a_directory(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """-o naming a directory is bad input: exit 2 with one line, with or without --force."""
    folder = tmp_path / "folder"
    folder.mkdir()
    assert_one_line_error(capsys, regress.main(["paper", "-o", str(folder), "--quiet"]))
    try:
        status = regress.main(["paper", "-o", str(folder), "--quiet", "--force"])
    except OSError as exc:
        pytest.fail(f"pipeline.regress crashed with a traceback instead of exit status 2: {exc!r}")
    assert_one_line_error(capsys, status)
    assert folder.is_dir() and list(folder.iterdir()) == []
