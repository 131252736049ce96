"""The output folder's lock (pipeline.io.folder_lock): created exclusively with the process id and
host, removed however the work ends, refused while its process lives, taken over when stale."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pipeline.exceptions import OutputLockedError
from pipeline.io.folder_lock import LOCK_NAME, LockHolder, build_lock, read_lock


def ended_pid() -> int:
    """The id of a process that has ended (and been reaped)."""
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def write_lock(folder: Path, pid: int, host: str | None = None) -> Path:
    folder.mkdir(exist_ok=True)
    lock = folder / LOCK_NAME
    lock.write_text(json.dumps({"pid": pid, "host": socket.gethostname() if host is None else host}))
    return lock


def test_the_lock_names_this_process_while_held_and_goes_away_after(tmp_path: Path) -> None:
    folder = tmp_path / "results"
    with build_lock(folder) as lock:
        assert lock == folder / LOCK_NAME
        assert read_lock(lock) == LockHolder(os.getpid(), socket.gethostname())
        (folder / "doe.json").write_text("{}")
    assert sorted(p.name for p in folder.iterdir()) == ["doe.json"]


@pytest.mark.parametrize("stop", [RuntimeError, KeyboardInterrupt])
def test_an_error_or_interrupt_removes_the_lock_and_the_folder_it_created(tmp_path: Path, stop: type) -> None:
    folder = tmp_path / "results"
    with pytest.raises(stop), build_lock(folder):
        raise stop()
    assert not folder.exists()
    existing = tmp_path / "existing"
    existing.mkdir()
    with pytest.raises(stop), build_lock(existing):
        raise stop()
    assert existing.is_dir() and list(existing.iterdir()) == []


def test_a_live_holder_is_refused_naming_it_and_its_lock_is_kept(tmp_path: Path) -> None:
    folder = tmp_path / "results"
    with build_lock(folder) as lock:
        with pytest.raises(OutputLockedError) as caught, build_lock(folder):
            pytest.fail("a second holder got the lock")
        assert read_lock(lock).pid == os.getpid()  # the first holder keeps it
    error = caught.value
    assert (error.pid, error.host, error.elsewhere) == (os.getpid(), socket.gethostname(), False)
    assert str(error) == (
        f"{folder}/ is being written by the build of process {os.getpid()} (lock {folder / LOCK_NAME}); "
        "wait for it or remove the lock"
    )
    assert not folder.exists()  # the first holder created it; nothing was written


def test_a_lock_of_another_host_or_unreadable_is_refused(tmp_path: Path) -> None:
    lock = write_lock(tmp_path, ended_pid(), host="elsewhere.example")
    with pytest.raises(OutputLockedError, match=r"process \d+ on elsewhere\.example \(lock ") as caught:
        with build_lock(tmp_path):
            pytest.fail("took a lock of another host")
    assert caught.value.elsewhere
    lock.write_text("")  # a lock being created, or damaged
    with pytest.raises(OutputLockedError, match=r"another build \(its lock cannot be read\)"):
        with build_lock(tmp_path):
            pytest.fail("took an unreadable lock")
    assert lock.read_text() == ""


def test_a_stale_lock_is_taken_over_with_one_line(tmp_path: Path) -> None:
    stale = ended_pid()
    lock = write_lock(tmp_path, stale)
    assert not LockHolder(stale, socket.gethostname()).alive()
    notes: list[str] = []
    with build_lock(tmp_path, note=notes.append):
        assert read_lock(lock) == LockHolder(os.getpid(), socket.gethostname())
    assert notes == [f"note: took over the lock {lock} of process {stale}, which is no longer running"]
    assert not lock.exists() and list(tmp_path.iterdir()) == []


def test_a_zombie_holds_no_lock(tmp_path: Path) -> None:
    if not Path("/proc/self/stat").exists():
        pytest.skip("zombies are read from /proc")
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    try:
        deadline = time.monotonic() + 30
        while Path(f"/proc/{child.pid}/stat").read_text().rpartition(")")[2].split()[0] != "Z":
            assert time.monotonic() < deadline, "the child did not end"
            time.sleep(0.01)  # ended, not yet reaped: a zombie
        assert not LockHolder(child.pid, socket.gethostname()).alive()
        assert LockHolder(os.getpid(), socket.gethostname()).alive()
    finally:
        child.wait()
