"""pipeline.io.allocator: under a Dask nanny's MALLOC_TRIM_THRESHOLD_ a 1 MiB NumPy array is a
fresh mmap (the slow path the module docstring measures); after raise_mmap_threshold, and in
every chunk the executor runs on a Dask worker, it comes from the heap."""

from __future__ import annotations

import os
import platform
import subprocess
import sys

import numpy as np
import pytest

from pipeline.io.allocator import MMAP_THRESHOLD_BYTES, mmapped_bytes, raise_mmap_threshold
from pipeline.io.executor import DaskScheduler, map_tasks

glibc = pytest.mark.skipif(
    platform.system() != "Linux" or platform.libc_ver()[0] != "glibc", reason="the allocator tuned is glibc's"
)

#: The array size probed [bytes]: above glibc's initial mmap threshold (128 KiB), below ours.
PROBE_BYTES = 1 << 20


def mapped_by_one_array(_task: object = None) -> int:
    """Bytes the allocator mmapped to hold one new array of :data:`PROBE_BYTES` (0: from the heap)."""
    before = mmapped_bytes()
    array = np.ones(PROBE_BYTES // 8)
    during = mmapped_bytes()
    del array
    return during - before


@glibc
def test_under_a_trim_threshold_a_mebibyte_array_is_mmapped_until_the_threshold_is_raised() -> None:
    # This module's own probe, run in a process started with the variable set.
    script = (
        "import runpy, sys\n"
        "from pipeline.io.allocator import raise_mmap_threshold as r\n"
        "m = runpy.run_path(sys.argv[1])['mapped_by_one_array']\n"
        "print(m(), m(), r(), m(), m())\n"
    )
    env = {**os.environ, "MALLOC_TRIM_THRESHOLD_": "65536"}
    out = subprocess.run([sys.executable, "-c", script, __file__], env=env, capture_output=True, text=True, check=True)
    before_1, before_2, accepted, after_1, after_2 = out.stdout.split()
    assert int(before_1) >= PROBE_BYTES and int(before_2) >= PROBE_BYTES  # the slow path, every time
    assert accepted == "True"
    assert int(after_1) == 0 and int(after_2) == 0


@glibc
def test_raise_mmap_threshold_is_accepted_and_mmapped_bytes_reads_a_count() -> None:
    assert raise_mmap_threshold() is True
    assert raise_mmap_threshold() is True  # idempotent
    assert isinstance(mmapped_bytes(), int) and mmapped_bytes() >= 0
    assert mapped_by_one_array() == 0
    big = np.ones(2 * MMAP_THRESHOLD_BYTES // 8)  # above the raised threshold: still mmapped
    assert mmapped_bytes() >= big.nbytes


@glibc
def test_every_dask_chunk_runs_with_the_raised_threshold() -> None:
    distributed = pytest.importorskip("distributed")
    with (
        distributed.LocalCluster(n_workers=1, processes=True, threads_per_worker=1, dashboard_address=None) as cluster,
        distributed.Client(cluster) as client,
    ):
        # The nanny's default environment: a plain task takes the slow path ...
        assert client.submit(mapped_by_one_array, pure=False).result() >= PROBE_BYTES
        # ... a task through map_tasks does not.
        assert map_tasks(DaskScheduler(cluster.scheduler_address), mapped_by_one_array, range(3)) == [0, 0, 0]
