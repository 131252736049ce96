"""What every command line of the project shares (``pipeline.build``, ``pipeline.regress``,
``pipeline.generate``, ``pipeline.certify_range``, ``verify.sweep``, ``verify.online_sweep``,
``verify.bench``, ``verify.view``): one parser class, one-line errors naming the program, exit
codes, Ctrl-C and termination signals (SIGTERM, SIGHUP), ``--jobs 0`` = every CPU, output paths
checked before any work, and the coefficients to use with the build's file as default.

A CLI module only declares its options and calls :func:`run_cli` with a function that does the
work; the work lives in importable functions below.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import NoReturn, TextIO

from pipeline.exceptions import DataFileError, PipelineError
from pipeline.io.executor import DEFAULT_WORKER_TIMEOUT_S
from pipeline.io.output_paths import check_output_file, check_output_folder
from pipeline.io.signals import Terminated, termination_raises
from pipeline.motion.families import PAPER_SOURCE
from pipeline.offline.coefficients import Coefficients
from pipeline.online.loading import load_coefficients

__all__ = [
    "DEFAULT_COEFFICIENTS",
    "EXIT_FAILED",
    "EXIT_INTERRUPTED",
    "EXIT_OK",
    "EXIT_TERMINATED",
    "EXIT_USAGE",
    "HelpFormatter",
    "Parser",
    "add_acceleration_limit_argument",
    "add_jerk_limit_argument",
    "add_progress_argument",
    "arm_for_cli",
    "check_output_file",
    "check_output_folder",
    "count_argument",
    "describe_coefficients",
    "finite_positive",
    "jobs_count",
    "limits_from_options",
    "load_coefficients_for_cli",
    "run_cli",
    "usage_error",
    "worker_timeout",
]

#: Exit status: success, or every check passed.
EXIT_OK = 0
#: Exit status: the work ran and its verdict is negative (a failed check, a refused certification).
EXIT_FAILED = 1
#: Exit status: bad command-line input or an unusable input file (argparse's own convention).
EXIT_USAGE = 2
#: Exit status: interrupted by Ctrl-C (128 + SIGINT).
EXIT_INTERRUPTED = 130
#: Exit status: ended by SIGTERM (128 + 15); SIGHUP gives 129.
EXIT_TERMINATED = 143
#: Exit status when the reader of the output went away (e.g. ``| head``): the shell's status of a
#: command stopped by SIGPIPE (128 + 13).
EXIT_PIPE_CLOSED = 141

#: Where ``python -m pipeline.build`` writes the coefficients by default.
DEFAULT_COEFFICIENTS = "results/coefficients.json"


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Appends "(default: ...)" only where a default means something: not for flags that are
    off by default, options without a default, or help that already states its default."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        if (
            "(default" in text
            or action.default is None
            or action.default is False  # identity: a default of 0 is a value to show
            or action.default is argparse.SUPPRESS
            or action.required
            or action.option_strings == ["-h", "--help"]
        ):
            return text
        return super()._get_help_string(action)


class Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line (no usage block) and exit with status 2."""

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> NoReturn:  # type: ignore[override]
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\n")


def usage_error(prog: str, message: str, stream: TextIO | None = None) -> int:
    """Print ``prog: error: message`` on one line; returns :data:`EXIT_USAGE`."""
    print(f"{prog}: error: {' '.join(str(message).split())}", file=sys.stderr if stream is None else stream)
    return EXIT_USAGE


def run_cli(
    parser: argparse.ArgumentParser, work: Callable[[argparse.Namespace], int], argv: Sequence[str] | None
) -> int:
    """Parse ``argv`` and run ``work(args)``; every failure becomes one line and an exit status.

    * a usage error or ``--help``: argparse's status (2 or 0), already printed;
    * a :class:`pipeline.exceptions.PipelineError` (bad value, unreadable file, refused output
      path): ``prog: error: message`` and :data:`EXIT_USAGE`;
    * Ctrl-C: ``prog: interrupted`` and :data:`EXIT_INTERRUPTED`;
    * SIGTERM or SIGHUP while ``work`` runs: the same unwinding as Ctrl-C (worker processes
      terminated and joined, files being written put back, locks removed:
      :func:`pipeline.io.signals.termination_raises`), then ``prog: terminated by SIGTERM`` and
      128 + the signal's number (143 for SIGTERM, 129 for SIGHUP);
    * the reader of stdout went away (``| head``): no more output, no message, and
      :data:`EXIT_PIPE_CLOSED`.
    """
    try:
        args = parser.parse_args(list(sys.argv[1:] if argv is None else argv))
    except SystemExit as exc:
        return int(exc.code or 0)
    try:
        with termination_raises():
            status = work(args)
            sys.stdout.flush()  # here, so that a closed pipe is handled below and not at exit
        return status
    except PipelineError as exc:
        return usage_error(parser.prog, str(exc))
    except Terminated as exc:
        print(f"{parser.prog}: terminated by {exc.signal_name}", file=sys.stderr)
        return exc.exit_status
    except KeyboardInterrupt:
        print(f"{parser.prog}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        # What is still buffered goes nowhere, so that the interpreter's last flush cannot fail.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_PIPE_CLOSED


def count_argument(text: str) -> int:
    """argparse type: a whole number >= 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"{value} must be >= 0")
    return value


def jobs_count(text: str) -> int:
    """argparse type of ``--jobs``: a count >= 0, where 0 means every CPU of this machine."""
    try:
        value = count_argument(text)
    except argparse.ArgumentTypeError as exc:
        raise argparse.ArgumentTypeError(f"--jobs {exc} (0 = every CPU)") from None
    return value if value > 0 else (os.cpu_count() or 1)


def load_coefficients_for_cli(source: str | Path) -> Coefficients:
    """:func:`pipeline.offline.coefficients.load_coefficients`, with a hint when the build's file is missing.

    Raises:
        DataFileError: missing, unreadable or malformed file.
    """
    source = str(source)
    if source != PAPER_SOURCE and not Path(source).is_file():
        hint = f" (run python -m pipeline.build first, or pass --coefficients {PAPER_SOURCE})"
        raise DataFileError(source, "coefficients file not found" + (hint if source == DEFAULT_COEFFICIENTS else ""))
    return load_coefficients(source)


def finite_positive(flag: str, unit: str):
    """An argparse type for ``flag``: a finite value > 0 [``unit``] (zero, negative, NaN and inf refused)."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{flag} {text!r} is not a number [{unit}]") from None
        if not 0.0 < value < math.inf:  # NaN too
            raise argparse.ArgumentTypeError(f"{flag} {value} must be > 0 and finite [{unit}]")
        return value

    return parse


def _add_limit_argument(parser: argparse.ArgumentParser, flag: str, kind: str, unit: str, use: str) -> None:
    """``flag X1 X2``: the arm's joint ``kind`` limits [``unit``], two finite values > 0 (URDF carries none)."""
    letter = kind[0].upper()
    parser.add_argument(
        flag,
        nargs=2,
        type=finite_positive(flag, unit),
        default=None,
        metavar=(f"{letter}1", f"{letter}2"),
        help=f"the arm's joint {kind} limits [{unit}] (URDF carries none): {use}",
    )


def add_acceleration_limit_argument(parser: argparse.ArgumentParser, use: str) -> None:
    """``--acceleration-limit A1 A2`` [rad/s^2]; ``use`` says what the command does with it."""
    _add_limit_argument(parser, "--acceleration-limit", "acceleration", "rad/s^2", use)


def limits_from_options(arm, coefficients, acceleration_limit, jerk_limit):
    """The limits of ``--acceleration-limit`` and ``--jerk-limit`` (None: not given) on top of the
    URDF's: the acceleration limits recorded with ``coefficients`` where none is given
    (:meth:`pipeline.model.limits.ArmLimits.recorded`), no jerk limit where none is given."""
    from dataclasses import replace

    from pipeline.model.limits import ArmLimits

    if acceleration_limit is None:
        limits = ArmLimits.recorded(arm, coefficients.provenance)
    else:
        limits = ArmLimits.from_arm(arm, tuple(acceleration_limit))
    return limits if jerk_limit is None else replace(limits, jerk_rad_s3=tuple(jerk_limit))


def add_jerk_limit_argument(parser: argparse.ArgumentParser, use: str) -> None:
    """``--jerk-limit J1 J2`` [rad/s^3]; ``use`` says what the command does with it."""
    _add_limit_argument(parser, "--jerk-limit", "jerk", "rad/s^3", use)


def worker_timeout(text: str) -> float:
    """argparse type of ``--worker-timeout``: a finite time > 0 [s]."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--worker-timeout {text!r} is not a number [s]") from None
    if not 0.0 < value < math.inf:  # NaN too
        raise argparse.ArgumentTypeError(f"--worker-timeout {value} must be a finite time > 0 [s]")
    return value


def add_scheduler_arguments(parser: argparse.ArgumentParser) -> None:
    """``--scheduler ADDRESS`` (a Dask cluster in place of the local processes) and
    ``--worker-timeout`` [s] (how long to wait for its first worker before any work)."""
    parser.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        default=None,
        help="Dask scheduler address (tcp://host:port); default: a local process pool of --jobs workers",
    )
    parser.add_argument(
        "--worker-timeout",
        type=worker_timeout,
        default=DEFAULT_WORKER_TIMEOUT_S,
        metavar="SECONDS",
        help="with --scheduler: how long to wait for its first worker before any work; none by then is refused [s]",
    )


def add_progress_argument(parser: argparse.ArgumentParser) -> None:
    """``--no-progress``: no progress bars (they go to stderr, and only when it is a terminal)."""
    parser.add_argument(
        "--no-progress",
        action="store_true",
        help="no progress bars on stderr (they are drawn only when stderr is a terminal)",
    )


def arm_for_cli(coefficients: Coefficients, urdf: str | Path | None):
    """The arm for ``coefficients``: the one recorded with them (:func:`pipeline.online.arm_check.arm_for`),
    or the ``--urdf`` given, checked against them.

    Raises:
        DataFileError: the recorded arm's URDF is missing or changed.
        RobotModelError: the URDF cannot be loaded.
        ArmMismatchError: the ``--urdf`` arm differs from the one the coefficients were fitted for.
    """
    from pipeline.online.arm_check import arm_for  # Pinocchio: only for the commands that need the arm

    return arm_for(coefficients, urdf)


def describe_coefficients(coefficients: Coefficients) -> str:
    """One line saying which coefficients are in use: source, family and short hash."""
    line = f"coefficients: {coefficients.source} ({coefficients.family.name}, sha256 {coefficients.source_sha256[:12]})"
    if not coefficients.converged:
        line += (
            "; NOT CONVERGED: written with --allow-unconverged (" + "; ".join(coefficients.unconverged_reasons) + ")"
        )
    return line
