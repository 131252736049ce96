"""What a fresh process pays to answer its first query from a build: the import of the package,
``pipeline.load`` of the results, and the first query, each timed, and the process's peak
resident memory.

    python scripts/load_time.py RESULTS [--repeat 5]

RESULTS is a results folder or a coefficients file (with its region map beside it). Each of
``--repeat`` runs is a new interpreter (``sys.executable -c ...``) that imports ``pipeline``,
loads RESULTS, and asks for the trajectory at the centre of the fitted box
(``g(L, W, x=..., d=...)`` over the axes the coefficients vary), then loads RESULTS again and
asks the same query (what a running process pays for a map once the package has started); it
reports the four wall times, ``resource.getrusage``'s peak resident size and which machine code
answered (the extension module compiled with the package, or Numba's JIT: ``pipeline.native``).
The script prints each run and the median of each column. Python's bytecode cache should be in
place (as after an install, or after one run without ``PYTHONDONTWRITEBYTECODE``): without it every
import compiles its source, and the first load pays for it. A measurement, not part of the test
suite.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys

#: The child's program: argv[1] is RESULTS; one JSON line out.
_CHILD = """
import json, resource, sys, time
started = time.perf_counter()
import pipeline
imported = time.perf_counter()
g = pipeline.load(sys.argv[1])
loaded = time.perf_counter()
names = g.coefficients.variables.names
centre = {n: 0.5 * sum(g.coefficients.fitted_range_m[n]) for n in names}
moves = {n: centre[n] for n in ("x", "d") if n in names}
answer = g(centre["L"], centre["W"], **moves)
answered = time.perf_counter()
again = pipeline.load(sys.argv[1])
again(centre["L"], centre["W"], **moves)
reloaded = time.perf_counter()
print(json.dumps({
    "import_s": imported - started, "load_s": loaded - imported, "first_query_s": answered - loaded,
    "reload_and_query_s": reloaded - answered,
    "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
    "leaves": int(getattr(g.coefficients.region_map, "size", 0) or 0),
    "ahead_of_time": sys.modules["pipeline.online.kernel"].COMPILED.ahead_of_time,
}))
"""

COLUMNS = ("import_s", "load_s", "first_query_s", "reload_and_query_s", "peak_rss_mb")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python scripts/load_time.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("results", help="results folder or coefficients file")
    parser.add_argument("--repeat", type=int, default=5, help="fresh processes [count] (default: 5)")
    args = parser.parse_args(argv)
    if args.repeat < 1:
        parser.error(f"--repeat {args.repeat}: expected >= 1")
    runs = []
    for _ in range(args.repeat):
        child = subprocess.run([sys.executable, "-c", _CHILD, args.results], capture_output=True, text=True)
        if child.returncode != 0:
            print(f"python scripts/load_time.py: error: {child.stderr.strip().splitlines()[-1]}", file=sys.stderr)
            return 2
        runs.append(json.loads(child.stdout.strip().splitlines()[-1]))
        tail = f"  leaves {runs[-1]['leaves']}  core {'ahead of time' if runs[-1]['ahead_of_time'] else 'JIT'}"
        print("  ".join(f"{c} {runs[-1][c]:.3f}" for c in COLUMNS) + tail, flush=True)
    medians = {c: statistics.median(run[c] for run in runs) for c in COLUMNS}
    print("median: " + "  ".join(f"{c} {v:.3f}" for c, v in medians.items()))
    print(f"median load + first query: {medians['load_s'] + medians['first_query_s']:.3f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
