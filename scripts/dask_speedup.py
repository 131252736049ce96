"""The range certificate's map stage on a Dask ``LocalCluster`` with 1 and with 2 workers: wall
times, their ratio, and whether the two maps' bytes agree.

    python scripts/dask_speedup.py results-xd/coefficients.json [--workers 1 2]

For each worker count it starts a local cluster (single-threaded worker processes, no dashboard),
runs ``certify_range`` on it with the default settings for the coefficients' axes
(``RangeCertificateConfig.for_axes``, the executor a ``DaskScheduler`` at the cluster's address),
and times the call; then it prints each time, the ratio to the first and the sha256 of each
map's table (the same bytes wherever the tasks run). A measurement, not part of the test suite.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import time


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python scripts/dask_speedup.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("coefficients", help="coefficients file")
    parser.add_argument(
        "--workers", type=int, nargs="+", default=[1, 2], help="worker counts, in order [count] (default: 1 2)"
    )
    args = parser.parse_args(argv)
    if any(w < 1 for w in args.workers):
        parser.error(f"--workers {args.workers}: expected counts >= 1")

    import distributed

    from pipeline import PipelineError, load_coefficients
    from pipeline.certify.map_files import region_map_files
    from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
    from pipeline.io.executor import DaskScheduler

    try:
        coefficients = load_coefficients(args.coefficients)
    except PipelineError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    times, digests = [], []
    for workers in args.workers:
        with distributed.LocalCluster(
            n_workers=workers, processes=True, threads_per_worker=1, dashboard_address=None
        ) as cluster:
            config = RangeCertificateConfig.for_axes(
                coefficients.variables.k, executor=DaskScheduler(cluster.scheduler_address)
            )
            started = time.perf_counter()
            region_map = certify_range(coefficients, config)
            times.append(time.perf_counter() - started)
        table = next(iter(region_map_files(region_map).values()))
        digests.append(hashlib.sha256(table).hexdigest()[:12])
        leaves = region_map.size
        print(f"{workers} worker(s): {times[-1]:.1f} s, {leaves} leaves, table sha256 {digests[-1]}", flush=True)
    for workers, seconds in zip(args.workers[1:], times[1:], strict=True):
        print(f"{args.workers[0]} -> {workers} workers: {times[0] / seconds:.2f}x faster")
    print("same bytes" if len(set(digests)) == 1 else "the maps differ")
    return 0 if len(set(digests)) == 1 else 1


if __name__ == "__main__":
    sys.exit(main())
