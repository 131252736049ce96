"""Where the build's tasks run: one interface for a local process pool and a Dask cluster.

An executor is a small frozen value that says where the work goes:

* :class:`LocalPool` (``jobs`` processes on this machine, the default; ``jobs == 1`` runs in this
  process);
* :class:`DaskScheduler` (the workers of a running Dask cluster, by its scheduler's address).

:func:`map_tasks` runs ``function`` on every task on either and returns the results in task
order, calling ``on_done(index, result)`` in this process as each task finishes. The tasks are
the caller's and are cut into fixed chunks, so as long as ``function`` is a pure function of its
task the results do not depend on the executor, the worker count or the order in which the
tasks finish. Work that draws random numbers carries its own seed in the task
(:func:`pipeline.io.parallel.item_seeds`).

Local pool. Worker processes start with ``spawn`` (no state inherited by accident), so
``function`` and the tasks must be picklable (a module-level function or a ``functools.partial``
of one). An error in a chunk cancels the chunks not yet started and shuts the pool down before
the exception propagates; Ctrl-C, or a termination signal turned into an exception
(:mod:`pipeline.io.signals`), also terminates the running workers and joins them, so that no
worker outlives the call. Each worker starts with the default action for SIGTERM and SIGHUP
(:func:`pipeline.io.signals.default_termination`).

A spawned worker imports the main module of the program again: a script that starts a pool must
do so under ``if __name__ == "__main__":``. Without it each worker would start the work again;
multiprocessing stops it, the pool breaks and :func:`map_tasks` raises
:class:`pipeline.exceptions.WorkerPoolError`, which says so. In a worker that is still importing
the main module, :func:`map_tasks` ends the worker quietly instead of starting a pool of its own,
so the message is the parent's alone.

Dask. ``distributed`` is imported only here, and only when a :class:`DaskScheduler` is used
(``pip install 'twolink-obstacle[dask]'``). Each call connects a client with a short timeout
before submitting anything (an unreachable scheduler raises
:class:`pipeline.exceptions.SchedulerUnreachableError`, one line naming the address), waits at
most ``DaskScheduler.worker_timeout_s`` for at least one worker (a scheduler without workers
would hold the tasks forever: :class:`NoDaskWorkersError`, one line naming the address and the
timeout), submits the chunks, collects them with ``distributed.as_completed``, and closes the
client; an error or Ctrl-C cancels the chunks not yet done. The workers must have this package
installed (the same version): they import ``function`` by name. Each chunk on a worker first
raises the C allocator's mmap threshold (:mod:`pipeline.io.allocator`: under the nanny's
``MALLOC_TRIM_THRESHOLD_`` the certificate's tasks ran slower per core). :func:`check_executor` makes the
connection and worker test on its own, so that a command can fail before any work.
"""

from __future__ import annotations

import contextlib
import math
import multiprocessing
import re
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import Any, TypeVar

from pipeline.exceptions import InvalidParameterError, PipelineError, SchedulerUnreachableError, WorkerPoolError
from pipeline.io.allocator import raise_mmap_threshold
from pipeline.io.signals import default_termination
from pipeline.validation import check_positive, check_positive_int

__all__ = [
    "DEFAULT_CONNECT_TIMEOUT_S",
    "DEFAULT_WORKER_TIMEOUT_S",
    "MAX_DEFAULT_CHUNK",
    "DaskScheduler",
    "Executor",
    "LocalPool",
    "NoDaskWorkersError",
    "as_executor",
    "check_executor",
    "check_scheduler_address",
    "default_chunk_size",
    "map_tasks",
]

Task = TypeVar("Task")
Result = TypeVar("Result")

#: Upper bound of the default chunk size [tasks]: small enough that progress is reported often.
MAX_DEFAULT_CHUNK = 16
#: How long a local worker may take to end after SIGTERM before it is killed [s].
WORKER_STOP_TIMEOUT_S = 5.0
#: How long a Dask client waits for the scheduler before giving up [s].
DEFAULT_CONNECT_TIMEOUT_S = 5.0
#: How long a Dask client waits for the scheduler's first worker before giving up [s].
DEFAULT_WORKER_TIMEOUT_S = 30.0

# host:port or tcp://host:port; host a name, an IPv4 address or a bracketed IPv6 address.
_ADDRESS = re.compile(r"^(?:tcp://)?(?:\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9](?:[A-Za-z0-9.\-]*[A-Za-z0-9])?):(\d{1,5})$")
_ADDRESS_EXPECTED = 'a Dask scheduler address "host:port" or "tcp://host:port"'


class NoDaskWorkersError(SchedulerUnreachableError):
    """The Dask scheduler answers but no worker joined it within the timeout (checked before any
    work: without workers the tasks would wait forever).

    Attributes:
        address: The scheduler's address as given.
        timeout_s: How long the client waited for a worker [s].
        reason: What was missing, in words.
    """

    def __init__(self, address: str, timeout_s: float) -> None:
        self.address = address
        self.timeout_s = timeout_s
        self.reason = f"no worker joined within {timeout_s:g} s"
        PipelineError.__init__(
            self,
            f"the Dask scheduler at {address} has no workers: none joined within {timeout_s:g} s "
            f"(start some with: dask worker {address})",
        )


def check_scheduler_address(name: str, value: object) -> str:
    """``value`` if it is a scheduler address ``host:port`` or ``tcp://host:port`` (port 1-65535).

    Raises:
        InvalidParameterError: anything else (named ``name``).
    """
    match = _ADDRESS.match(value) if isinstance(value, str) else None
    if match is None or not 1 <= int(match.group(1)) <= 65535:
        raise InvalidParameterError(name, value, _ADDRESS_EXPECTED)
    return value


#: Start methods of a local pool's workers.
START_METHODS = ("spawn", "fork")


@dataclass(frozen=True)
class LocalPool:
    """``jobs`` worker processes on this machine, started with ``spawn`` (1: in this process).

    Attributes:
        jobs: Number of processes, >= 1.
        start_method: How workers start: "spawn" (default: a fresh interpreter, nothing
            inherited) or "fork" (a copy of this process, where the platform offers it: no
            start-up cost, for tasks that read no state of the calling script).
    """

    jobs: int = 1
    start_method: str = "spawn"

    def __post_init__(self) -> None:
        check_positive_int("jobs", self.jobs, minimum=1)
        if self.start_method not in START_METHODS:
            raise InvalidParameterError("start_method", self.start_method, f"one of {START_METHODS}")


@dataclass(frozen=True)
class DaskScheduler:
    """The workers of a running Dask cluster.

    Attributes:
        address: The scheduler's address, ``host:port`` or ``tcp://host:port``.
        connect_timeout_s: How long to wait for the scheduler before giving up [s].
        worker_timeout_s: How long to wait, once connected, for at least one worker before
            giving up [s] (:class:`NoDaskWorkersError`).
    """

    address: str
    connect_timeout_s: float = DEFAULT_CONNECT_TIMEOUT_S
    worker_timeout_s: float = DEFAULT_WORKER_TIMEOUT_S

    def __post_init__(self) -> None:
        check_scheduler_address("scheduler", self.address)
        check_positive("connect_timeout_s", self.connect_timeout_s)
        check_positive("worker_timeout_s", self.worker_timeout_s)


#: Where tasks run.
Executor = LocalPool | DaskScheduler


def as_executor(where: int | Executor) -> Executor:
    """``where`` itself if it is an executor, else ``LocalPool(where)`` (a number of processes).

    Raises:
        InvalidParameterError: a number of processes < 1, or neither a number nor an executor.
    """
    if isinstance(where, LocalPool | DaskScheduler):
        return where
    return LocalPool(check_positive_int("jobs", where, minimum=1))


def default_chunk_size(n_tasks: int, workers: int) -> int:
    """About four chunks per worker, at most :data:`MAX_DEFAULT_CHUNK` tasks each, at least one."""
    check_positive_int("jobs", workers, minimum=1)
    return max(1, min(MAX_DEFAULT_CHUNK, math.ceil(n_tasks / (4 * workers))))


def check_executor(executor: int | Executor) -> None:
    """Fail now rather than after some work: for a :class:`DaskScheduler`, connect to its scheduler,
    wait for a worker, and disconnect (a local pool needs no check).

    Raises:
        SchedulerUnreachableError: the scheduler cannot be reached within its timeout (or
            ``distributed`` is not installed).
        NoDaskWorkersError: no worker joined it within ``worker_timeout_s``.
    """
    executor = as_executor(executor)
    if isinstance(executor, DaskScheduler):
        _connect(executor).close()


def map_tasks(
    executor: int | Executor,
    function: Callable[[Task], Result],
    tasks: Sequence[Task],
    on_done: Callable[[int, Result], None] | None = None,
    *,
    chunk_size: int | None = None,
) -> list[Result]:
    """``[function(task) for task in tasks]``, in task order, on ``executor``.

    Args:
        executor: Where to run: a :class:`LocalPool`, a :class:`DaskScheduler`, or a number of
            local processes (``LocalPool(jobs)``).
        function: Applied to each task; picklable (a module-level function or a
            ``functools.partial`` of one) unless it runs in this process (``LocalPool(1)``).
        tasks: The tasks (picklable, as ``function``).
        on_done: Called in this process once per task, ``on_done(index, result)``, as the tasks
            finish (the tasks of one chunk together, the chunks in the order they finish).
        chunk_size: Tasks per worker call; default :func:`default_chunk_size` of the workers.

    Raises:
        InvalidParameterError: ``jobs`` or ``chunk_size`` < 1.
        WorkerPoolError: a local worker process died, or this is a worker still importing the
            main script (a script without a ``__main__`` guard).
        SchedulerUnreachableError: the Dask scheduler cannot be reached (before any task runs).
        NoDaskWorkersError: it has no worker within ``worker_timeout_s`` (before any task runs).
        Whatever ``function`` raises (the first failing chunk's error), KeyboardInterrupt, or
        :class:`pipeline.io.signals.Terminated` (the local workers then terminated and joined).
    """
    executor = as_executor(executor)
    work = list(tasks)
    if chunk_size is not None:
        check_positive_int("chunk_size", chunk_size, minimum=1)
    report = on_done if on_done is not None else _ignore

    def chunk_done(start: int, results: list[Result]) -> None:
        for offset, result in enumerate(results):
            report(start + offset, result)

    if isinstance(executor, DaskScheduler):
        return _dask_map(executor, function, work, chunk_size, chunk_done)
    size = default_chunk_size(len(work), executor.jobs) if chunk_size is None else chunk_size
    starts = range(0, len(work), size)
    if executor.jobs == 1 or len(starts) <= 1:
        results: list[Result] = []
        for start in starts:
            done = _run_chunk(function, work[start : start + size])
            results.extend(done)
            chunk_done(start, done)
        return results
    return _pool_map(function, work, size, min(executor.jobs, len(starts)), chunk_done, executor.start_method)


def _ignore(_index: int, _result: Any) -> None:
    return None


def _run_chunk(function: Callable[[Task], Result], chunk: Sequence[Task]) -> list[Result]:
    return [function(task) for task in chunk]


def _run_dask_chunk(function: Callable[[Task], Result], chunk: Sequence[Task]) -> list[Result]:
    """:func:`_run_chunk` on a Dask worker, after restoring the allocator's speed for NumPy
    temporaries there (:func:`pipeline.io.allocator.raise_mmap_threshold`: the nanny's
    ``MALLOC_TRIM_THRESHOLD_`` made the certificate's tasks slower per core)."""
    raise_mmap_threshold()
    return _run_chunk(function, chunk)


def _pool_map(
    function: Callable[[Task], Result],
    work: list[Task],
    size: int,
    jobs: int,
    chunk_done: Callable[[int, list[Result]], None],
    start_method: str = "spawn",
) -> list[Result]:
    if getattr(multiprocessing.current_process(), "_inheriting", False):
        # A spawned worker re-running an unguarded script: end it quietly; the parent's pool
        # breaks and raises WorkerPoolError, which says why (one message, not one per worker).
        raise SystemExit(1)
    done: dict[int, list[Result]] = {}
    pool = ProcessPoolExecutor(
        max_workers=jobs, mp_context=multiprocessing.get_context(start_method), initializer=default_termination
    )
    try:
        pending: dict[Future, int] = {
            pool.submit(_run_chunk, function, work[start : start + size]): start for start in range(0, len(work), size)
        }
        while pending:
            finished, _ = wait(pending, return_when=FIRST_COMPLETED)
            for future in finished:
                start = pending.pop(future)
                done[start] = future.result()
                chunk_done(start, done[start])
    except BrokenProcessPool:
        pool.shutdown(wait=True, cancel_futures=True)
        raise WorkerPoolError("a worker process ended abruptly") from None
    except Exception:
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    except BaseException:  # Ctrl-C, a termination signal: the workers are stopped, not waited for
        _stop_workers(pool)
        raise
    pool.shutdown(wait=True)
    return [result for start in sorted(done) for result in done[start]]


def _stop_workers(pool: ProcessPoolExecutor) -> None:
    """Terminate the pool's worker processes (SIGTERM, then SIGKILL for one that outlives
    :data:`WORKER_STOP_TIMEOUT_S`), cancel its chunks not yet started, and join its workers and
    its manager thread: nothing of the pool runs once this returns."""
    terminate = getattr(pool, "terminate_workers", None)  # Python 3.14
    processes = list((getattr(pool, "_processes", None) or {}).values())  # before 3.14: the pool's own record
    if terminate is not None:
        terminate()
    for process in processes:
        with contextlib.suppress(OSError, ValueError):  # already ended and closed
            process.terminate()
    for process in processes:
        with contextlib.suppress(OSError, ValueError):
            process.join(WORKER_STOP_TIMEOUT_S)
            if process.exitcode is None:
                process.kill()
                process.join()
    pool.shutdown(wait=True, cancel_futures=True)


def _connect(scheduler: DaskScheduler) -> Any:
    """A ``distributed.Client`` connected to ``scheduler`` with at least one worker (the caller
    closes it).

    Raises:
        SchedulerUnreachableError: not within ``scheduler.connect_timeout_s``, or no ``distributed``.
        NoDaskWorkersError: no worker within ``scheduler.worker_timeout_s`` (the client is closed).
    """
    try:
        import distributed  # lazily: only a Dask executor needs it
    except ImportError:
        raise SchedulerUnreachableError(
            scheduler.address, "the distributed package is not installed (pip install 'twolink-obstacle[dask]')"
        ) from None
    try:
        client = distributed.Client(scheduler.address, timeout=scheduler.connect_timeout_s, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise SchedulerUnreachableError(scheduler.address, str(exc) or type(exc).__name__) from None
    try:
        client.wait_for_workers(1, timeout=scheduler.worker_timeout_s)
    except TimeoutError:  # distributed's WorkerStartTimeoutError is one
        client.close()
        raise NoDaskWorkersError(scheduler.address, scheduler.worker_timeout_s) from None
    except OSError as exc:  # the connection dropped while waiting
        client.close()
        raise SchedulerUnreachableError(scheduler.address, str(exc) or type(exc).__name__) from None
    except BaseException:
        client.close()
        raise
    return client


def _dask_map(
    scheduler: DaskScheduler,
    function: Callable[[Task], Result],
    work: list[Task],
    chunk_size: int | None,
    chunk_done: Callable[[int, list[Result]], None],
) -> list[Result]:
    if not work:
        return []
    import distributed  # _connect has checked that it is installed

    client = _connect(scheduler)
    try:
        if chunk_size is None:
            workers = sum(client.nthreads().values()) or 1
            chunk_size = default_chunk_size(len(work), workers)
        starts = range(0, len(work), chunk_size)
        futures = [client.submit(_run_dask_chunk, function, work[s : s + chunk_size], pure=False) for s in starts]
        start_of = {future.key: start for future, start in zip(futures, starts, strict=True)}
        done: dict[int, list[Result]] = {}
        try:
            for future in distributed.as_completed(futures, loop=client.loop):
                start = start_of[future.key]
                done[start] = future.result()
                chunk_done(start, done[start])
        except BaseException:
            with contextlib.suppress(Exception):  # the connection may be what failed
                client.cancel([future for future in futures if not future.done()])
            raise
        return [result for start in starts for result in done[start]]
    finally:
        client.close()
