"""``python -m pipeline.generate --L 0.27 --W 0.09``: the online step from the command line.

Prints which coefficients it uses, the eight sinusoid parameters and T for the obstacle L x W,
and, where the region map beside the coefficients covers (L, W), its certified clearance and
endpoint-error bounds over the whole of [0, T]. With ``--certify``, the answer must keep the
margin (a cell of the map certified to keep it answers at once; elsewhere the trajectory is
certified per query with Coal and repaired if needed, unless ``--no-repair``), end within the
endpoint tolerance, and, with the chosen ``--timing``, keep the arm's joint, speed,
acceleration (``--acceleration-limit``) and torque limits over all of [0, T'].

Coefficients over more scene variables than (L, W) (``python -m pipeline.build --vary x ...``)
take their values by flag: ``--x`` the obstacle's centre x [m] (``Scene.centre_x_m``), ``--d`` its
far edge y [m] (``Scene.top_y_m``). A variable the coefficients vary without its flag, or a flag
for one they do not vary, is refused in one line (exit 2) before any work.

``--timing near-optimal`` (the default of this command) executes the same path starting and
ending at rest, as fast as the arm's limits allow along it, with continuous accelerations and
bounded jerk, certified over all of [0, T'] (:mod:`pipeline.motion.near_optimal`): what a
controller should be given. The URDF gives no acceleration or jerk limit; where none is given
(``--acceleration-limit``, ``--jerk-limit``, or the build's recorded acceleration limit) the servo
defaults are used (:meth:`pipeline.model.limits.ArmLimits.with_servo_defaults`: 10 rad/s^2, and
the acceleration limit / 50 ms), printed, and written into the file. ``--timing rest-to-rest``
scales the paper's speed with smooth ramps at the ends; ``--timing paper`` (the default of
:func:`pipeline.generate`) starts and ends at the path's full speed, a velocity step for an arm
at rest. With ``--out FILE`` it writes the trajectory sampled at ``--rate`` (t = 0, 1/rate,
2/rate, ... and T' itself as the last sample), in the format the suffix names:

* ``.csv``: the header ``t_s, q1_rad, q2_rad, dq1_rad_s, dq2_rad_s, ddq1_rad_s2, ddq2_rad_s2,
  tau1_n_m, tau2_n_m`` (units in the names), ``#`` comment lines with the timing and the limits it
  keeps, then one row per sample (``numpy.loadtxt(f, delimiter=",", skiprows=1)``,
  ``numpy.genfromtxt(f, delimiter=",", names=True)`` and ``pandas.read_csv(f, comment="#")`` skip
  the comments);
* ``.npz``: arrays ``t_s`` (n,), ``q_rad``, ``dq_rad_s``, ``ddq_rad_s2``, ``tau_n_m`` (n, 2),
  ``parameters`` (8,) with ``parameter_names``, ``duration_s``, ``path_duration_s``, ``timing``,
  ``joint_names``, the obstacle's scene variables ``variables_m`` (k,) [m] with
  ``variable_names`` (``L``, ``W``, then ``x`` and ``d`` when the coefficients vary them), and
  the limits ``velocity_limits_rad_s``, ``acceleration_limits_rad_s2``, ``effort_limits_n_m``,
  ``jerk_limits_rad_s3`` (2,) (inf: none);
* ``.json``: a ROS ``trajectory_msgs/JointTrajectory`` (``header``, ``joint_names`` from the URDF,
  ``points`` with ``positions`` [rad], ``velocities`` [rad/s], ``accelerations`` [rad/s^2],
  ``effort`` [N m] and ``time_from_start`` as ``{"sec", "nanosec"}``), and beside the message's
  fields a ``metadata`` object with the timing and the limits (not a message field: a ROS
  consumer drops it);
* ``.mcap`` or ``.db3``: a ROS 2 bag (rosbag2, MCAP or SQLite 3 storage; needs ``pip install
  'twolink-obstacle[ros]'``), a folder of that name (:mod:`pipeline.io.rosbag_export`): the same
  ``JointTrajectory`` as one ``trajectory_msgs/msg/JointTrajectory`` message on ``--topic``, with
  ``--joint-states`` also one ``sensor_msgs/msg/JointState`` per sample on ``/joint_states``
  (stamped with the sample times), and the timing, the limits and the obstacle in the bag's
  custom metadata. An existing bag is refused (exit 2, before any work), never replaced.

The file is written atomically (a temporary file in the same folder, then a rename; a bag: a
temporary folder, then a rename), only after everything else succeeded. Exit status: 0 done; 1
certification refused (the reason on stderr, no file written), or no timing of the chosen kind
keeps the limits; 2 bad input (one line on stderr, no file written); 130 interrupted.
"""

from __future__ import annotations

import argparse
import csv
import io
import math
import sys
import time
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import MappingProxyType

import numpy as np

from pipeline.cli import (
    DEFAULT_COEFFICIENTS,
    EXIT_FAILED,
    EXIT_OK,
    Parser,
    add_acceleration_limit_argument,
    add_jerk_limit_argument,
    arm_for_cli,
    check_output_file,
    describe_coefficients,
    limits_from_options,
    load_coefficients_for_cli,
    run_cli,
)
from pipeline.exceptions import ExecutionRefusedError, InvalidParameterError, NoCertifiedTrajectoryError
from pipeline.io.jsonio import dumps, write_bytes_atomic
from pipeline.io.rosbag_export import (
    BAG_STORAGE,
    DEFAULT_TRAJECTORY_TOPIC,
    JOINT_STATES_TOPIC,
    TrajectoryBag,
    check_topic,
    custom_data_text,
    duration_parts,
    require_rosbags,
    write_bag,
)
from pipeline.model.arm import PlanarArm
from pipeline.model.dynamics import rnea_torques
from pipeline.model.limits import DEFAULT_ACCELERATION_RAD_S2, SHORTEST_ACCELERATION_RISE_S, ArmLimits
from pipeline.motion.near_optimal import NEAR_OPTIMAL, NearOptimal
from pipeline.motion.rest_to_rest import REST_TO_REST
from pipeline.motion.timed_trajectory import TimedTrajectory
from pipeline.motion.timing import PAPER_TIMING
from pipeline.motion.trajectory import PARAMETER_NAMES, PARAMETER_UNITS
from pipeline.offline.coefficients import Coefficients
from pipeline.online.execution import retime
from pipeline.online.generator import OUT_OF_RANGE_POLICIES, generate
from pipeline.online.repair import RepairConfig, generate_certified

PROG = "python -m pipeline.generate"
#: Output formats, by file suffix (``.mcap``, ``.db3``: ROS 2 bags, folders).
FORMATS = (".csv", ".npz", ".json", *BAG_STORAGE)
#: Default sampling rate of the written trajectory [Hz].
DEFAULT_RATE_HZ = 100.0
#: Most samples a written trajectory may hold (about 56 MB as NPZ, more as JSON).
MAX_SAMPLES = 1_000_000
#: Tolerance of the certificate the CLI prints [m]: the bound is within this of the sampled minimum.
CLI_CERTIFICATE_TOLERANCE_M = 1e-5
#: Columns of the CSV file (units in the names).
CSV_COLUMNS = (
    "t_s",
    "q1_rad",
    "q2_rad",
    "dq1_rad_s",
    "dq2_rad_s",
    "ddq1_rad_s2",
    "ddq2_rad_s2",
    "tau1_n_m",
    "tau2_n_m",
)
#: The timings of ``--timing``.
TIMINGS = MappingProxyType({"near-optimal": NEAR_OPTIMAL, "rest-to-rest": REST_TO_REST, "paper": PAPER_TIMING})
#: The scene variables beyond (L, W) this command takes: name -> (flag, meaning).
SCENE_VARIABLE_FLAGS = MappingProxyType(
    {
        "x": ("--x", "the obstacle's centre x"),
        "d": ("--d", "the obstacle's far edge y"),
    }
)


def sample_times(duration_s: float, rate_hz: float) -> np.ndarray:
    """t = 0, 1/rate, 2/rate, ... below T, then T itself [s] (each k / rate computed directly)."""
    count = math.floor(duration_s * rate_hz)
    times = np.arange(count + 1) / rate_hz
    times = times[times < duration_s]
    return np.append(times, duration_s)


def ros_duration(t_s: float, ros1: bool = False) -> dict[str, int]:
    """A ROS 2 ``builtin_interfaces/Duration``: {"sec", "nanosec"} with 0 <= nanosec < 1e9
    (ROS 1's ``duration``: {"secs", "nsecs"})."""
    seconds, nanoseconds = duration_parts(t_s)
    return {"secs": seconds, "nsecs": nanoseconds} if ros1 else {"sec": seconds, "nanosec": nanoseconds}


def joint_names(arm: PlanarArm | None) -> list[str]:
    """The URDF's names of the two joints (``joint1``, ``joint2`` without an arm)."""
    if arm is None:
        return ["joint1", "joint2"]
    return [str(arm.model.names[1]), str(arm.model.names[2])]


def export_metadata(executed, limits: ArmLimits | None) -> dict:
    """What every written file records beside the samples: the timing, T', T and the limits the
    motion keeps [rad/s, rad/s^2, N m, rad/s^3] (None: none, or no arm loaded)."""

    def pair(name: str) -> list[float | None] | None:
        if limits is None:
            return None
        return [float(v) if math.isfinite(v) else None for v in getattr(limits, name)]

    return {
        "timing": executed.timing.name,
        "duration_s": float(executed.duration_s),
        "path_duration_s": float(executed.trajectory.duration_s),
        "velocity_limits_rad_s": pair("velocity_rad_s"),
        "acceleration_limits_rad_s2": pair("acceleration_rad_s2"),
        "effort_limits_n_m": pair("effort_n_m"),
        "jerk_limits_rad_s3": pair("jerk_rad_s3"),
    }


def trajectory_document(samples: dict, names: Sequence[str], ros1: bool = False) -> dict:
    """The samples as a ROS ``trajectory_msgs/JointTrajectory`` message (plain JSON; ROS 2 field
    names, or ROS 1's with ``ros1``), torques in ``effort``."""
    stamp = {"secs": 0, "nsecs": 0} if ros1 else {"sec": 0, "nanosec": 0}
    header = {"seq": 0, "stamp": stamp, "frame_id": ""} if ros1 else {"stamp": stamp, "frame_id": ""}
    return {
        "header": header,
        "joint_names": list(names),
        "points": [
            {
                "positions": samples["q"][i].tolist(),
                "velocities": samples["dq"][i].tolist(),
                "accelerations": samples["ddq"][i].tolist(),
                "effort": samples["tau"][i].tolist(),
                "time_from_start": ros_duration(float(t), ros1),
            }
            for i, t in enumerate(samples["t"])
        ],
    }


def sample(executed, arm: PlanarArm, rate_hz: float) -> dict:
    """The executed trajectory at ``rate_hz`` (T' the last sample): t, q, dq, ddq and RNEA torques."""
    times = sample_times(executed.duration_s, rate_hz)
    q, dq, ddq = executed.states(times)
    return {"t": times, "q": q, "dq": dq, "ddq": ddq, "tau": rnea_torques(arm, q, dq, ddq)}


def encode(
    path: Path,
    executed,
    samples: dict,
    names: Sequence[str],
    ros1: bool = False,
    variables: Mapping[str, float] | None = None,
    limits: ArmLimits | None = None,
) -> bytes:
    """The file's bytes in the format of ``path``'s suffix; the NPZ records ``variables``, the
    obstacle's scene variables (name -> value [m]: L, W and those of ``--x``, ``--d``); every
    format records :func:`export_metadata` (the timing and ``limits``)."""
    suffix = path.suffix.lower()
    metadata = export_metadata(executed, limits)
    if suffix == ".json":
        return dumps({**trajectory_document(samples, names, ros1), "metadata": metadata}).encode("utf-8")
    times, q, dq, ddq, tau = (samples[k] for k in ("t", "q", "dq", "ddq", "tau"))
    if suffix == ".npz":
        buffer = io.BytesIO()
        np.savez(
            buffer,
            t_s=times,
            q_rad=q,
            dq_rad_s=dq,
            ddq_rad_s2=ddq,
            tau_n_m=tau,
            parameters=np.array(executed.parameters),
            parameter_names=np.array(PARAMETER_NAMES),
            duration_s=np.array(executed.duration_s),
            path_duration_s=np.array(executed.trajectory.duration_s),
            timing=np.array(executed.timing.name),
            joint_names=np.array(list(names)),
            variables_m=np.array([float(v) for v in (variables or {}).values()]),
            variable_names=np.array(list(variables or {}), dtype=str),
            **{
                key: np.array([np.inf if v is None else v for v in value], dtype=float)
                for key, value in metadata.items()
                if "_limits_" in key and value is not None
            },
        )
        return buffer.getvalue()
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for key, value in metadata.items():
        shown = value if not isinstance(value, list) else " ".join("none" if v is None else repr(v) for v in value)
        text.write(f"# {key}: {shown}\n")
    for row in np.column_stack([times, q, dq, ddq, tau]):
        writer.writerow([repr(float(v)) for v in row])
    return text.getvalue().encode("utf-8")


def add_scene_variable_arguments(parser: argparse.ArgumentParser) -> None:
    """``--x`` and ``--d`` [m]: the values of the scene variables beyond (L, W), for coefficients
    that vary them (read back by :func:`scene_variables`)."""
    for name, (flag, meaning) in SCENE_VARIABLE_FLAGS.items():
        parser.add_argument(
            flag,
            type=float,
            default=None,
            dest=name,
            metavar="M",
            help=f"{meaning} [m], for coefficients that vary {name} (python -m pipeline.build --vary {name}): "
            f"required for those, refused for others (default: none; the coefficients' scene holds it fixed)",
        )


def add_bag_arguments(parser: argparse.ArgumentParser) -> None:
    """``--topic`` and ``--joint-states``: what a ROS 2 bag ``--out`` (``.mcap``, ``.db3``) holds."""
    parser.add_argument(
        "--topic",
        metavar="TOPIC",
        default=None,
        help="with a .mcap or .db3 --out: the topic of the JointTrajectory message, fully qualified "
        f"(default: {DEFAULT_TRAJECTORY_TOPIC})",
    )
    parser.add_argument(
        "--joint-states",
        action="store_true",
        help=f"with a .mcap or .db3 --out: also record one sensor_msgs/msg/JointState per sample on "
        f"{JOINT_STATES_TOPIC}, stamped with the sample times",
    )


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface of ``python -m pipeline.generate``."""
    p = Parser(
        prog=PROG,
        description="The online step: the trajectory for the obstacle L x W from the regression coefficients, "
        "optionally certified (and repaired), printed and written sampled at a rate (CSV, NPZ, ROS JSON or a "
        "ROS 2 bag).",
    )
    p.add_argument("--L", type=float, required=True, metavar="M", help="obstacle length L [m]")
    p.add_argument("--W", type=float, required=True, metavar="M", help="obstacle width W [m]")
    add_scene_variable_arguments(p)
    p.add_argument(
        "--coefficients",
        metavar="FILE",
        default=DEFAULT_COEFFICIENTS,
        help="coefficients file, or 'paper' for the paper's Eq. 9",
    )
    p.add_argument(
        "--urdf",
        metavar="U",
        default=None,
        help="the arm's URDF (default: the one recorded with the coefficients; given, it must match them)",
    )
    p.add_argument(
        "--certify",
        action="store_true",
        help="certify the clearance over all of [0, T] (Coal); repair the trajectory if it is below the margin",
    )
    p.add_argument("--no-repair", action="store_true", help="with --certify: refuse instead of repairing")
    p.add_argument(
        "--margin",
        type=float,
        default=None,
        metavar="M",
        help="with --certify: clearance to certify [m] (default: the coefficients' scene margin)",
    )
    p.add_argument(
        "--timing",
        choices=tuple(TIMINGS),
        default="near-optimal",
        help="timing of the printed and written trajectory: near-optimal (at rest at both ends, as fast as the "
        "limits allow along the path, continuous accelerations, certified: what a controller should get), "
        "rest-to-rest (the paper's speed scaled, smooth ramps at the ends) or paper (the path's full speed from "
        "t = 0, the generator's own timing)",
    )
    add_acceleration_limit_argument(
        p,
        "default: those recorded with the coefficients by python -m pipeline.build --acceleration-limit, else none; "
        f"the near-optimal timing then uses {DEFAULT_ACCELERATION_RAD_S2:g} rad/s^2",
    )
    add_jerk_limit_argument(
        p,
        "default: none; the near-optimal timing then uses the acceleration limit / "
        f"{SHORTEST_ACCELERATION_RISE_S:g} s (the acceleration rises from zero to its limit in at least "
        f"{1e3 * SHORTEST_ACCELERATION_RISE_S:g} ms)",
    )
    p.add_argument("--ros1", action="store_true", help="ROS 1 field names in the .json (secs/nsecs, header seq)")
    add_bag_arguments(p)
    p.add_argument(
        "--out-of-range",
        choices=OUT_OF_RANGE_POLICIES,
        default="warn",
        help="outside the fitted range: warn, refuse (error) or ignore",
    )
    p.add_argument(
        "--rate",
        type=float,
        default=DEFAULT_RATE_HZ,
        metavar="HZ",
        help=f"sampling rate of --out [Hz], at most {MAX_SAMPLES:,} samples in all",
    )
    p.add_argument(
        "--out",
        metavar="FILE",
        default=None,
        help="write the sampled trajectory; the suffix picks the format: .csv, .npz, .json (ROS JointTrajectory), "
        ".mcap or .db3 (a ROS 2 bag folder, MCAP or SQLite 3 storage: pip install 'twolink-obstacle[ros]'; "
        "never replaced)",
    )
    return p


def _check_inputs(args: argparse.Namespace) -> Path | None:
    """Every check that needs no work: rate, margin, output path and format. Returns the output path."""
    if not (math.isfinite(args.rate) and args.rate > 0.0):
        raise InvalidParameterError("--rate", args.rate, "a positive finite rate [Hz]")
    if args.margin is not None and not (math.isfinite(args.margin) and args.margin >= 0.0):
        raise InvalidParameterError("--margin", args.margin, "a non-negative finite clearance [m]")
    if args.no_repair and not args.certify:
        raise InvalidParameterError("--no-repair", True, "used with --certify")
    bag = args.out is not None and Path(args.out).suffix.lower() in BAG_STORAGE
    if not bag:
        for flag, given in (("--topic", args.topic), ("--joint-states", args.joint_states or None)):
            if given is not None:
                raise InvalidParameterError(flag, given, f"used with a --out ending in {' or '.join(BAG_STORAGE)}")
    if args.out is None:
        return None
    out = Path(args.out)
    if out.suffix.lower() not in FORMATS:
        raise InvalidParameterError("--out", str(out), f"a file name ending in one of {', '.join(FORMATS)}")
    if bag:
        _check_bag_output(args, out)
        return out
    out = check_output_file(args.out, "--out")  # probes the folder: /proc is refused now, not after the work
    return out


def _check_bag_output(args: argparse.Namespace, out: Path) -> None:
    """The checks of a ROS 2 bag ``--out`` (before any work): rosbags installed, no --ros1, a valid
    --topic, and a path that does not exist yet in a writable folder."""
    require_rosbags()
    if args.ros1:
        raise InvalidParameterError("--ros1", True, "a .json --out (a ROS 2 bag holds ROS 2 messages)")
    check_topic(DEFAULT_TRAJECTORY_TOPIC if args.topic is None else args.topic)
    if out.exists() or out.is_symlink():
        raise InvalidParameterError(
            "--out", str(out), "a path that does not exist yet (a ROS 2 bag is a folder and is never replaced)"
        )
    check_output_file(out, "--out")  # the folder exists and is writable


def scene_variables(coefficients: Coefficients, args: argparse.Namespace) -> dict[str, float]:
    """The values of ``--x`` and ``--d`` [m] for the call to :func:`generate`, checked against the
    variables ``coefficients`` vary (before any work): name -> value, in the canonical order.

    Raises:
        InvalidParameterError: a variable of the coefficients without its flag, a flag for one
            they do not vary, or a value that is not finite (the message names the flag).
    """
    varied = coefficients.variables
    given = {name: getattr(args, name) for name in SCENE_VARIABLE_FLAGS if getattr(args, name) is not None}
    for name, value in given.items():
        flag = SCENE_VARIABLE_FLAGS[name][0]
        if name not in varied.extra:
            raise InvalidParameterError(
                flag, value, f"no {flag}: the coefficients vary {', '.join(varied.names)} only, not {name}"
            )
        if not math.isfinite(value):
            raise InvalidParameterError(flag, value, f"a finite value [m] ({SCENE_VARIABLE_FLAGS[name][1]})")
    for name in varied.extra:
        if name not in given:
            flag, meaning = SCENE_VARIABLE_FLAGS[name]
            raise InvalidParameterError(
                flag, None, f"{meaning} [m]: the coefficients vary {', '.join(varied.names)} ({flag} is required)"
            )
    return {name: float(given[name]) for name in varied.extra}


def _obstacle_line(generated, values: dict[str, float]) -> str:
    """The obstacle in one line: L, W and the values of the extra variables [m]."""
    extra = "".join(f", {name} = {value!r} m" for name, value in values.items())
    return f"obstacle L = {generated.length_m!r} m, W = {generated.width_m!r} m{extra}" + (
        " (outside the fitted range: extrapolated)" if generated.extrapolated else ""
    )


def _range_line(generated) -> str:
    """What the region map certifies for this answer, in one line."""
    if generated.certificate_source is None:
        return "range certificate: none for this answer (no region map beside the coefficients, or outside its range)"
    return (
        f"range certificate: clearance >= {generated.certified_clearance_m * 1e3:.3f} mm over all of [0, T], "
        f"endpoint error <= {generated.endpoint_error_bound_m * 1e3:.3f} mm (map cell: {generated.range_status})"
    )


def _execution_lines(certified) -> list[str]:
    """What the execution certificate proves, in words."""
    execution = certified.execution
    certificate, limits = execution.certificate, execution.limits
    (lo1, hi1), (lo2, hi2) = certificate.angle_range_rad

    def pair(values, limit, unit: str) -> str:
        return ", ".join(f"{v:.4f} (limit {lim:g}) {unit}" for v, lim in zip(values, limit, strict=True))

    measured, bounds = execution.endpoint_errors_m, execution.endpoint_error_bounds_m
    return [
        f"executes: endpoint errors {1e3 * measured[0]:.3f} mm at P1, {1e3 * measured[1]:.3f} mm at P5 "
        f"(bounds {1e3 * bounds[0]:.3f}, {1e3 * bounds[1]:.3f} mm <= tolerance "
        f"{1e3 * execution.endpoint_tolerance_m:.3f} mm)",
        f"  {certificate.timing_name} timing, T' = {certificate.duration_s:.6f} s; over all of [0, T']: "
        f"q1 in [{lo1:.4f}, {hi1:.4f}] rad, q2 in [{lo2:.4f}, {hi2:.4f}] rad",
        f"  |dq| <= {pair(certificate.speed_bound_rad_s, limits.velocity_rad_s, 'rad/s')}",
        f"  |ddq| <= {pair(certificate.acceleration_bound_rad_s2, limits.acceleration_rad_s2, 'rad/s^2')}",
        f"  |tau| <= {pair(certificate.torque_bound_n_m, limits.effort_n_m, 'N m')} (RNEA, no gravity: vertical axes)",
        f"  |jerk| <= {pair(certificate.jerk_bound_rad_s3, limits.jerk_rad_s3, 'rad/s^3')}",
    ]


def _limits(args: argparse.Namespace, arm: PlanarArm | None, coefficients: Coefficients, timing):
    """The limits the motion is held to (None without an arm), and where each kind comes from."""
    if arm is None:
        return None, {}
    limits = limits_from_options(arm, coefficients, args.acceleration_limit, args.jerk_limit)
    given = args.acceleration_limit is not None
    recorded = not given and math.isfinite(limits.acceleration_rad_s2[0])
    sources = {
        "acceleration": "--acceleration-limit" if given else "recorded by the build" if recorded else "none given",
        "jerk": "none given" if args.jerk_limit is None else "--jerk-limit",
        "speed": "URDF",
        "effort": "URDF",
    }
    if isinstance(timing, NearOptimal):
        for kind in ("acceleration", "jerk"):
            if sources[kind] == "none given":
                sources[kind] = "servo default"
        limits = limits.with_servo_defaults()
    return limits, sources


def _limits_line(limits: ArmLimits, sources: dict[str, str]) -> str:
    """The limits in one line, each with where it comes from."""
    parts = []
    for kind, values, unit in (
        ("speed", limits.velocity_rad_s, "rad/s"),
        ("acceleration", limits.acceleration_rad_s2, "rad/s^2"),
        ("jerk", limits.jerk_rad_s3, "rad/s^3"),
        ("effort", limits.effort_n_m, "N m"),
    ):
        shown = "none" if math.isinf(values[0]) and math.isinf(values[1]) else f"{values[0]:g}, {values[1]:g} {unit}"
        parts.append(f"{kind} {shown} ({sources[kind]})")
    return "limits: " + "; ".join(parts)


def _certificate_line(certified) -> str:
    """Where the answer's clearance certificate comes from: the map's cell, or the per-query
    certificate of the regression's answer or of its repair."""
    if certified.certificate is None:
        return (
            f"certificate: the region map's cell keeps the margin {certified.margin_m * 1e3:.3f} mm "
            f"(clearance >= {certified.certified_clearance_m * 1e3:.3f} mm over all of [0, T]): the regression's "
            "answer, unchanged"
        )
    certificate = certified.certificate
    source = (
        f"repaired in {certified.repair_seconds * 1e3:.1f} ms (the regression's answer: "
        f"{certified.regression_certificate.certified_clearance_m * 1e3:.3f} mm)"
        if certified.repaired
        else "the regression's answer, unchanged"
    )
    return (
        f"certificate: clearance >= {certificate.certified_clearance_m * 1e3:.3f} mm over all of [0, T] "
        f"(rigorous lower bound, link {certificate.bound_link} at t = {certificate.bound_time_s:.4f} s; "
        f"margin {certified.margin_m * 1e3:.3f} mm; {certificate.evaluations} Coal configurations): {source}"
    )


def work(args: argparse.Namespace) -> int:
    """Generate (and certify), print, write; see the module docstring for the exit status."""
    out = _check_inputs(args)
    coefficients = load_coefficients_for_cli(args.coefficients)
    values = scene_variables(coefficients, args)
    print(describe_coefficients(coefficients))
    timing = TIMINGS[args.timing]
    needs_arm = args.certify or args.urdf is not None or out is not None or timing is not PAPER_TIMING
    arm = arm_for_cli(coefficients, args.urdf) if needs_arm else None
    limits, sources = _limits(args, arm, coefficients, timing)
    if limits is not None:
        print(_limits_line(limits, sources))
    started = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        generated = generate(coefficients, args.L, args.W, **values, out_of_range=args.out_of_range)
    for warning in caught:
        print(f"{PROG}: warning: {warning.message}", file=sys.stderr)
    trajectory = generated.trajectory
    certified = None
    if args.certify:
        config = RepairConfig(
            margin_m=args.margin, repair=not args.no_repair, certificate_tolerance_m=CLI_CERTIFICATE_TOLERANCE_M
        )
        try:
            certified = generate_certified(
                coefficients,
                args.L,
                args.W,
                arm,
                **values,
                out_of_range="ignore",
                config=config,
                timing=timing,
                limits=limits,
            )
        except (NoCertifiedTrajectoryError, ExecutionRefusedError) as exc:
            print(f"{PROG}: certification refused: {exc}", file=sys.stderr)
            return EXIT_FAILED
        trajectory = certified.trajectory
        executed = certified.executed
    elif arm is not None:
        try:
            executed = retime(generated, arm, limits, timing)
        except ExecutionRefusedError as exc:
            print(f"{PROG}: timing refused: {exc}", file=sys.stderr)
            return EXIT_FAILED
    else:
        executed = TimedTrajectory(trajectory, PAPER_TIMING)
    elapsed = time.perf_counter() - started

    print(_obstacle_line(generated, values))
    for name, value in trajectory.as_dict().items():
        print(f"  {name:<7s}= {value: .9f} {PARAMETER_UNITS[name]}")
    print(f"T = {trajectory.duration_s:.9f} s (the path at the paper's speed)")
    print(f"timing: {executed.timing.name}, T' = {executed.duration_s:.9f} s")
    print(_range_line(generated))
    if certified is not None:
        print("\n".join([_certificate_line(certified), *_execution_lines(certified)]))
        print(f"repair_seconds = {certified.repair_seconds:.6f}")
    print(f"time: {elapsed * 1e3:.3f} ms")
    if out is not None:
        if executed.duration_s * args.rate + 1.0 > MAX_SAMPLES:
            raise InvalidParameterError(
                "--rate",
                args.rate,
                f"a rate giving at most {MAX_SAMPLES:,} samples over T' = {executed.duration_s:.3f} s",
            )
        samples = sample(executed, arm, args.rate)
        variables = {"L": generated.length_m, "W": generated.width_m, **values}
        write_output(out, executed, samples, joint_names(arm), args, variables, limits)
        print(f"wrote {out} ({samples['t'].size} samples at {args.rate:g} Hz, the last at T')")
    return EXIT_OK


def bag_content(
    executed,
    samples: dict,
    names: Sequence[str],
    topic: str = DEFAULT_TRAJECTORY_TOPIC,
    joint_states: bool = False,
    variables: Mapping[str, float] | None = None,
    limits: ArmLimits | None = None,
) -> TrajectoryBag:
    """The samples as a ROS 2 bag's content: the JointTrajectory on ``topic`` (and the joint
    states), with :func:`export_metadata` and the obstacle's ``variables`` [m] (as ``variables_m``,
    name -> value) in the bag's custom metadata."""
    metadata = {**export_metadata(executed, limits), "variables_m": dict(variables or {})}
    return TrajectoryBag(
        times_s=samples["t"],
        positions_rad=samples["q"],
        velocities_rad_s=samples["dq"],
        accelerations_rad_s2=samples["ddq"],
        efforts_n_m=samples["tau"],
        joint_names=tuple(names),
        topic=topic,
        joint_states=joint_states,
        custom_data=custom_data_text(metadata),
    )


def write_output(
    out: Path,
    executed,
    samples: dict,
    names: Sequence[str],
    args: argparse.Namespace,
    variables: Mapping[str, float],
    limits: ArmLimits | None,
) -> None:
    """Write ``--out`` in the format of its suffix: a file (:func:`encode`, atomically) or a ROS 2 bag
    folder (:func:`bag_content`, :func:`pipeline.io.rosbag_export.write_bag`).

    Raises:
        InvalidParameterError: the output cannot be written (the OS's reason in the message).
        OutputExistsError: a bag's folder appeared after the checks.
    """
    try:
        if out.suffix.lower() in BAG_STORAGE:
            topic = DEFAULT_TRAJECTORY_TOPIC if args.topic is None else args.topic
            write_bag(out, bag_content(executed, samples, names, topic, args.joint_states, variables, limits))
        else:
            write_bytes_atomic(out, encode(out, executed, samples, names, args.ros1, variables, limits))
    except OSError as exc:
        raise InvalidParameterError("--out", str(out), f"a writable file ({exc.strerror})") from None


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    return run_cli(build_parser(), work, argv)


if __name__ == "__main__":
    sys.exit(main())
