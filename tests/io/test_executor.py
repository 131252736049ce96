"""pipeline.io.executor: the same results, in task order, on this process, a local pool and a Dask
cluster; progress once per task; errors that reach the caller; an unreachable scheduler refused
in one line before any work; addresses checked; ``distributed`` imported only when used."""

from __future__ import annotations

import functools
import re
import subprocess
import sys
import time

import numpy as np
import pytest

from pipeline.exceptions import InvalidParameterError, PipelineError, SchedulerUnreachableError
from pipeline.io.executor import (
    DaskScheduler,
    LocalPool,
    as_executor,
    check_executor,
    check_scheduler_address,
    map_tasks,
)
from pipeline.io.parallel import item_seeds

distributed = pytest.importorskip("distributed")

#: Nothing listens there: connection refused.
UNREACHABLE = "tcp://127.0.0.1:1"


def draw(scale: float, seed: np.random.SeedSequence) -> float:
    """A random number from the task's own seed (module level: picklable for the workers)."""
    return scale * float(np.random.default_rng(seed).random())


def fail_on_three(value: int) -> int:
    if value == 3:
        raise ValueError(f"task {value}")
    return value


@pytest.fixture(scope="module")
def cluster():
    """Two single-threaded worker processes, as a small Dask cluster on this machine."""
    with distributed.LocalCluster(
        n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None
    ) as local_cluster:
        yield local_cluster


def executors(cluster) -> dict[str, object]:
    return {
        "in process": LocalPool(1),
        "local pool": LocalPool(2),
        "dask": DaskScheduler(cluster.scheduler_address),
    }


def test_every_executor_gives_the_same_results_in_task_order_and_reports_each_task_once(cluster) -> None:
    tasks = item_seeds(7, 23)
    function = functools.partial(draw, 2.0)
    serial = [function(task) for task in tasks]
    assert len(set(serial)) == 23
    for name, executor in executors(cluster).items():
        for chunk_size in (None, 4):
            reported: list[tuple[int, float]] = []

            def on_done(index: int, result: float, reported: list = reported) -> None:
                reported.append((index, result))

            results = map_tasks(executor, function, tasks, on_done, chunk_size=chunk_size)
            assert results == serial, (name, chunk_size)
            assert sorted(k for k, _ in reported) == list(range(23)), (name, chunk_size)
            assert all(serial[k] == r for k, r in reported), (name, chunk_size)
        assert map_tasks(executor, abs, []) == [], name


def test_a_number_of_jobs_is_a_local_pool() -> None:
    assert as_executor(3) == LocalPool(3)
    assert as_executor(LocalPool(2)) == LocalPool(2)
    assert map_tasks(2, abs, range(-5, 0)) == [5, 4, 3, 2, 1]
    offset = 5  # a closure runs in this process
    assert map_tasks(1, lambda x: x + offset, [1, 2]) == [6, 7]


def test_an_error_in_a_task_reaches_the_caller_and_the_cluster_stays_usable(cluster) -> None:
    for name, executor in executors(cluster).items():
        with pytest.raises(ValueError, match="task 3"):
            map_tasks(executor, fail_on_three, range(8), chunk_size=2)
        assert map_tasks(executor, fail_on_three, [0, 1, 2]) == [0, 1, 2], name


def test_an_unreachable_scheduler_is_one_line_naming_it_before_any_work() -> None:
    scheduler = DaskScheduler(UNREACHABLE, connect_timeout_s=2.0)
    reported: list = []
    started = time.perf_counter()
    with pytest.raises(SchedulerUnreachableError) as caught:
        map_tasks(scheduler, abs, [1, 2, 3], lambda *call: reported.append(call))
    assert time.perf_counter() - started < 30.0
    assert not reported
    error = caught.value
    assert isinstance(error, PipelineError) and error.address == UNREACHABLE
    assert len(str(error).splitlines()) == 1 and UNREACHABLE in str(error)
    with pytest.raises(SchedulerUnreachableError, match=re.escape(UNREACHABLE)):
        check_executor(scheduler)
    check_executor(LocalPool(2))  # nothing to check


@pytest.mark.parametrize(
    "address", ["localhost:8786", "tcp://10.0.0.5:8786", "tcp://[::1]:8786", "scheduler-1.example.org:1"]
)
def test_scheduler_addresses_are_host_and_port(address: str) -> None:
    assert check_scheduler_address("--scheduler", address) == address
    assert DaskScheduler(address).address == address


@pytest.mark.parametrize(
    "address", ["", "localhost", "tcp://host", "http://host:8786", "host:0", "host:70000", "a b:1", 8786, None]
)
def test_anything_else_is_refused_naming_the_option(address) -> None:
    with pytest.raises(InvalidParameterError, match="--scheduler"):
        check_scheduler_address("--scheduler", address)
    with pytest.raises(InvalidParameterError):
        DaskScheduler(address)


@pytest.mark.parametrize("value", [0, -1, 1.5, True, "2"])
def test_bad_numbers_of_jobs_are_refused(value) -> None:
    with pytest.raises(InvalidParameterError):
        LocalPool(value)
    with pytest.raises(InvalidParameterError):
        map_tasks(value, abs, [1])


def test_distributed_is_imported_only_when_a_dask_executor_is_used() -> None:
    code = (
        "import sys, pipeline, pipeline.build, pipeline.commands.build, pipeline.io.executor as e\n"
        "assert 'distributed' not in sys.modules and 'dask' not in sys.modules\n"
        "e.map_tasks(e.LocalPool(1), abs, [1])\n"
        "assert 'distributed' not in sys.modules\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
