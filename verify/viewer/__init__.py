"""Visual inspection of trajectories and sweeps in Meshcat.

The only package of the project that imports Meshcat (the modules below import it; this
``__init__`` does not, so importing :mod:`verify.viewer.server` stays light).

* :mod:`verify.viewer.server`: a loopback-only Meshcat server process, stopped by PID.
* :mod:`verify.viewer.drawing`: drawing arm, obstacle, paths, constraint points, minimum
  clearance and animation; top-down camera; flat-colour style for pixel tests.
* :mod:`verify.viewer.trajectory_view`: one trajectory live, as HTML, or as a screenshot.
* :mod:`verify.viewer.sweep_view`: a sweep's (L, W) map and its worst cases.
* :mod:`verify.viewer.browser`: headless-Chromium screenshots of exported pages.
* :mod:`verify.viewer.errors`: :class:`ViewerError`, the viewer's exception.
* :mod:`verify.viewer._meshcat`: the one place Meshcat is imported (its import-time
  DeprecationWarning silenced).
"""
