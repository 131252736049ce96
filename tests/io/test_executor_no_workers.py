"""pipeline.io.executor with a Dask scheduler that has no workers: the work waits at most
``DaskScheduler.worker_timeout_s`` for one, then stops before any task runs with one line naming
the address and the timeout (a SchedulerUnreachableError, so a PipelineError); the build's and
the range certificate's CLIs wait their ``--worker-timeout`` and exit 2 with that line; a worker
that joins in time is used."""

from __future__ import annotations

import pickle
import threading
import time
from pathlib import Path

import pytest

from pipeline.build import config as build_config
from pipeline.commands import build as build_command
from pipeline.commands import certify_range as certify_range_command
from pipeline.exceptions import InvalidParameterError, PipelineError, SchedulerUnreachableError
from pipeline.io.executor import (
    DEFAULT_WORKER_TIMEOUT_S,
    DaskScheduler,
    NoDaskWorkersError,
    check_executor,
    map_tasks,
)

distributed = pytest.importorskip("distributed")

TIMEOUT_S = 1.0


@pytest.fixture
def empty_cluster():
    """A Dask scheduler in this process with no worker at all, on a TCP address (as a build is given)."""
    with distributed.LocalCluster(
        n_workers=0, processes=False, protocol="tcp", host="127.0.0.1", dashboard_address=None
    ) as cluster:
        yield cluster


def test_the_worker_timeout_is_a_checked_field() -> None:
    assert DaskScheduler("localhost:8786").worker_timeout_s == DEFAULT_WORKER_TIMEOUT_S == 30.0
    assert DaskScheduler("localhost:8786", worker_timeout_s=0.5).worker_timeout_s == 0.5
    for bad in (0.0, -1.0, float("nan"), float("inf"), None):
        with pytest.raises(InvalidParameterError, match="worker_timeout_s"):
            DaskScheduler("localhost:8786", worker_timeout_s=bad)


def test_no_workers_is_one_line_naming_the_address_and_timeout_before_any_work(empty_cluster) -> None:
    address = empty_cluster.scheduler_address
    scheduler = DaskScheduler(address, worker_timeout_s=TIMEOUT_S)
    reported: list = []
    started = time.perf_counter()
    with pytest.raises(NoDaskWorkersError) as caught:
        map_tasks(scheduler, abs, [1, 2, 3], lambda *call: reported.append(call))
    waited = time.perf_counter() - started
    assert TIMEOUT_S <= waited < TIMEOUT_S + 10.0
    assert not reported
    error = caught.value
    assert isinstance(error, SchedulerUnreachableError) and isinstance(error, PipelineError)
    assert error.address == address and error.timeout_s == TIMEOUT_S
    message = str(error)
    assert len(message.splitlines()) == 1 and address in message and "1 s" in message and "no workers" in message
    assert str(pickle.loads(pickle.dumps(error))) == message
    with pytest.raises(NoDaskWorkersError, match="no workers"):
        check_executor(scheduler)
    assert not empty_cluster.scheduler.tasks  # nothing was submitted


def test_a_worker_that_joins_within_the_timeout_is_used(empty_cluster) -> None:
    scheduler = DaskScheduler(empty_cluster.scheduler_address, worker_timeout_s=30.0)
    joiner = threading.Timer(0.5, lambda: empty_cluster.scale(1))
    joiner.start()
    try:
        assert map_tasks(scheduler, abs, [-1, -2, 3]) == [1, 2, 3]
    finally:
        joiner.cancel()


@pytest.mark.parametrize("command", ["build", "certify_range"])
def test_the_clis_wait_worker_timeout_then_exit_2_with_one_line(
    command: str, empty_cluster, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    address = empty_cluster.scheduler_address
    timeout = ["--scheduler", address, "--worker-timeout", str(TIMEOUT_S), "--no-progress"]
    started = time.perf_counter()
    if command == "build":
        status = build_command.main([*timeout, "--out", str(out)])
    else:
        out.mkdir()
        status = certify_range_command.main(["paper", *timeout, "--output", str(out / "map.json")])
    assert TIMEOUT_S <= time.perf_counter() - started < TIMEOUT_S + 20.0  # its timeout, not the default 30 s
    assert status == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith(f"python -m pipeline.{command}: error:") and address in lines[0] and "1 s" in lines[0]
    assert not out.exists() or not any(out.iterdir())  # nothing written


def test_the_build_config_passes_its_worker_timeout_and_checks_it() -> None:
    config = build_config.BuildConfig.from_settings(scheduler="tcp://127.0.0.1:8786", worker_timeout_s=2.5)
    assert config.execution.executor == DaskScheduler("tcp://127.0.0.1:8786", worker_timeout_s=2.5)
    assert (
        build_config.BuildConfig.from_settings(scheduler="tcp://127.0.0.1:8786").execution.executor.worker_timeout_s
        == 30.0
    )
    for bad in (0.0, -1.0, float("nan"), float("inf"), True, "5"):
        with pytest.raises(InvalidParameterError, match=r"^--worker-timeout = "):
            build_config.BuildConfig.from_settings(worker_timeout_s=bad)
