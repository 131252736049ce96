"""The viewer's error: one exception under the project's root, :class:`pipeline.exceptions.PipelineError`."""

from __future__ import annotations

from pipeline.exceptions import PipelineError


class ViewerError(PipelineError):
    """The Meshcat viewer or the headless browser could not start, serve or render."""
