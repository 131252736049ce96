"""Progress of long work, reported on stderr.

Library calls take a :data:`ProgressCallback`, ``progress(stage, done, total)``: ``stage`` names
the step (e.g. ``"DOE"``, ``"range map: search"``), ``done`` of ``total`` units are finished.
They call it once with ``done == 0`` when a stage starts and again as work finishes; they never
print. A command line passes a :class:`ProgressBars`, which draws one tqdm bar per stage on
stderr, and nothing when it is disabled (``--no-progress``) or stderr is not a terminal.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import TextIO

from tqdm import tqdm

#: ``progress(stage, done, total)``: ``done`` of ``total`` units of ``stage`` are finished.
ProgressCallback = Callable[[str, int, int], None]

__all__ = ["ProgressBars", "ProgressCallback", "progress_enabled"]


def progress_enabled(requested: bool, stream: TextIO | None = None) -> bool:
    """True if progress is ``requested`` and ``stream`` (default stderr) is a terminal."""
    stream = sys.stderr if stream is None else stream
    isatty = getattr(stream, "isatty", None)
    return bool(requested and isatty is not None and isatty())


class ProgressBars:
    """A :data:`ProgressCallback` drawing one tqdm bar per stage on ``stream`` (default stderr).

    Use as a context manager (or call :meth:`close`) so that the last bar is closed.

    Args:
        enabled: Draw at all (a command line's ``not --no-progress``); the bars are drawn only
            if ``stream`` is also a terminal.
        stream: Where to draw (default stderr).
        unit: The unit shown after the counts.
    """

    def __init__(self, enabled: bool = True, stream: TextIO | None = None, unit: str = "it") -> None:
        self.stream = sys.stderr if stream is None else stream
        self.enabled = progress_enabled(enabled, self.stream)
        self.unit = unit
        self._stage: str | None = None
        self._bar: tqdm | None = None

    def __call__(self, stage: str, done: int, total: int) -> None:
        if not self.enabled:
            return
        if stage != self._stage or self._bar is None or done < self._bar.n:
            self.close()
            self._stage = stage
            self._bar = tqdm(total=total, desc=stage, unit=self.unit, file=self.stream, dynamic_ncols=True)
        elif total != self._bar.total:  # the same stage found more work (or less): one bar, a new total
            self._bar.total = total
            self._bar.refresh()
        self._bar.update(max(0, done - self._bar.n))

    def close(self) -> None:
        """Close the current bar (a later call starts a new one)."""
        if self._bar is not None:
            self._bar.close()
        self._bar, self._stage = None, None

    def __enter__(self) -> ProgressBars:
        return self

    def __exit__(self, *_exc) -> None:
        self.close()
