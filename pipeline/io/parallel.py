"""Seeds per work item, and the list form of :func:`pipeline.io.executor.map_tasks` on a local
pool: results that do not depend on the number of processes.

``process_map(function, items, jobs=J)`` returns ``[function(item) for item in items]``, in item
order, on ``LocalPool(J)`` (:mod:`pipeline.io.executor`: with ``jobs == 1`` in this process, where
``function`` may be any callable, a closure over already loaded objects included; otherwise in
worker processes started with ``spawn``, with everything that implies: picklable work, Ctrl-C and
errors cancel, a one-line :class:`pipeline.exceptions.WorkerPoolError` for a script without a
``__main__`` guard).

The results do not depend on ``jobs`` or on the chunk size as long as ``function`` is a pure
function of its item. Work that draws random numbers must therefore carry its own seed in the
item: :func:`item_seeds` gives each item an independent ``SeedSequence`` child of one seed, the
same whatever the chunking.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import TypeVar

import numpy as np

from pipeline.io.executor import MAX_DEFAULT_CHUNK, LocalPool, default_chunk_size, map_tasks
from pipeline.validation import check_positive_int

__all__ = ["MAX_DEFAULT_CHUNK", "default_chunk_size", "item_seeds", "process_map"]

Item = TypeVar("Item")
Result = TypeVar("Result")


def item_seeds(seed: int, n_items: int) -> list[np.random.SeedSequence]:
    """One independent ``SeedSequence`` per item, children of ``SeedSequence(seed)`` in item order."""
    check_positive_int("seed", seed, minimum=0)
    check_positive_int("n_items", n_items, minimum=0)
    return np.random.SeedSequence(seed).spawn(n_items)


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
    pool = LocalPool(jobs)
    work = list(items)
    size = default_chunk_size(len(work), pool.jobs) if chunk_size is None else chunk_size
    check_positive_int("chunk_size", size, minimum=1)
    report = None
    if on_done is not None:
        chunks: dict[int, list[Result]] = {}

        def report(index: int, result: Result) -> None:
            # The tasks of a chunk are reported together: pass the chunk on when it is whole.
            chunk = chunks.setdefault(index // size, [])
            chunk.append(result)
            if len(chunk) == min(size, len(work) - (index // size) * size):
                on_done(chunks.pop(index // size))

    return map_tasks(pool, function, work, report, chunk_size=size)
