"""Termination signals unwound like Ctrl-C (pipeline.io.signals), and a local pool stopped by one
(pipeline.io.executor): the workers are terminated and joined at once, not waited for, and a
forked worker does not keep the parent's handler."""

from __future__ import annotations

import multiprocessing
import os
import signal
import threading
import time

import pytest

from pipeline.io.executor import LocalPool, map_tasks
from pipeline.io.signals import TERMINATION_SIGNALS, Terminated, default_termination, termination_raises

pytestmark = pytest.mark.skipif(not hasattr(signal, "SIGHUP"), reason="POSIX signals")


@pytest.fixture(autouse=True)
def default_actions():
    """Every test starts and ends with the default action for the termination signals."""
    before = {signum: signal.getsignal(signum) for signum in TERMINATION_SIGNALS}
    if any(action is not signal.SIG_DFL for action in before.values()):
        pytest.skip("the test runner handles or ignores SIGTERM or SIGHUP")
    yield
    for signum, action in before.items():
        signal.signal(signum, action)


@pytest.mark.parametrize(("signum", "status"), [(signal.SIGTERM, 143), (signal.SIGHUP, 129)])
def test_a_termination_signal_raises_terminated_inside_only(signum: int, status: int) -> None:
    with pytest.raises(Terminated) as caught, termination_raises():
        assert callable(signal.getsignal(signum))
        os.kill(os.getpid(), signum)
        time.sleep(5)  # interrupted by the handler
        pytest.fail("the signal did not interrupt the work")
    assert caught.value.signum == signum and caught.value.exit_status == status
    assert caught.value.signal_name == signal.Signals(signum).name
    assert not isinstance(caught.value, Exception | KeyboardInterrupt)  # not swallowed as an error
    assert signal.getsignal(signum) is signal.SIG_DFL


def test_a_second_signal_while_unwinding_is_ignored() -> None:
    unwound = []
    with pytest.raises(Terminated), termination_raises():
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(5)
        finally:
            os.kill(os.getpid(), signal.SIGTERM)  # the cleanup goes on to its end
            time.sleep(0.2)
            unwound.append(True)
    assert unwound == [True]


def test_an_ignored_signal_stays_ignored() -> None:
    signal.signal(signal.SIGHUP, signal.SIG_IGN)  # as under nohup
    with termination_raises():
        assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN
        assert callable(signal.getsignal(signal.SIGTERM))
    assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN


def test_default_termination_resets_an_inherited_handler_only() -> None:
    signal.signal(signal.SIGHUP, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, lambda *_: None)
    default_termination()
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
    assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN


def test_outside_the_main_thread_nothing_is_installed() -> None:
    seen = []

    def run() -> None:
        with termination_raises():
            seen.append(signal.getsignal(signal.SIGTERM))

    thread = threading.Thread(target=run)
    thread.start()
    thread.join()
    assert seen == [signal.SIG_DFL]


def handler_name(signum: int) -> str:
    """The action for ``signum`` in the worker that runs this (module level: picklable)."""
    action = signal.getsignal(signum)
    return getattr(action, "name", repr(action))


def test_a_forked_worker_does_not_keep_the_parents_handler() -> None:
    if "fork" not in multiprocessing.get_all_start_methods():
        pytest.skip("no fork on this platform")
    with termination_raises():
        names = map_tasks(LocalPool(2, start_method="fork"), handler_name, [signal.SIGTERM, signal.SIGHUP] * 2, None)
    assert names == ["SIG_DFL"] * 4


def test_a_signal_stops_the_pools_workers_at_once() -> None:
    """Four tasks of a minute on two spawned workers; SIGTERM after two seconds. The call raises
    Terminated within seconds, with its workers ended and reaped."""
    workers: list[int] = []

    def stop() -> None:
        workers.extend(process.pid for process in multiprocessing.active_children())
        os.kill(os.getpid(), signal.SIGTERM)

    timer = threading.Timer(2.0, stop)
    started = time.monotonic()
    with pytest.raises(Terminated), termination_raises():
        timer.start()
        map_tasks(LocalPool(2), time.sleep, [60.0] * 4, None, chunk_size=1)
    timer.join()
    assert time.monotonic() - started < 20.0  # not the minute of the tasks running
    assert len(workers) >= 2
    for pid in workers:
        with pytest.raises(ProcessLookupError):  # ended and reaped
            os.kill(pid, 0)
    assert not multiprocessing.active_children()
