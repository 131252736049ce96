"""Termination signals unwound like Ctrl-C: SIGTERM and SIGHUP become an exception.

By default SIGTERM (``kill PID``, a service manager stopping a job) and SIGHUP (the terminal went
away) end a Python process on the spot: no ``finally`` runs, so the worker processes of a pool
keep running and a lock file stays behind. Inside :func:`termination_raises` they raise
:class:`Terminated` in the main thread instead, and the same cleanup as for Ctrl-C runs (the
pool's workers are terminated and joined, a file set being written is put back, a lock is
removed) before the command exits with 128 + the signal's number (143 for SIGTERM, 129 for
SIGHUP), what a shell shows for a process ended by that signal.

:class:`Terminated` derives from ``BaseException``, not ``Exception``, so that code catching
errors does not swallow it, and not from ``KeyboardInterrupt``, so that the command says which
signal stopped it.

Worker processes must keep the default action (a pool terminates its workers with SIGTERM):
spawned workers start with it; a forked worker inherits the parent's handler, so a pool calls
:func:`default_termination` first thing in each worker (its initializer).
"""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["TERMINATION_SIGNALS", "Terminated", "default_termination", "termination_raises"]

#: The signals :func:`termination_raises` turns into :class:`Terminated` (SIGHUP where the platform has it).
TERMINATION_SIGNALS: tuple[signal.Signals, ...] = tuple(
    getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name)
)


class Terminated(BaseException):
    """A termination signal arrived while a command worked (raised in the main thread).

    Attributes:
        signum: The signal's number (``signal.SIGTERM``, ``signal.SIGHUP``).
    """

    def __init__(self, signum: int) -> None:
        self.signum = int(signum)
        super().__init__(self.signal_name)

    @property
    def signal_name(self) -> str:
        """The signal's name, e.g. "SIGTERM"."""
        try:
            return signal.Signals(self.signum).name
        except ValueError:
            return f"signal {self.signum}"

    @property
    def exit_status(self) -> int:
        """128 + the signal's number: what a shell reports for a process the signal ended."""
        return 128 + self.signum


@contextmanager
def termination_raises() -> Iterator[None]:
    """While inside, SIGTERM and SIGHUP raise :class:`Terminated` in this thread; the previous
    handlers are restored on the way out.

    Only signals whose action is the default are taken over: one that is ignored (``nohup``
    ignores SIGHUP) stays ignored, and one the program already handles keeps its handler. The
    first signal raises; any that follows while the exception unwinds is ignored, so that the
    cleanup runs to its end. Outside the main thread (where Python delivers no signal) this does
    nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    owner = os.getpid()
    raised: list[int] = []

    def handler(signum: int, _frame: object) -> None:
        if os.getpid() != owner:  # a forked child that has not reset its handlers: end as by default
            signal.signal(signum, signal.SIG_DFL)
            os.kill(os.getpid(), signum)
            return
        if raised:
            return
        raised.append(signum)
        raise Terminated(signum)

    previous = {}
    try:
        for signum in TERMINATION_SIGNALS:
            if signal.getsignal(signum) is signal.SIG_DFL:
                previous[signum] = signal.signal(signum, handler)
        yield
    finally:
        for signum, action in previous.items():
            signal.signal(signum, action)


def default_termination() -> None:
    """SIGTERM and SIGHUP back to their default action where a Python handler was inherited (a
    forked worker process); an ignored signal stays ignored. Called at the start of each worker."""
    for signum in TERMINATION_SIGNALS:
        if callable(signal.getsignal(signum)):
            signal.signal(signum, signal.SIG_DFL)
