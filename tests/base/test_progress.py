"""Progress bars on stderr: drawn only when asked for and stderr is a terminal, one bar per stage
(a stage whose total grows keeps its bar), never on stdout."""

from __future__ import annotations

import io

from pipeline.io.progress import ProgressBars, progress_enabled


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_nothing_is_drawn_unless_asked_for_on_a_terminal() -> None:
    pipe = io.StringIO()
    with ProgressBars(stream=pipe) as bars:
        bars("DOE", 0, 9)
        bars("DOE", 9, 9)
    assert pipe.getvalue() == "" and not progress_enabled(True, pipe)
    terminal = Terminal()
    with ProgressBars(enabled=False, stream=terminal) as bars:
        bars("DOE", 3, 9)
    assert terminal.getvalue() == "" and not progress_enabled(False, terminal)


def test_one_bar_per_stage_and_a_growing_total_keeps_its_bar() -> None:
    terminal = Terminal()
    with ProgressBars(stream=terminal, unit="exp") as bars:
        for done in range(10):
            bars("DOE", done, 9)
        bars("range map: refine", 0, 100)
        bars("range map: refine", 100, 100)
        bars("range map: refine", 150, 400)  # the same stage found more work
        bars("range map: refine", 400, 400)
    text = terminal.getvalue()
    finals = [line for line in text.replace("\r", "\n").splitlines() if line.strip()]
    assert any(line.startswith("DOE: 100%") and "9/9" in line for line in finals)
    assert any(line.startswith("range map: refine: 100%") and "400/400" in line for line in finals)
    assert not any("100/100" in line and "100%" in line for line in finals)  # not a second, finished bar
    assert text.count("\n") == 2  # two bars, each closed once
