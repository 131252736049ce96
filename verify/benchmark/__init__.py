"""The benchmark's library: :mod:`.results` (settings, per-method results, the report record),
:mod:`.methods` (what is timed), :mod:`.range_map` (the region map row (a*) looks up),
:mod:`.ompl_planner` (the OMPL RRT-Connect baseline), :mod:`.toppra_peer` (TOPP-RA on our paths),
:mod:`.near_optimal` (the near-optimal timing's row and TOPP-RA's beside it),
:mod:`.run` (one run of every method) and :mod:`.report` (the printed table). The CLI
``verify.bench`` only parses and calls :func:`verify.benchmark.run.run_bench`."""
