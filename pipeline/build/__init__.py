"""The offline build as one library call, above ``offline`` and ``certify``: DOE, regression,
certifiable regression and range map, written as one set of files.

* :class:`BuildConfig` (``config``): what to build, validated on construction, in sections
  (:class:`DesignSettings`, :class:`OptimiserSettings`, :class:`RegressionSettings`,
  :class:`RangeMapSettings`, :class:`ExecutionSettings`); every setting and its command-line
  option is declared once in :mod:`pipeline.build.options`;
* :func:`run_build` (``run``): config -> :class:`BuildResult`, the files written at the end;
* :func:`scene_from_options` (``config``): the scene from defaults, a scene file and options.

``python -m pipeline.build`` (:mod:`pipeline.commands.build`) parses its options into a
``BuildConfig``, calls :func:`run_build` and prints the result.
"""

from pipeline.build.config import (
    BuildConfig,
    DesignSettings,
    ExecutionSettings,
    OptimiserSettings,
    RangeMapSettings,
    RegressionSettings,
    scene_from_options,
)
from pipeline.build.run import BuildResult, run_build

__all__ = [
    "BuildConfig",
    "BuildResult",
    "DesignSettings",
    "ExecutionSettings",
    "OptimiserSettings",
    "RangeMapSettings",
    "RegressionSettings",
    "run_build",
    "scene_from_options",
]
