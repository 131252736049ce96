"""The benchmark's library: :mod:`.results` (settings, per-method results, the report record),
:mod:`.methods` (what is timed), :mod:`.range_map` (the region map row (a*) looks up),
:mod:`.ompl_planner` (the OMPL RRT-Connect baseline),
:mod:`.run` (one run of every method) and :mod:`.report` (the printed table). The CLI
``verify.bench`` only parses and calls :func:`verify.benchmark.run.run_bench`."""
