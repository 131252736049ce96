"""One process-pool map for the project: chunked, ordered, and with results that do not depend on
the number of processes.

``process_map(function, items, jobs=J)`` returns ``[function(item) for item in items]``. With
``jobs == 1`` it runs in this process (``function`` may then be any callable, a closure over
already loaded objects included); with ``jobs > 1`` the items are cut into chunks that worker
processes (started with ``spawn``, so no state is inherited by accident) evaluate, and
``function`` and the items must be picklable. Either way the result list is in item order.

The results do not depend on ``jobs`` or on the chunk size as long as ``function`` is a pure
function of its item. Work that draws random numbers must therefore carry its own seed in the
item: :func:`item_seeds` gives each item an independent ``SeedSequence`` child of one seed, the
same whatever the chunking.

Ctrl-C (or any error) cancels the chunks not yet started and shuts the pool down before the
exception propagates.

A worker started with ``spawn`` imports the main module of the program again. A script that
starts a pool must therefore do so under ``if __name__ == "__main__":``; without it each worker
would start the work again, and multiprocessing stops it: the pool breaks, and
:func:`process_map` raises :class:`pipeline.exceptions.WorkerPoolError`, which says so. In a
worker that is still importing the main module, :func:`process_map` ends the worker quietly
instead of starting a pool of its own, so the message is the parent's alone.
"""

from __future__ import annotations

import math
import multiprocessing
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import TypeVar

import numpy as np

from pipeline.exceptions import WorkerPoolError
from pipeline.validation import check_positive_int

Item = TypeVar("Item")
Result = TypeVar("Result")

#: Upper bound of the default chunk size [items]: small enough that progress is reported often.
MAX_DEFAULT_CHUNK = 16


def default_chunk_size(n_items: int, jobs: int) -> int:
    """About four chunks per process, at most :data:`MAX_DEFAULT_CHUNK` items each, at least one."""
    check_positive_int("jobs", jobs, minimum=1)
    return max(1, min(MAX_DEFAULT_CHUNK, math.ceil(n_items / (4 * jobs))))


def item_seeds(seed: int, n_items: int) -> list[np.random.SeedSequence]:
    """One independent ``SeedSequence`` per item, children of ``SeedSequence(seed)`` in item order."""
    check_positive_int("seed", seed, minimum=0)
    check_positive_int("n_items", n_items, minimum=0)
    return np.random.SeedSequence(seed).spawn(n_items)


def _run_chunk(function: Callable[[Item], Result], chunk: Sequence[Item]) -> list[Result]:
    return [function(item) for item in chunk]


def process_map(
    function: Callable[[Item], Result],
    items: Iterable[Item],
    *,
    jobs: int = 1,
    chunk_size: int | None = None,
    on_done: Callable[[list[Result]], None] | None = None,
) -> list[Result]:
    """``[function(item) for item in items]``, in item order, on ``jobs`` processes.

    Args:
        function: Applied to each item; picklable (a module-level function or a
            ``functools.partial`` of one) when ``jobs > 1``.
        items: The work items (picklable when ``jobs > 1``).
        jobs: Number of processes, >= 1 (1: in this process, no pool).
        chunk_size: Items per worker call; default :func:`default_chunk_size`.
        on_done: Called in this process with the results of each finished chunk (in the order the
            chunks finish; ``len`` of it counts progress).

    Raises:
        InvalidParameterError: ``jobs`` or ``chunk_size`` < 1.
        WorkerPoolError: a worker process died, or this is a worker still importing the main
            script (a script without a ``__main__`` guard).
        Whatever ``function`` raises (the first failing chunk's error), or KeyboardInterrupt.
    """
    check_positive_int("jobs", jobs, minimum=1)
    work = list(items)
    size = default_chunk_size(len(work), jobs) if chunk_size is None else chunk_size
    check_positive_int("chunk_size", size, minimum=1)
    chunks = [work[i : i + size] for i in range(0, len(work), size)]
    report = on_done if on_done is not None else (lambda _results: None)
    if jobs == 1 or len(chunks) <= 1:
        results: list[Result] = []
        for chunk in chunks:
            done = _run_chunk(function, chunk)
            results.extend(done)
            report(done)
        return results
    return _pool_map(function, chunks, min(jobs, len(chunks)), report)


def _pool_map(
    function: Callable[[Item], Result],
    chunks: list[list[Item]],
    jobs: int,
    report: Callable[[list[Result]], None],
) -> list[Result]:
    if getattr(multiprocessing.current_process(), "_inheriting", False):
        # A spawned worker re-running an unguarded script: end it quietly; the parent's pool
        # breaks and raises WorkerPoolError, which says why (one message, not one per worker).
        raise SystemExit(1)
    done: list[list[Result] | None] = [None] * len(chunks)
    pool = ProcessPoolExecutor(max_workers=jobs, mp_context=multiprocessing.get_context("spawn"))
    try:
        pending: dict[Future, int] = {pool.submit(_run_chunk, function, chunk): k for k, chunk in enumerate(chunks)}
        while pending:
            finished, _ = wait(pending, return_when=FIRST_COMPLETED)
            for future in finished:
                index = pending.pop(future)
                done[index] = future.result()
                report(done[index])
    except BrokenProcessPool:
        pool.shutdown(wait=True, cancel_futures=True)
        raise WorkerPoolError("a worker process ended abruptly") from None
    except BaseException:
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    pool.shutdown(wait=True)
    return [result for chunk in done if chunk is not None for result in chunk]
