"""Show one generated trajectory in Meshcat: live, as a self-contained HTML page, or as a
screenshot.

    python -m verify.view --L 0.27 --W 0.09 [--coefficients FILE]   (default: results/coefficients.json)
    python -m verify.view --L 0.27 --W 0.09 --html view.html
    python -m verify.view --L 0.27 --W 0.09 --x 0.02 --coefficients results-x/coefficients.json
    python -m verify.view --paper-test1 --screenshot docs/viewer.png

Live, a Meshcat server starts on 127.0.0.1 only, its URL is printed, and the scene stays
up until Ctrl-C (or ``--hold`` seconds); the server process is then terminated. The scene:
the arm from the URDF, the rounded obstacle at its true size and place (``--x``, ``--d`` for
coefficients that vary the obstacle's centre x or far edge y), the desired and
the actual end-effector paths, the five constraint points, the point of minimum clearance
with its distance, and the trajectory as an animation (Animations > default: play, pause,
scrub the time).

This module only parses the command line and calls :mod:`verify.viewer`. SIGTERM is turned
into a clean stop (the server process is terminated) from the start of the command, before the
server is announced.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import threading
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from pipeline import load_coefficients
from pipeline.cli import (
    DEFAULT_COEFFICIENTS,
    EXIT_FAILED,
    EXIT_OK,
    Parser,
    add_acceleration_limit_argument,
    add_jerk_limit_argument,
    describe_coefficients,
    limits_from_options,
    run_cli,
)
from pipeline.commands.generate import SCENE_VARIABLE_FLAGS, add_scene_variable_arguments, scene_variables
from pipeline.exceptions import InvalidParameterError, OutOfFittedRangeWarning
from pipeline.io.output_paths import check_output_file
from pipeline.motion.families import PAPER_SOURCE
from verify.cli_support import arm_for_verify, load_coefficients_for_verify

PROG = "python -m verify.view"


def _size(text: str) -> tuple[int, int]:
    try:
        width, height = (int(part) for part in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT in pixels, e.g. 1200x800, got {text!r}") from None
    if width < 64 or height < 64:
        raise argparse.ArgumentTypeError(f"image size {text!r} too small: at least 64x64 px")
    return width, height


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = Parser(
        prog=PROG,
        description="Show a generated trajectory around the rounded obstacle in Meshcat (live on "
        "127.0.0.1, as a self-contained HTML file, or as a PNG screenshot).",
    )
    _add_trajectory_arguments(parser)
    _add_output_arguments(parser)
    _add_joint_plot_arguments(parser)
    _add_scene_arguments(parser)
    return parser


def _add_trajectory_arguments(parser: argparse.ArgumentParser) -> None:
    """Which trajectory to show: the obstacle (L, W [m] and the scene variables), the coefficients
    or the paper's Test 1, and the arm's URDF."""
    parser.add_argument(
        "--L", type=float, metavar="METRES", help="obstacle length L [m], > 0 (required unless --paper-test1)"
    )
    parser.add_argument(
        "--W", type=float, metavar="METRES", help="obstacle width W [m], > 0 (required unless --paper-test1)"
    )
    add_scene_variable_arguments(parser)
    parser.add_argument(
        "--coefficients",
        default=DEFAULT_COEFFICIENTS,
        metavar="FILE",
        help=f"coefficients file of the generator, or '{PAPER_SOURCE}' for the paper's Eq. 9",
    )
    parser.add_argument(
        "--paper-test1",
        action="store_true",
        help="show the paper's published Table 2 Test 1 trajectory (L = 0.30 m, W = 0.12 m) instead of a generated one",
    )
    parser.add_argument(
        "--urdf",
        type=Path,
        default=None,
        metavar="FILE",
        help="URDF of the arm (default: the one recorded with the coefficients; given, it must match them)",
    )


def _add_output_arguments(parser: argparse.ArgumentParser) -> None:
    """Where it goes instead of a live server: an HTML file, a PNG screenshot or a joint plot."""
    output = parser.add_mutually_exclusive_group()
    output.add_argument(
        "--html",
        type=Path,
        metavar="FILE",
        help="write the scene as one self-contained HTML file instead of serving it",
    )
    output.add_argument(
        "--screenshot",
        type=Path,
        metavar="PNG",
        help="write a PNG screenshot of the exported page (headless Chromium) instead of serving it",
    )
    output.add_argument(
        "--joint-plot",
        type=Path,
        metavar="PNG",
        help="write a PNG of q, dq, ddq and tau (RNEA) against time, with the arm's limits and the certified "
        "bounds, instead of the scene (certifies the answer: exit 1 if refused)",
    )


def _add_joint_plot_arguments(parser: argparse.ArgumentParser) -> None:
    """The joint plot's timing and limits (acceleration [rad/s^2], jerk [rad/s^3])."""
    parser.add_argument(
        "--timing",
        choices=("near-optimal", "rest-to-rest", "paper"),
        default="near-optimal",
        help="--joint-plot: the timing to plot (default: near-optimal, what python -m pipeline.generate exports)",
    )
    add_acceleration_limit_argument(
        parser,
        "--joint-plot's limits (default: those recorded with the coefficients; the near-optimal timing fills in "
        "the servo default, 10 rad/s^2)",
    )
    add_jerk_limit_argument(
        parser, "--joint-plot's limits (default: none; the near-optimal timing fills in the acceleration limit / 50 ms)"
    )


def _add_scene_arguments(parser: argparse.ArgumentParser) -> None:
    """How the scene is drawn and served: screenshot size [px], style, serving time [s], frame rate
    [1/s], samples per path and autoplay."""
    parser.add_argument(
        "--size", type=_size, default=(1200, 800), metavar="WxH", help="screenshot size [px] (default: 1200x800)"
    )
    parser.add_argument(
        "--flat",
        action="store_true",
        help="flat unlit colours, no grid, axes or background (the pixel test's style)",
    )
    parser.add_argument(
        "--hold",
        type=float,
        default=None,
        metavar="SECONDS",
        help="live mode: stop the server after this many seconds [s] (default: run until Ctrl-C)",
    )
    parser.add_argument("--fps", type=int, default=30, help="animation frame rate [1/s]")
    parser.add_argument(
        "--samples",
        type=int,
        default=400,
        help="points per path, and time samples of the (sampled, not certified) minimum clearance [samples]",
    )
    parser.add_argument(
        "--no-play", action="store_true", help="do not start the animation on load (default: it plays once)"
    )


def _check_args(args: argparse.Namespace) -> None:
    """Raise InvalidParameterError, named after the option, on values argparse cannot check."""
    if args.paper_test1:
        for name in ("L", "W"):
            if getattr(args, name) is not None:
                raise InvalidParameterError(
                    f"--{name}", getattr(args, name), "no value with --paper-test1 (it fixes L and W)"
                )
        for name, (flag, _) in SCENE_VARIABLE_FLAGS.items():
            if getattr(args, name) is not None:
                raise InvalidParameterError(
                    flag, getattr(args, name), "no value with --paper-test1 (the paper's scene)"
                )
    else:
        for name in ("L", "W"):
            value = getattr(args, name)
            if value is None:
                raise InvalidParameterError(f"--{name}", None, f"a length in metres: --{name} is required")
            if not math.isfinite(value) or value <= 0:
                raise InvalidParameterError(f"--{name}", value, "a positive finite length [m]")
    if args.hold is not None and not (math.isfinite(args.hold) and args.hold > 0):
        raise InvalidParameterError("--hold", args.hold, "a positive number of seconds")
    if args.fps < 1:
        raise InvalidParameterError("--fps", args.fps, "an integer >= 1")
    if args.samples < 16:
        raise InvalidParameterError("--samples", args.samples, "an integer >= 16")
    check_output_file(args.html, "--html")
    check_output_file(args.screenshot, "--screenshot")
    check_output_file(args.joint_plot, "--joint-plot")
    if args.joint_plot is not None and args.paper_test1:
        raise InvalidParameterError("--joint-plot", str(args.joint_plot), "a generated trajectory (not --paper-test1)")


@contextmanager
def _sigterm_stops() -> Iterator[None]:
    """While inside, SIGTERM raises KeyboardInterrupt (a clean stop: the server is terminated)."""

    def _terminate(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    if threading.current_thread() is not threading.main_thread():  # signals reach the main thread only
        yield
        return
    previous = signal.signal(signal.SIGTERM, _terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit code (0 ok, 2 bad input or failure, 130 interrupted)."""
    return run_cli(build_parser(), _work, argv)


def _work(args: argparse.Namespace) -> int:
    _check_args(args)
    with _sigterm_stops():
        return _run(args)


def _case(args: argparse.Namespace):  # -> TrajectoryCase (the viewer's, imported lazily)
    from verify.viewer.trajectory_view import case_from_generated, paper_test1_case

    if args.paper_test1:  # Table 2 is for the paper's arm
        return paper_test1_case(arm_for_verify(load_coefficients(PAPER_SOURCE, region_map=None), args.urdf))
    from pipeline.online.generator import generate

    coefficients = load_coefficients_for_verify(PROG, args.coefficients, beside=False)  # the view shows no bounds
    values = scene_variables(coefficients, args)
    arm = arm_for_verify(coefficients, args.urdf)
    print(describe_coefficients(coefficients), flush=True)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", OutOfFittedRangeWarning)
        generated = generate(coefficients, args.L, args.W, **values)
    for warning in caught:
        print(f"{PROG}: warning: {warning.message}", file=sys.stderr)
    return case_from_generated(generated, arm)


def _joint_plot(args: argparse.Namespace) -> int:
    """Certify the answer with the chosen timing and plot its joint states."""
    from pipeline.exceptions import ExecutionRefusedError, NoCertifiedTrajectoryError
    from pipeline.motion.near_optimal import NEAR_OPTIMAL
    from pipeline.motion.rest_to_rest import REST_TO_REST
    from pipeline.motion.timing import PAPER_TIMING
    from pipeline.online.repair import RepairConfig, generate_certified
    from verify.acceptance.joint_plot import plot_joint_states

    coefficients = load_coefficients_for_verify(PROG, args.coefficients)
    values = scene_variables(coefficients, args)
    arm = arm_for_verify(coefficients, args.urdf)
    limits = limits_from_options(arm, coefficients, args.acceleration_limit, args.jerk_limit)
    timing = {"near-optimal": NEAR_OPTIMAL, "rest-to-rest": REST_TO_REST, "paper": PAPER_TIMING}[args.timing]
    try:
        answer = generate_certified(
            coefficients,
            args.L,
            args.W,
            arm,
            **values,
            timing=timing,
            limits=limits,
            config=RepairConfig(certificate_tolerance_m=1e-5),
        )
    except (NoCertifiedTrajectoryError, ExecutionRefusedError) as exc:
        print(f"{PROG}: certification refused: {exc}", file=sys.stderr)
        return EXIT_FAILED
    where = "".join(f", {name} = {value} m" for name, value in values.items())
    title = f"L = {args.L} m, W = {args.W} m{where}: q, dq, ddq, τ, jerk (dotted: certified bounds, dashed: limits)"
    plot_joint_states(answer.executed, arm, answer.execution, args.joint_plot, title=title)
    print(
        f"wrote {args.joint_plot} ({answer.execution.certificate.timing_name} timing, T' = {answer.duration_s:.3f} s)"
    )
    return EXIT_OK


def _run(args: argparse.Namespace) -> int:
    if args.joint_plot is not None:
        return _joint_plot(args)
    # Meshcat is imported here, by the viewer modules, only when a view is requested.
    from verify.viewer.browser import BrowserConfig
    from verify.viewer.drawing import ViewStyle
    from verify.viewer.trajectory_view import screenshot_trajectory, show_trajectory, trajectory_html, write_html

    case = _case(args)
    changes = {"fps": args.fps, "samples": args.samples, "play": not args.no_play}
    if args.screenshot is not None:
        width, height = args.size
        style = ViewStyle.for_pixels(**changes) if args.flat else ViewStyle(**changes)
        view = screenshot_trajectory(case, args.screenshot, BrowserConfig(width_px=width, height_px=height), style)
        print(f"wrote {args.screenshot} ({width}x{height} px; {view.cases[0].clearance.label})")
        return EXIT_OK
    style = ViewStyle.for_pixels(aspect=1.6, **changes) if args.flat else ViewStyle(aspect=1.6, **changes)
    if args.html is not None:
        html, view = trajectory_html(case, style)
        write_html(args.html, html)
        print(f"wrote {args.html} ({len(html) / 1e6:.1f} MB, opens offline; {view.cases[0].clearance.label})")
        return EXIT_OK
    view = show_trajectory(case, style, hold_s=args.hold)
    print(f"stopped the Meshcat server ({view.cases[0].clearance.label})")
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
