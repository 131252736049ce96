"""SIGTERM to a running ``python -m pipeline.build``: nothing of the build is left, and the folder it
was writing keeps its files.

Copies a finished build's folder (``--results``, default ``results/``) to a temporary folder,
starts ``python -m pipeline.build --out`` that folder (the default build, which would replace its
files at the end), records the process ids of the build and of its workers, sends SIGTERM after
``--at`` seconds, and reports: the exit status (143 expected), how long the build took to stop,
which recorded process is still running 30 s later (none expected), whether every file of the
folder kept its sha256, and the build's stderr (one line expected). Exit 0 if all hold, 1 if not.

    python scripts/build_sigterm_check.py --at 20
    python scripts/build_sigterm_check.py --at 60
"""

from __future__ import annotations

import argparse
import hashlib
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import psutil

#: How long the recorded processes may take to end after the build has [s].
SETTLE_S = 30.0


def digests(folder: Path) -> dict[str, str]:
    """sha256 of every file of ``folder``, by name."""
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir()) if p.is_file()}


def running(pids: set[int]) -> list[int]:
    """The processes of ``pids`` still running (zombies count as ended)."""
    alive = []
    for pid in sorted(pids):
        try:
            if psutil.Process(pid).status() != psutil.STATUS_ZOMBIE:
                alive.append(pid)
        except psutil.NoSuchProcess:
            pass
    return alive


def check(results: Path, at_s: float) -> bool:
    """Run the check once (module docstring); prints its line, returns whether everything held."""
    with tempfile.TemporaryDirectory() as scratch:
        folder = Path(scratch) / "results"
        shutil.copytree(results, folder)
        before = digests(folder)
        build = subprocess.Popen(
            [sys.executable, "-m", "pipeline.build", "--out", str(folder), "--no-progress"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        time.sleep(at_s)
        pids = {build.pid} | {child.pid for child in psutil.Process(build.pid).children(recursive=True)}
        build.send_signal(signal.SIGTERM)
        sent = time.monotonic()
        status = build.wait(timeout=120)
        stopped_s = time.monotonic() - sent
        deadline = time.monotonic() + SETTLE_S
        while running(pids) and time.monotonic() < deadline:
            time.sleep(0.2)
        left, same = running(pids), digests(folder) == before
        stderr = build.stderr.read().strip()
    print(
        f"SIGTERM at {at_s:g} s: exit {status} after {stopped_s:.1f} s; {len(pids)} processes recorded, still "
        f"running {left or 'none'}; files unchanged: {same}; stderr: {stderr!r}"
    )
    return status == 128 + signal.SIGTERM and not left and same and stderr.count("\n") == 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--at", type=float, default=20.0, help="seconds after the start to send SIGTERM [s]")
    parser.add_argument("--results", type=Path, default=Path("results"), help="a finished build's folder to copy")
    args = parser.parse_args(argv)
    if not (args.at > 0.0):
        parser.error(f"--at {args.at} must be a positive number of seconds")
    if not (args.results / "coefficients.json").is_file():
        parser.error(f"--results {args.results} holds no coefficients.json (run python -m pipeline.build first)")
    return 0 if check(args.results, args.at) else 1


if __name__ == "__main__":
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    raise SystemExit(main())
