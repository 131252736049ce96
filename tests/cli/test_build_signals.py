"""``python -m pipeline.build`` stopped by a termination signal, for real: a build in its own
process with two spawned workers gets SIGTERM midway, exits 143 with one line, leaves none of its
processes running (workers, resource tracker) and the folder's earlier files byte for byte as
they were. In process: SIGHUP through the shared CLI scaffold exits 129."""

from __future__ import annotations

import hashlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pipeline.cli import EXIT_TERMINATED, Parser, run_cli

ROOT = Path(__file__).resolve().parents[2]
#: A build of seconds: a tiny PSO (the optima miss the thresholds: --allow-unconverged writes them).
TINY = ["--swarm-size", "8", "--iterations", "5", "--restarts", "1", "--n-points", "15", "--plain"]
TINY += ["--allow-unconverged", "--quiet", "--no-progress", "--jobs", "2", "--near-optimal-cells", "2"]
#: A build of minutes, to be stopped midway.
LONG = [*TINY, "--swarm-size", "40", "--iterations", "400"]
PROG = "python -m pipeline.build"

pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads processes from /proc")


def _state(pid: int) -> str | None:
    """The state letter of process ``pid`` in /proc (None: no such process)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()[0]
    except (OSError, IndexError):
        return None


def _running(pid: int) -> bool:
    """True if ``pid`` exists and has not ended (an ended process not yet reaped is a zombie)."""
    return _state(pid) not in (None, "Z")


def _descendants(pid: int) -> set[int]:
    """Every process below ``pid`` (psutil if installed, else the parent ids in /proc)."""
    try:
        import psutil
    except ImportError:
        psutil = None
    if psutil is not None:
        try:
            return {child.pid for child in psutil.Process(pid).children(recursive=True)}
        except psutil.NoSuchProcess:
            return set()
    parents = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                parents[int(entry.name)] = int((entry / "stat").read_text().rpartition(")")[2].split()[1])
            except (OSError, IndexError, ValueError):
                continue
    found, frontier = set(), [pid]
    while frontier:
        parent = frontier.pop()
        children = {child for child, of in parents.items() if of == parent} - found
        found |= children
        frontier.extend(children)
    return found


def _digests(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir())}


def _build(out: Path, options: list[str], log: Path) -> subprocess.Popen:
    environment = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    with log.open("w") as stderr:  # a file, not a pipe: a worker left running would hold a pipe open
        return subprocess.Popen(
            [sys.executable, "-m", "pipeline.build", *options, "--out", str(out)],
            stdout=subprocess.DEVNULL,
            stderr=stderr,
            cwd=out.parent,
            env=environment,
        )


def test_sigterm_midway_stops_every_process_and_keeps_the_earlier_files(tmp_path: Path) -> None:
    out = tmp_path / "r"
    first = _build(out, TINY, tmp_path / "first.log")
    assert first.wait(timeout=240) == 0, (tmp_path / "first.log").read_text()
    before = _digests(out)
    assert {"doe.json", "coefficients.json", "build_timing.json"} <= set(before)

    build = _build(out, LONG, tmp_path / "second.log")
    try:
        deadline = time.monotonic() + 120
        processes: set[int] = set()
        while len(processes) < 3 and time.monotonic() < deadline:  # two workers and the resource tracker
            time.sleep(0.1)
            processes = _descendants(build.pid)
        assert len(processes) >= 3, f"the build started no pool: {processes}"
        time.sleep(2.0)  # the workers at work
        processes = _descendants(build.pid)
        assert build.poll() is None, "the build ended before the signal: it is not stopped midway"
        build.send_signal(signal.SIGTERM)
        status = build.wait(timeout=30)
    finally:
        if build.poll() is None:
            build.kill()
            build.wait()
    errors = (tmp_path / "second.log").read_text()
    assert status == EXIT_TERMINATED == 143, errors
    assert errors.strip().splitlines() == [f"{PROG}: terminated by SIGTERM"], errors
    deadline = time.monotonic() + 30
    while any(_running(pid) for pid in processes) and time.monotonic() < deadline:
        time.sleep(0.1)
    left = {pid: _state(pid) for pid in processes if _running(pid)}
    for pid in left:  # not to leave them behind this test either
        os.kill(pid, signal.SIGKILL)
    assert not left, f"processes of the build still running 30 s after it ended: {left}"
    assert _digests(out) == before  # the earlier build's files, byte for byte, and nothing beside them


def _signals_itself(signum: int):
    def work(_args) -> int:
        os.kill(os.getpid(), signum)
        time.sleep(5)  # the handler interrupts this
        raise AssertionError("the signal did not stop the work")

    return work


def test_sighup_exits_129_with_one_line_and_restores_the_default(capsys: pytest.CaptureFixture[str]) -> None:
    if getattr(signal, "SIGHUP", None) is None or signal.getsignal(signal.SIGHUP) is not signal.SIG_DFL:
        pytest.skip("no SIGHUP, or it is ignored (nohup) or handled by the test runner")
    started = time.monotonic()
    assert run_cli(Parser(prog="prog"), _signals_itself(signal.SIGHUP), []) == 129
    assert time.monotonic() - started < 4.0
    assert capsys.readouterr().err == "prog: terminated by SIGHUP\n"
    assert signal.getsignal(signal.SIGHUP) is signal.SIG_DFL  # only while the work runs
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
