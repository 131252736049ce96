"""``python -m pipeline.generate`` end to end: the written samples reproduce ``generate``'s q, dq, ddq at
their times, the rate is honoured with T as the last sample, the ROS JSON carries the URDF's joint
names, a refused certification exits 1 with its reason, and bad input is one line, exit 2, no file."""

from __future__ import annotations

import csv
import importlib
import json
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pipeline import load_coefficients
from pipeline.model.arm import DEFAULT_URDF
from pipeline.motion.families import EXACT_ENDPOINTS
from pipeline.offline.coefficients import Coefficients, save_coefficients
from pipeline.online.generator import generate

generate_module = importlib.import_module("pipeline.commands.generate")


def run(capsys, *argv: str) -> tuple[int, str, str]:
    status = generate_module.main(list(argv))
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def urdf_revolute_joints(path: Path) -> list[str]:
    """Names of the URDF's revolute joints, read with the XML parser (independent of Pinocchio)."""
    return [
        j.get("name") for j in ET.parse(path).getroot().iter("joint") if j.get("type") in ("revolute", "continuous")
    ]


def rnea(q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> np.ndarray:
    """Torques [N m] by Pinocchio's RNEA on the shipped URDF, sample by sample."""
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(DEFAULT_URDF))
    data = model.createData()
    return np.array([pin.rnea(model, data, *state).copy() for state in zip(q, dq, ddq, strict=True)])


def expected_times(duration: float, rate: float) -> np.ndarray:
    times = [k / rate for k in range(int(duration * rate) + 2) if k / rate < duration]
    return np.array([*times, duration])


@pytest.mark.parametrize("rate", [100.0, 7.5])
def test_csv_reproduces_generate_at_the_rate(tmp_path: Path, capsys, rate: float) -> None:
    out = tmp_path / "trajectory.csv"
    status, stdout, _ = run(
        capsys,
        "--L",
        "0.27",
        "--W",
        "0.09",
        "--coefficients",
        "paper",
        "--rate",
        str(rate),
        "--out",
        str(out),
        "--timing",
        "paper",
    )
    assert status == 0
    assert "coefficients: paper (paper, sha256" in stdout and "T = " in stdout and "gamma2" in stdout
    with out.open() as handle:
        rows = [row for row in csv.reader(handle) if not row[0].startswith("#")]
    assert rows[0] == list(generate_module.CSV_COLUMNS)
    data = np.array(rows[1:], dtype=float)
    answer = generate(load_coefficients("paper"), 0.27, 0.09)
    t = data[:, 0]
    assert t[-1] == answer.duration_s and t[0] == 0.0
    assert_allclose(t, expected_times(answer.duration_s, rate), rtol=0, atol=1e-15)
    assert_allclose(np.diff(t[:-1]), 1.0 / rate, rtol=1e-12)
    assert 0.0 < t[-1] - t[-2] <= 1.0 / rate
    assert_allclose(data[:, 1:3], answer.q(t), rtol=0, atol=0)
    assert_allclose(data[:, 3:5], answer.dq(t), rtol=0, atol=0)
    assert_allclose(data[:, 5:7], answer.ddq(t), rtol=0, atol=0)
    assert_allclose(data[:, 7:9], rnea(answer.q(t), answer.dq(t), answer.ddq(t)), rtol=0, atol=1e-15)


def test_npz_reproduces_generate(tmp_path: Path, capsys) -> None:
    out = tmp_path / "trajectory.npz"
    status, _, _ = run(
        capsys,
        "--L",
        "0.22",
        "--W",
        "0.11",
        "--coefficients",
        "paper",
        "--rate",
        "50",
        "--out",
        str(out),
        "--timing",
        "paper",
    )
    assert status == 0
    data = np.load(out)
    answer = generate(load_coefficients("paper"), 0.22, 0.11)
    assert_allclose(data["t_s"], expected_times(answer.duration_s, 50.0), rtol=0, atol=1e-15)
    assert_allclose(data["q_rad"], answer.q(data["t_s"]), rtol=0, atol=0)
    assert_allclose(data["dq_rad_s"], answer.dq(data["t_s"]), rtol=0, atol=0)
    assert_allclose(data["ddq_rad_s2"], answer.ddq(data["t_s"]), rtol=0, atol=0)
    assert tuple(data["parameters"]) == answer.trajectory.parameters
    assert float(data["duration_s"]) == answer.duration_s


def test_ros_json_has_the_urdf_joint_names_and_reproduces_generate(tmp_path: Path, capsys) -> None:
    out = tmp_path / "trajectory.json"
    status, _, _ = run(
        capsys,
        "--L",
        "0.25",
        "--W",
        "0.1",
        "--coefficients",
        "paper",
        "--rate",
        "20",
        "--out",
        str(out),
        "--timing",
        "paper",
    )
    assert status == 0
    message = json.loads(out.read_text())
    assert message["joint_names"] == urdf_revolute_joints(DEFAULT_URDF)
    answer = generate(load_coefficients("paper"), 0.25, 0.1)
    points = message["points"]
    t = np.array([p["time_from_start"]["sec"] + p["time_from_start"]["nanosec"] * 1e-9 for p in points])
    assert all(0 <= p["time_from_start"]["nanosec"] < 1_000_000_000 for p in points)
    assert_allclose(t, expected_times(answer.duration_s, 20.0), rtol=0, atol=1e-9)
    exact_t = expected_times(answer.duration_s, 20.0)
    assert_allclose([p["positions"] for p in points], answer.q(exact_t), rtol=0, atol=0)
    assert_allclose([p["velocities"] for p in points], answer.dq(exact_t), rtol=0, atol=0)
    assert_allclose([p["accelerations"] for p in points], answer.ddq(exact_t), rtol=0, atol=0)
    assert_allclose([p["effort"] for p in points], rnea(answer.q(exact_t), answer.dq(exact_t), answer.ddq(exact_t)))


def test_certify_prints_the_certificate_and_the_repair_time(tmp_path: Path, capsys) -> None:
    out = tmp_path / "t.csv"
    status, stdout, _ = run(
        capsys, "--L", "0.20", "--W", "0.115", "--coefficients", "paper", "--certify", "--out", str(out)
    )
    assert status == 0  # Eq. 9 at (0.20, 0.115) is below the margin: repaired
    assert "certificate: clearance >= " in stdout and "repaired in" in stdout and "repair_seconds = " in stdout
    bound = float(stdout.split("clearance >= ")[1].split(" mm")[0])
    assert bound >= 10.0
    assert out.is_file()


def test_refused_certification_exits_1_with_the_reason(tmp_path: Path, capsys) -> None:
    out = tmp_path / "t.json"
    status, _, err = run(
        capsys, "--L", "0.30", "--W", "0.12", "--coefficients", "paper", "--certify", "--no-repair", "--out", str(out)
    )
    assert status == 1
    assert "certification refused" in err and "repair disabled" in err and err.count("\n") == 1
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_refused_end_pose_exits_1(tmp_path: Path, capsys) -> None:
    """Exact-endpoints coefficients at W = 0.12 m: the fixed pose at P5 is closer than the margin."""
    paper = load_coefficients("paper")
    constant = {"w1": 1.2, "phi1": 0.216, "A2": 3.0, "w2": 0.562}
    exact = Coefficients(
        family=EXACT_ENDPOINTS,
        parameters={name: (value, 0.0, 0.0, 0.0, 0.0, 0.0) for name, value in constant.items()},
        fitted_range_m=paper.fitted_range_m,
        scene=paper.scene,
        link_lengths_m=paper.link_lengths_m,
        link_radii_m=paper.link_radii_m,
    )
    path = tmp_path / "exact.json"
    save_coefficients(exact, path)
    status, _, err = run(capsys, "--L", "0.25", "--W", "0.12", "--coefficients", str(path), "--certify")
    assert status == 1 and "end pose at P5" in err


@pytest.mark.parametrize(
    ("argv", "named"),
    [
        (["--L", "0.27", "--W", "abc"], "--W"),
        (["--L", "0.001", "--W", "0.001"], "L = 0.001 m"),
        (["--L", "nan", "--W", "0.09"], "L = nan m"),
        (["--L", "0.27", "--W", "0.09", "--rate", "0"], "--rate"),
        (["--L", "0.27", "--W", "0.09", "--rate", "inf"], "--rate"),
        (["--L", "0.27", "--W", "0.09", "--out", "OUT.txt"], "--out"),
        (["--L", "0.27", "--W", "0.09", "--out", "/proc/x.csv"], "--out"),
        (["--L", "0.27", "--W", "0.09", "--out", "DIR"], "--out"),
        (["--L", "0.27", "--W", "0.09", "--coefficients", "/nonexistent.json"], "/nonexistent.json"),
        (["--L", "0.27", "--W", "0.09", "--no-repair"], "--no-repair"),
        (["--L", "0.27", "--W", "0.09", "--certify", "--margin", "-1"], "--margin"),
        (["--L", "0.27", "--W", "0.09", "--out-of-range", "error", "--L", "0.4"], "L = 0.4000 m"),
        (["--W", "0.09"], "--L"),
    ],
)
def test_bad_input_is_one_line_exit_2_and_no_file(tmp_path: Path, capsys, argv: list[str], named: str) -> None:
    argv = [a.replace("OUT", str(tmp_path / "out")).replace("DIR", str(tmp_path)) for a in argv]
    status, _, err = (
        run(capsys, "--coefficients", "paper", *argv) if "--coefficients" not in argv else run(capsys, *argv)
    )
    assert status == 2
    assert err.count("\n") == 1 and "Traceback" not in err and named in err, err
    assert err.startswith("python -m pipeline.generate: error:")
    assert list(tmp_path.iterdir()) == []


def test_another_arm_is_refused(double_pendulum_urdf, capsys) -> None:
    status, _, err = run(
        capsys, "--L", "0.27", "--W", "0.09", "--coefficients", "paper", "--urdf", str(double_pendulum_urdf)
    )
    assert status == 2 and "0.1, 0.2 m" in err and "0.3, 0.35 m" in err


def test_sample_times_and_ros_durations() -> None:
    assert generate_module.sample_times(1.0, 4.0).tolist() == [0.0, 0.25, 0.5, 0.75, 1.0]
    assert generate_module.sample_times(0.9, 4.0).tolist() == [0.0, 0.25, 0.5, 0.75, 0.9]
    assert generate_module.ros_duration(3.9999999999) == {"sec": 4, "nanosec": 0}
    assert generate_module.ros_duration(1.25) == {"sec": 1, "nanosec": 250_000_000}
    assert math.isclose(sum(generate_module.ros_duration(2.5e-10).values()), 0)


def test_the_package_function_survives_importing_the_cli_module() -> None:
    import pipeline
    from pipeline import generate as exported

    paper = load_coefficients("paper")
    assert exported(paper, 0.27, 0.09).trajectory.parameters == generate(paper, 0.27, 0.09).trajectory.parameters
    assert pipeline.generate(paper, 0.25, 0.1).duration_s == generate(paper, 0.25, 0.1).duration_s


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """coefficients.json (the paper's Eq. 9 as a file) with a coarse region map of it beside."""
    import shutil

    from pipeline.certify.map_files import save_region_map
    from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
    from pipeline.certify.region_map import DEFAULT_MAP_NAME
    from pipeline.offline.coefficients import paper_data_path

    folder = tmp_path_factory.mktemp("results")
    shutil.copyfile(paper_data_path("paper_eq9_coefficients.json"), folder / "coefficients.json")
    coefficients = load_coefficients(folder / "coefficients.json")
    config = RangeCertificateConfig(min_cell=1 / 16, boundary_cell=1 / 8, strip_split=0)
    save_region_map(certify_range(coefficients, config), folder / DEFAULT_MAP_NAME)
    return folder / "coefficients.json"


def test_the_maps_certified_bounds_are_printed(built: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "t.json"
    status, stdout, _ = run(capsys, "--L", "0.27", "--W", "0.09", "--coefficients", str(built), "--out", str(out))
    assert status == 0 and out.is_file()
    cell = load_coefficients(built).region_map.cell_at(0.27, 0.09)
    assert (
        f"range certificate: clearance >= {cell.clearance_bound_m * 1e3:.3f} mm over all of [0, T], "
        f"endpoint error <= {cell.endpoint_bound_m * 1e3:.3f} mm (map cell: {cell.status})"
    ) in stdout


def test_certify_in_a_margin_cell_answers_from_the_map(built: Path, capsys) -> None:
    region_map = load_coefficients(built).region_map
    cell = region_map.cell_at(0.22, 0.085)
    assert cell.status == "margin"  # Eq. 9 keeps the margin there
    status, stdout, _ = run(capsys, "--L", "0.22", "--W", "0.085", "--coefficients", str(built), "--certify")
    assert status == 0
    assert "the region map's cell keeps the margin 10.000 mm" in stdout
    assert f"clearance >= {cell.clearance_bound_m * 1e3:.3f} mm" in stdout


def _urdf_with(tmp_path: Path, name: str, old: str, new: str) -> Path:
    text = DEFAULT_URDF.read_text(encoding="utf-8")
    assert old in text
    path = tmp_path / name
    path.write_text(text.replace(old, new), encoding="utf-8")
    return path


def test_near_optimal_is_the_default_starts_and_ends_at_rest_on_the_same_path(tmp_path: Path, capsys) -> None:
    out = tmp_path / "t.npz"
    status, stdout, _ = run(capsys, "--L", "0.27", "--W", "0.09", "--coefficients", "paper", "--out", str(out))
    assert status == 0 and "timing: near-optimal" in stdout
    data = np.load(out)
    assert str(data["timing"]) == "near-optimal"
    for key in ("dq_rad_s", "ddq_rad_s2"):
        assert np.max(np.abs(data[key][[0, -1]])) == 0.0, key
    # The same configurations as the paper's timing: every sample lies on the path theta(s).
    answer = generate(load_coefficients("paper"), 0.27, 0.09)
    s = np.linspace(0.0, answer.duration_s, 200001)
    path = answer.q(s)
    nearest = np.min(np.linalg.norm(path[None, :, :] - data["q_rad"][:, None, :], axis=2), axis=1)
    assert nearest.max() < 1e-4  # 2e5 path samples: within the sampling's own spacing
    assert_allclose(data["q_rad"][[0, -1]], answer.q(np.array([0.0, answer.duration_s])), rtol=0, atol=1e-12)
    assert_allclose(data["tau_n_m"], rnea(data["q_rad"], data["dq_rad_s"], data["ddq_rad_s2"]), rtol=0, atol=1e-15)


def test_the_default_export_keeps_the_servo_defaults_and_records_them(tmp_path: Path, capsys) -> None:
    """At 100 Hz: |ddq| <= 10 rad/s^2 (the default for an arm whose URDF gives none), so consecutive
    speeds differ by at most 10 rad/s^2 x 0.01 s; the limits are printed and in every format."""
    for suffix in (".csv", ".npz", ".json"):
        out = tmp_path / f"t{suffix}"
        status, stdout, _ = run(capsys, "--L", "0.27", "--W", "0.09", "--coefficients", "paper", "--out", str(out))
        assert status == 0
        assert "acceleration 10, 10 rad/s^2 (servo default); jerk 200, 200 rad/s^3 (servo default)" in stdout
        if suffix == ".csv":
            text = out.read_text()
            assert "# acceleration_limits_rad_s2: 10.0 10.0\n" in text and "# jerk_limits_rad_s3: 200.0 200.0\n" in text
            data = np.loadtxt(out, delimiter=",", skiprows=1)  # the comment lines skipped
            named = np.genfromtxt(out, delimiter=",", names=True)
            assert_allclose(named["ddq2_rad_s2"], data[:, 6], rtol=0, atol=0)
            dq, ddq = data[:, 3:5], data[:, 5:7]
        elif suffix == ".npz":
            data = np.load(out)
            assert_allclose(data["acceleration_limits_rad_s2"], [10.0, 10.0], rtol=0, atol=0)
            assert_allclose(data["jerk_limits_rad_s3"], [200.0, 200.0], rtol=0, atol=0)
        else:
            metadata = json.loads(out.read_text())["metadata"]
            assert metadata["timing"] == "near-optimal" and metadata["jerk_limits_rad_s3"] == [200.0, 200.0]
    assert np.abs(ddq).max() <= 10.0
    assert np.abs(np.diff(dq, axis=0)).max() <= 10.0 * 0.01
    assert np.abs(dq[[0, -1]]).max() == 0.0 and np.abs(ddq[[0, -1]]).max() == 0.0


def test_a_fine_export_shows_no_acceleration_step(tmp_path: Path, capsys) -> None:
    out = tmp_path / "t.npz"
    status, stdout, _ = run(
        capsys,
        *("--L", "0.27", "--W", "0.09", "--coefficients", "paper"),
        *("--acceleration-limit", "5", "5", "--rate", "2000", "--out", str(out)),
    )
    assert status == 0 and "acceleration 5, 5 rad/s^2 (--acceleration-limit); jerk 100, 100 rad/s^3" in stdout
    ddq = np.load(out)["ddq_rad_s2"]
    assert np.abs(ddq).max() <= 5.0
    assert np.abs(np.diff(ddq, axis=0)).max() <= 0.1 * 5.0


@pytest.mark.parametrize(
    ("flag", "values"),
    [
        ("--jerk-limit", ("0", "100")),
        ("--jerk-limit", ("-1", "100")),
        ("--jerk-limit", ("nan", "100")),
        ("--jerk-limit", ("inf", "100")),
        ("--acceleration-limit", ("5", "inf")),
        ("--acceleration-limit", ("0", "5")),
    ],
)
def test_a_bad_limit_is_one_line_exit_2(tmp_path: Path, capsys, flag: str, values: tuple[str, str]) -> None:
    out = tmp_path / "t.csv"
    status, _, err = run(
        capsys, "--L", "0.27", "--W", "0.09", "--coefficients", "paper", flag, *values, "--out", str(out)
    )
    assert status == 2 and err.count("\n") == 1 and flag in err and not out.exists()


def test_a_jerk_limit_far_below_what_the_path_needs_is_refused(tmp_path: Path, capsys) -> None:
    out = tmp_path / "t.csv"
    status, _, err = run(
        capsys,
        "--L",
        "0.27",
        "--W",
        "0.09",
        "--coefficients",
        "paper",
        "--jerk-limit",
        "1e-6",
        "1e-6",
        "--out",
        str(out),
    )
    assert status == 1 and err.count("\n") == 1 and "longer than 3600 s" in err and not out.exists()


def test_a_slow_arm_refuses_the_paper_timing_and_certifies_near_optimal(tmp_path: Path, capsys) -> None:
    slow = _urdf_with(tmp_path, "slow.urdf", 'velocity="3.0"', 'velocity="0.3"')
    argv = ["--L", "0.27", "--W", "0.09", "--coefficients", "paper", "--certify", "--urdf", str(slow)]
    status, _, err = run(capsys, *argv, "--timing", "paper")
    assert status == 1 and err.count("\n") == 1
    assert "joint 2 speed bound 1.2350 rad/s > limit 0.3000 rad/s (by 0.935 rad/s)" in err
    suggested = float(err.split("keeps them in T' = ")[1].split(" s")[0])
    out = tmp_path / "t.csv"
    status, stdout, _ = run(capsys, *argv, "--out", str(out))
    assert status == 0
    duration = float(stdout.split("T' = ")[1].split(" s")[0])
    assert duration == pytest.approx(suggested, abs=5e-4)  # the hint's T' is the one the call returns
    assert duration > generate(load_coefficients("paper"), 0.27, 0.09).duration_s
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    assert np.abs(data[:, 3:5]).max() <= 0.3


def test_a_path_beyond_the_joint_limits_is_refused_with_the_joint_and_the_angle(tmp_path: Path, capsys) -> None:
    narrow = _urdf_with(tmp_path, "narrow.urdf", 'lower="-3.14159" upper="3.14159"', 'lower="-0.5" upper="0.5"')
    for timing in ("paper", "rest-to-rest", "near-optimal"):
        status, _, err = run(
            capsys,
            "--L",
            "0.27",
            "--W",
            "0.09",
            "--coefficients",
            "paper",
            "--certify",
            "--urdf",
            str(narrow),
            "--timing",
            timing,
        )
        assert status == 1, timing
        assert "joint 1 angle bound 1.6140 rad > upper limit 0.5000 rad" in err


def test_hand_edited_coefficients_missing_p5_are_refused(built: Path, tmp_path: Path, capsys) -> None:
    document = json.loads(built.read_text())
    document["parameters"]["A1"][0] += 0.05
    edited = tmp_path / "coefficients.json"
    edited.write_text(json.dumps(document), encoding="utf-8")
    status, _, err = run(capsys, "--L", "0.27", "--W", "0.09", "--coefficients", str(edited), "--certify")
    assert status == 1 and "endpoint error bound at P" in err and "> tolerance 10.000 mm" in err


def test_ros1_field_names(tmp_path: Path, capsys) -> None:
    out = tmp_path / "t.json"
    status, _, _ = run(capsys, "--L", "0.27", "--W", "0.09", "--coefficients", "paper", "--ros1", "--out", str(out))
    assert status == 0
    message = json.loads(out.read_text())
    assert set(message["header"]) == {"seq", "stamp", "frame_id"} and set(message["header"]["stamp"]) == {
        "secs",
        "nsecs",
    }
    assert all(set(p["time_from_start"]) == {"secs", "nsecs"} and len(p["effort"]) == 2 for p in message["points"])
