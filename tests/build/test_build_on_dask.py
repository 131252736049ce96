"""The build on a Dask cluster (``BuildConfig.from_settings(scheduler=...)``, ``--scheduler``): the
same bytes as on the local pool, and an unreachable scheduler refused in one line before any work."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from pipeline import BuildConfig, run_build
from pipeline.commands import build as build_command
from pipeline.commands import certify_range as certify_range_command
from pipeline.exceptions import InvalidParameterError, SchedulerUnreachableError
from pipeline.io.executor import DaskScheduler, LocalPool

distributed = pytest.importorskip("distributed")

#: Nothing listens there: connection refused.
UNREACHABLE = "tcp://127.0.0.1:1"
#: The timing file holds wall times: the one output file that differs from run to run.
TIMING = "build_timing.json"
#: A DOE this rough does not converge (tests/offline/test_build_config.py): written marked, no map.
TINY = {"swarm_size": 8, "iterations": 5, "restarts": 1, "endpoint_tolerance_m": None, "allow_unconverged": True}


@pytest.fixture(scope="module")
def cluster():
    """Two single-threaded worker processes, as a small Dask cluster on this machine."""
    with distributed.LocalCluster(
        n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None
    ) as local_cluster:
        yield local_cluster


def files(folder: Path) -> dict[str, bytes]:
    return {path.name: path.read_bytes() for path in sorted(folder.iterdir())}


def assert_same_files(local: Path, dask: Path) -> None:
    """The same file names, and byte for byte the same files but the timing."""
    on_pool, on_cluster = files(local), files(dask)
    assert sorted(on_pool) == sorted(on_cluster)
    for name in on_pool:
        if name != TIMING:
            assert on_pool[name] == on_cluster[name], name


def test_the_range_stage_on_a_cluster_writes_the_local_pools_bytes(replayed: list, tmp_path: Path, cluster) -> None:
    """The DOE replayed, then the regression and a coarse map, its tasks on the cluster's workers
    (without the certifiable regression's rounds: they run the same map's tasks, after a refit in
    this process that takes most of a build's time)."""
    local, dask = tmp_path / "local", tmp_path / "dask"
    run_build(BuildConfig.from_settings(out_folder=local, jobs=2, clearance_rounds=0))
    result = run_build(
        BuildConfig.from_settings(out_folder=dask, scheduler=cluster.scheduler_address, clearance_rounds=0)
    )
    assert result.region_map is not None
    assert sorted(files(dask)) == [
        "build_timing.json",
        "coefficients.json",
        "doe.json",
        "near_optimal_cells.json",
        "near_optimal_cells.npy",
        "region_map.json",
        "region_map.npy",
    ]
    assert_same_files(local, dask)
    assert json.loads((dask / TIMING).read_text())["scheduler"] == cluster.scheduler_address


@pytest.mark.filterwarnings("ignore::pipeline.exceptions.UnconvergedCoefficientsWarning")
def test_the_doe_on_a_cluster_gives_the_local_pools_optima(tmp_path: Path, cluster) -> None:
    """A real (rough) DOE, each experiment on a worker of the cluster: the same doe.json and
    coefficients.json as two local processes."""
    local, dask = tmp_path / "local", tmp_path / "dask"
    run_build(BuildConfig.from_settings(out_folder=local, jobs=2, **TINY))
    run_build(BuildConfig.from_settings(out_folder=dask, scheduler=cluster.scheduler_address, **TINY))
    assert sorted(files(dask)) == ["build_timing.json", "coefficients.json", "doe.json"]
    assert_same_files(local, dask)


def test_the_scheduler_chooses_the_executor_and_is_checked_on_construction() -> None:
    assert BuildConfig.from_settings(jobs=3).execution.executor == LocalPool(3)
    config = BuildConfig.from_settings(jobs=3, scheduler="tcp://10.0.0.5:8786")
    assert config.execution.executor == DaskScheduler("tcp://10.0.0.5:8786")
    for bad in ("", "10.0.0.5", "tcp://10.0.0.5", 8786):
        with pytest.raises(InvalidParameterError, match="--scheduler"):
            BuildConfig.from_settings(scheduler=bad)


def test_run_build_refuses_an_unreachable_scheduler_before_any_work(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from pipeline.build import doe_fit

    monkeypatch.setattr(doe_fit, "run_doe", lambda *args, **kwargs: pytest.fail("the DOE started"))
    out = tmp_path / "results"
    with pytest.raises(SchedulerUnreachableError, match=re.escape(UNREACHABLE)):
        run_build(BuildConfig.from_settings(out_folder=out, scheduler=UNREACHABLE))
    assert not out.exists()


def test_the_command_line_exits_with_one_line_and_creates_nothing(tmp_path: Path) -> None:
    out = tmp_path / "results"
    done = subprocess.run(
        [sys.executable, "-m", "pipeline.build", "--scheduler", UNREACHABLE, "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode != 0
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert lines[0].startswith("python -m pipeline.build: error: ") and UNREACHABLE in lines[0]
    assert not out.exists()


def test_bad_scheduler_options_are_one_line_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert build_command.main(["--scheduler", "nowhere", "--out", str(tmp_path / "a")]) == 2
    assert certify_range_command.main(["paper", "--scheduler", "nowhere"]) == 2
    assert certify_range_command.main(["paper", "--scheduler", UNREACHABLE]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 3, lines
    assert all("--scheduler" in line for line in lines[:2])
    assert lines[2].startswith("python -m pipeline.certify_range: error: ") and UNREACHABLE in lines[2]
    assert not (tmp_path / "a").exists()


def test_an_l_w_x_map_on_a_cluster_has_the_local_pools_bytes(over_x, cluster) -> None:
    """The range certificate over (L, W, x): one worker, two workers and the cluster give one map."""
    from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
    from pipeline.certify.region_map import region_map_text
    from pipeline.online.loading import load_coefficients

    coefficients = over_x(load_coefficients("paper"), scale=0.2)
    coarse = RangeCertificateConfig(min_cell=1 / 16, boundary_cell=1 / 4, max_depth_s=12)
    texts = [
        region_map_text(certify_range(coefficients, RangeCertificateConfig(**{**coarse.__dict__, **where})))
        for where in ({"jobs": 1}, {"jobs": 2}, {"executor": DaskScheduler(cluster.scheduler_address)})
    ]
    assert texts[0] == texts[1] == texts[2]
    assert '"axes"' in texts[0] and len(texts[0]) > 10_000
