"""One build at a time per output folder: a lock file, ``.build.lock``, in the folder.

:func:`build_lock` creates the lock with ``O_CREAT | O_EXCL`` (the file system lets exactly one
process create it) before any work, writes the process id and the host name into it, and removes
it when the work ends, however it ends (an error, Ctrl-C, a termination signal turned into an
exception: :mod:`pipeline.io.signals`). A second build into the same folder finds the lock and
is refused at once with :class:`pipeline.exceptions.OutputLockedError`, naming the process that
holds it.

A lock whose process is no longer alive on this host (a build killed with SIGKILL, a machine
that went down) is stale: the next build takes it over and says so in one line. A lock written
on another host is never taken over (its process cannot be checked from here), nor one that
cannot be read; removing the file by hand releases it. A process id that the system has given
to another process since looks alive: the lock is then held until removed by hand.

The folder is created if it does not exist (its parent must), and removed again on the way out
if it was created here and is empty (a build that wrote nothing leaves nothing).
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from pipeline.exceptions import OutputLockedError

__all__ = ["LOCK_NAME", "LockHolder", "build_lock", "read_lock"]

#: The lock file's name in the output folder.
LOCK_NAME = ".build.lock"
#: How long to wait for a lock that was just created to hold its content [s].
_CONTENT_WAIT_S = 1.0


@dataclass(frozen=True)
class LockHolder:
    """Who holds a lock.

    Attributes:
        pid: The holding process's id.
        host: The host it runs on (``socket.gethostname()`` there).
    """

    pid: int
    host: str

    @property
    def on_this_host(self) -> bool:
        """True if the holder runs on this host."""
        return self.host == socket.gethostname()

    def alive(self) -> bool:
        """False only if the holder runs on this host and its process has ended (or is a zombie)."""
        if not self.on_this_host:
            return True
        try:
            os.kill(self.pid, 0)
        except ProcessLookupError:
            return False
        except PermissionError:  # another user's process: alive
            return True
        stat = Path(f"/proc/{self.pid}/stat")  # Linux: an ended process not yet reaped is a zombie
        with contextlib.suppress(OSError, IndexError):
            return stat.read_text().rpartition(")")[2].split()[0] != "Z"
        return True


def read_lock(path: str | Path) -> LockHolder | None:
    """The holder written in the lock file ``path``, or None if it is missing or cannot be read
    (after waiting up to a second for a lock being created to get its content)."""
    deadline = time.monotonic() + _CONTENT_WAIT_S
    while True:
        try:
            data = json.loads(Path(path).read_text(encoding="utf-8"))
            return LockHolder(int(data["pid"]), str(data["host"]))
        except FileNotFoundError:
            return None
        except (OSError, ValueError, TypeError, KeyError):
            if time.monotonic() > deadline:
                return None
            time.sleep(0.05)


def _note_on_stderr(text: str) -> None:
    print(text, file=sys.stderr)


@contextmanager
def build_lock(folder: str | Path, note: Callable[[str], None] | None = None) -> Iterator[Path]:
    """Hold the lock of ``folder`` while inside; yields the lock file's path.

    Args:
        folder: The output folder (created if missing; its parent must exist).
        note: Gets the one line saying that a stale lock was taken over (default: printed on stderr).

    Raises:
        OutputLockedError: another build holds the lock (nothing created, nothing changed).
        OSError: the folder or the lock cannot be created.
    """
    folder = Path(folder)
    try:
        folder.mkdir()
        created = True
    except FileExistsError:
        created = False
    lock = folder / LOCK_NAME
    try:
        _acquire(folder, lock, _note_on_stderr if note is None else note)
    except BaseException:
        _remove_folder_if_created(folder, created)
        raise
    try:
        yield lock
    finally:
        if read_lock(lock) == LockHolder(os.getpid(), socket.gethostname()):
            lock.unlink(missing_ok=True)
        _remove_folder_if_created(folder, created)


def _acquire(folder: Path, lock: Path, note: Callable[[str], None]) -> None:
    """Create ``lock`` for this process, taking over a stale one (at most a few times, if other
    builds race for it)."""
    content = json.dumps({"pid": os.getpid(), "host": socket.gethostname()}) + "\n"
    for _ in range(3):
        try:
            handle = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            holder = read_lock(lock)
            if holder is None and lock.exists():
                raise OutputLockedError(folder, lock, None, None, False) from None
            if holder is not None and holder.alive():
                raise OutputLockedError(folder, lock, holder.pid, holder.host, not holder.on_this_host) from None
            if holder is not None and _remove_stale(lock, holder):
                note(f"note: took over the lock {lock} of process {holder.pid}, which is no longer running")
            continue
        try:
            with os.fdopen(handle, "w", encoding="utf-8") as stream:
                stream.write(content)
        except BaseException:
            lock.unlink(missing_ok=True)
            raise
        return
    holder = read_lock(lock)
    raise OutputLockedError(
        folder, lock, None if holder is None else holder.pid, None if holder is None else holder.host, False
    )


def _remove_stale(lock: Path, stale: LockHolder) -> bool:
    """Remove ``lock`` if it still names ``stale``; True if this call removed it. The lock is moved
    aside first (one process wins the rename), and put back if another build took it over meanwhile."""
    aside = lock.with_name(f"{lock.name}.stale-{os.getpid()}")
    try:
        os.rename(lock, aside)
    except FileNotFoundError:
        return False  # another build removed it first
    if read_lock(aside) != stale:  # a live lock taken over by another build in between: put it back
        with contextlib.suppress(FileExistsError):
            os.link(aside, lock)
        aside.unlink(missing_ok=True)
        return False
    aside.unlink(missing_ok=True)
    return True


def _remove_folder_if_created(folder: Path, created: bool) -> None:
    if created:
        with contextlib.suppress(OSError):  # not empty: the build wrote its files
            folder.rmdir()
