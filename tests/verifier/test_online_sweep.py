"""``python -m verify.online_sweep``: certify-or-repair over many obstacles; every answer is
certified at least the margin or refused; bad input is one line and exit status 2."""

from __future__ import annotations

import json

import pytest

from pipeline.exceptions import InvalidParameterError
from verify import online_sweep
from verify.acceptance.online import OnlineCase, summarize_online


def test_online_sweep_cli_reports_and_writes_json(tmp_path, capsys):
    out = tmp_path / "online.json"
    status = online_sweep.main(["--coefficients", "paper", "--n", "6", "--no-progress", "--json", str(out)])
    assert status == 0
    summary = json.loads(out.read_text())["summary"]
    assert summary["cases"] == 6
    assert summary["answers_below_margin"] == 0
    assert summary["certified_from_regression"] + summary["repaired"] + summary["refused"] == 6
    assert "certify-or-repair on paper" in capsys.readouterr().out


def test_online_sweep_cli_bad_input(capsys):
    assert online_sweep.main(["--coefficients", "/nonexistent.json", "--n", "3"]) == 2
    assert online_sweep.main(["--coefficients", "paper", "--n", "0"]) == 2
    err = capsys.readouterr().err
    assert "error:" in err and "Traceback" not in err


def test_online_sweep_refuses_bad_options_one_by_one(capsys):
    for argv, option in (
        (["--n", "-1"], "--n"),
        (["--jobs", "-1"], "--jobs"),
        (["--beyond", "5"], "--beyond"),
        (["--beyond", "-0.1"], "--beyond"),
        (["--max-seconds", "0"], "--max-seconds"),
    ):
        assert online_sweep.main(["--coefficients", "paper", *argv]) == 2
        err = capsys.readouterr().err
        lines = err.strip().splitlines()
        assert len(lines) == 1 and option in lines[0] and "Traceback" not in err, err
        assert lines[0].startswith("python -m verify.online_sweep: error:")


def test_online_sweep_checks_the_json_path_before_any_work(capsys, monkeypatch):
    monkeypatch.setattr(online_sweep, "run_online_cases", lambda *a, **k: pytest.fail("cases ran despite --json"))
    assert online_sweep.main(["--coefficients", "paper", "--n", "1000", "--json", "/proc/x"]) == 2
    err = capsys.readouterr().err
    assert "--json" in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_online_sweep_refuses_another_arm(capsys, double_pendulum_urdf):
    status = online_sweep.main(["--coefficients", "paper", "--n", "2", "--urdf", str(double_pendulum_urdf)])
    err = capsys.readouterr().err
    assert status == 2 and "0.3, 0.35" in err and "0.1, 0.2" in err and len(err.strip().splitlines()) == 1


def test_online_sweep_results_do_not_depend_on_jobs(capsys, tmp_path):
    documents = []
    for jobs in ("1", "2"):
        out = tmp_path / f"online_{jobs}.json"
        argv = [
            "--coefficients",
            "paper",
            "--n",
            "4",
            "--seed",
            "5",
            "--no-progress",
            "--jobs",
            jobs,
            "--json",
            str(out),
        ]
        assert online_sweep.main(argv) == 0
        documents.append(json.loads(out.read_text()))
    strip = [[{k: v for k, v in c.items() if k != "seconds"} for c in d["cases"]] for d in documents]
    assert strip[0] == strip[1]


def test_online_summary_counts_and_refuses_an_empty_sweep():
    cases = [
        OnlineCase(0.25, 0.10, "certified", 0.02, 0.02, "", 0.01),
        OnlineCase(0.25, 0.11, "repaired", 0.0101, 0.004, "", 0.03),
        OnlineCase(0.25, 0.12, "refused", None, 0.003, "end pose at P5 too close (detail)", 0.02),
    ]
    summary = summarize_online(cases, 0.01)
    assert (summary.n_certified_from_regression, summary.n_repaired, summary.n_refused) == (1, 1, 1)
    assert summary.invariant_holds and summary.min_returned_certified_clearance_m == 0.0101
    assert dict(summary.refusal_reasons) == {"end pose at P5 too close": 1}
    unsafe = summarize_online([OnlineCase(0.25, 0.1, "certified", 0.005, 0.005, "", 0.01)], 0.01)
    assert not unsafe.invariant_holds
    with pytest.raises(InvalidParameterError):
        summarize_online([], 0.01)
    with pytest.raises(InvalidParameterError):
        OnlineCase(0.25, 0.1, "refused", 0.02, None, "", 0.01)


def test_online_sweep_ctrl_c_is_one_line_and_status_130(capsys, monkeypatch):
    from verify.acceptance import online

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(online, "query", interrupted)
    assert online_sweep.main(["--coefficients", "paper", "--n", "3", "--no-progress"]) == 130
    err = capsys.readouterr().err
    assert err.strip() == "python -m verify.online_sweep: interrupted"


def test_workers_refuse_a_coefficients_file_that_is_not_the_one_given(tmp_path):
    """The worker processes load the coefficients from the file; when it is not the object the
    caller holds (rewritten, or another file under that name), they refuse with a one-line
    DataFileError rather than answer for other coefficients (their cache is keyed by sha256)."""
    import dataclasses

    import numpy as np

    from pipeline import load_coefficients
    from pipeline.exceptions import DataFileError
    from pipeline.offline.coefficients import save_coefficients
    from pipeline.online.repair import RepairConfig
    from verify.acceptance.online import run_online_cases

    path = tmp_path / "coefficients.json"
    save_coefficients(load_coefficients("paper"), path)
    held = load_coefficients(path)
    cases = np.array([[0.25, 0.1], [0.22, 0.09]])
    answers = run_online_cases(str(path), cases, RepairConfig(), jobs=2, progress=False, coefficients=held)
    assert len(answers) == 2
    parameters = dict(held.parameters)
    parameters["gamma2"] = (parameters["gamma2"][0] + 1e-3, *parameters["gamma2"][1:])
    changed = dataclasses.replace(held, parameters=parameters)
    save_coefficients(changed, path)  # the file under the same name now holds other coefficients
    with pytest.raises(DataFileError, match="sha256 differs"):
        run_online_cases(str(path), cases, RepairConfig(), jobs=2, progress=False, coefficients=held)


def test_queries_run_the_per_query_certificate_even_with_a_map_attached():
    """The online sweep checks certify-or-repair: a region map attached to the coefficients (which
    would answer these cells at once, without a per-query certificate) is not used."""
    import dataclasses

    from pipeline import load_coefficients
    from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
    from pipeline.online.arm_check import arm_for
    from pipeline.online.repair import RepairConfig, generate_certified
    from verify.acceptance.online import query

    paper = load_coefficients("paper")
    region_map = certify_range(paper, RangeCertificateConfig(min_cell=1 / 16, boundary_cell=1 / 8))
    with_map = dataclasses.replace(paper, region_map=region_map)
    assert generate_certified(with_map, 0.25, 0.09).regression_certificate is None  # the map's answer
    answer = query(with_map, arm_for(paper), 0.25, 0.09, RepairConfig())
    alone = query(paper, arm_for(paper), 0.25, 0.09, RepairConfig())
    assert answer.regression_certified_clearance_m == alone.regression_certified_clearance_m is not None


def test_the_arm_is_the_one_recorded_with_the_coefficients(tmp_path):
    """Without --urdf the arm is the one the coefficients record; missing, it is a one-line error."""
    import dataclasses
    import hashlib

    from pipeline import load_coefficients
    from pipeline.model.arm import DEFAULT_URDF
    from pipeline.offline.coefficients import save_coefficients

    urdf = tmp_path / "arm.urdf"
    urdf.write_text(DEFAULT_URDF.read_text() + "\n<!-- the arm of this build -->\n")
    paper = load_coefficients("paper", region_map=None)
    record = {"urdf": "arm.urdf", "urdf_sha256": hashlib.sha256(urdf.read_bytes()).hexdigest()}
    source = tmp_path / "coefficients.json"
    save_coefficients(dataclasses.replace(paper, extra={**paper.extra, "provenance": record}), source)
    assert online_sweep.main(["--coefficients", str(source), "--n", "2", "--no-progress"]) == 0
    urdf.unlink()
    assert online_sweep.main(["--coefficients", str(source), "--n", "2", "--no-progress"]) == 2
