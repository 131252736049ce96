"""pipeline.io.parallel.process_map: ordered results that depend neither on the number of
processes nor on the chunk size, seeds per item, progress, errors and bad arguments."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from pipeline.exceptions import InvalidParameterError
from pipeline.io.parallel import default_chunk_size, item_seeds, process_map


def draw(scale: float, seed: np.random.SeedSequence) -> float:
    """A random number from the item's own seed (module level: picklable for worker processes)."""
    return scale * float(np.random.default_rng(seed).random())


def fail_on_three(value: int) -> int:
    if value == 3:
        raise ValueError(f"item {value}")
    return value


def test_results_are_in_item_order_whatever_the_processes_and_chunks():
    seeds = item_seeds(7, 23)
    function = functools.partial(draw, 2.0)
    serial = process_map(function, seeds, jobs=1)
    assert len(serial) == 23 and len(set(serial)) == 23
    assert process_map(function, seeds, jobs=1, chunk_size=5) == serial
    assert process_map(function, item_seeds(8, 23), jobs=1) != serial
    seen: list[int] = []  # one pool only: worker processes are slow to start on a loaded machine
    assert process_map(function, seeds, jobs=2, chunk_size=4, on_done=lambda done: seen.append(len(done))) == serial
    assert sorted(seen) == [3, 4, 4, 4, 4, 4]


def test_seeds_are_children_of_one_seed_in_item_order():
    first = [s.generate_state(1)[0] for s in item_seeds(3, 5)]
    assert first == [s.generate_state(1)[0] for s in item_seeds(3, 5)]
    assert first[:3] == [s.generate_state(1)[0] for s in item_seeds(3, 3)]  # prefix does not depend on n
    assert len(set(first)) == 5


def test_each_finished_chunk_is_reported_once():
    seen: list[int] = []
    assert process_map(abs, range(-10, 0), jobs=1, chunk_size=3, on_done=lambda done: seen.append(len(done))) == list(
        range(10, 0, -1)
    )
    assert seen == [3, 3, 3, 1]
    chunks: list[list[int]] = []
    process_map(abs, range(-4, 0), jobs=1, chunk_size=2, on_done=chunks.append)
    assert chunks == [[4, 3], [2, 1]]


def test_a_failing_item_raises_its_error_in_the_caller():
    for jobs in (1, 2):
        with pytest.raises(ValueError, match="item 3"):
            process_map(fail_on_three, range(8), jobs=jobs, chunk_size=2)


def test_closures_run_in_process_and_empty_input_gives_nothing():
    offset = 5
    assert process_map(lambda x: x + offset, [1, 2], jobs=1) == [6, 7]
    assert process_map(abs, [], jobs=2) == []


@pytest.mark.parametrize("kwargs", [{"jobs": 0}, {"jobs": -1}, {"jobs": 1.5}, {"chunk_size": 0}])
def test_bad_arguments_are_refused(kwargs):
    with pytest.raises(InvalidParameterError):
        process_map(abs, [1], **kwargs)


def test_default_chunks_are_small_and_about_four_per_process():
    assert default_chunk_size(1000, 2) == 16
    assert default_chunk_size(40, 2) == 5
    assert default_chunk_size(1, 8) == 1


def test_a_script_without_a_main_guard_gets_one_clear_error(tmp_path) -> None:
    """Spawned workers re-import the script: without ``if __name__ == "__main__":`` they would start
    the work again. They end quietly and the caller gets one WorkerPoolError saying what to add."""
    import subprocess
    import sys

    script = tmp_path / "unguarded.py"
    script.write_text("from pipeline.io.parallel import process_map\nprint(process_map(abs, range(-40, 0), jobs=2))\n")
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert done.returncode == 1
    assert done.stderr.count("Traceback") == 1, done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("pipeline.exceptions.WorkerPoolError:") and 'if __name__ == "__main__":' in last
    guarded = tmp_path / "guarded.py"
    guarded.write_text(
        "from pipeline.io.parallel import process_map\n"
        "if __name__ == '__main__':\n    print(process_map(abs, range(-40, 0), jobs=2))\n"
    )
    done = subprocess.run([sys.executable, str(guarded)], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == str(list(range(40, 0, -1)))
